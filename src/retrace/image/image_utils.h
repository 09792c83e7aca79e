#pragma once

// Image helpers used by every stage above the camera layer: conversion to 8-bit gray, resizing to a working width,
// and a contact sheet for visual inspection of many frames at once.

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

// Converts any image cv::imread can return to 8-bit single-channel gray:
//  - channels: 1 (kept), 3 (BGR), 4 (BGRA, alpha dropped) — colour through cv::cvtColor's BT.601 weights;
//  - depth: 8U kept; 16U scaled by 1/256 (full 16-bit range → 8 bits); 32F/64F assumed in [0, 1] and scaled by 255;
//    other depths are converted with saturation.
// An empty input gives an empty output.
cv::Mat ToGray8(const cv::Mat& image);

// Resizes `image` to `width` columns keeping the aspect ratio (rows = round(rows * factor)), with INTER_AREA when
// shrinking and INTER_LINEAR when enlarging. Returns the factor = width / image.cols, so that a pixel coordinate
// scales as x_out = factor * x_in (for pixel-centre coordinates with (0,0) at the top-left pixel centre, the exact
// map is x_out = factor * (x_in + 0.5) - 0.5). `width` <= 0 or an empty image leaves `out` a copy and returns 1.
double ResizeToWidth(const cv::Mat& image, int width, cv::Mat* out);

// A grid of thumbnails (each resized to `thumb_width`, height from the first image's aspect ratio) with `columns`
// per row and the label drawn in the top-left corner of each, as an 8-bit BGR image. Gray inputs are shown as gray.
// `labels` may be shorter than `images` (missing labels are empty). Empty images leave a black cell.
cv::Mat MakeContactSheet(const std::vector<cv::Mat>& images, const std::vector<std::string>& labels, int columns,
                         int thumb_width);

}  // namespace retrace
