#pragma once

// Key-image descriptors stored as their differences from what the stored key-image predicts (issue 16: a map's size).
//
// Teach stores each key-image's binary relocalization descriptors (32 bytes per key-point, 1000 key-points: most of a
// map) and the key-image itself. Describing the stored key-image again at the stored key-points gives almost the
// same descriptors: the codec and the key-point positions' rounding flip about 1 of 256 bits in the simulated town
// (JPEG quality 90 at 320x240) and 3.4 on kitti07 (1226x370 at half resolution near quality 85; medians 1 and 2).
// So the map keeps only which bits differ — a lossless predictive code: the descriptors read back are the ones teach
// extracted, bit for bit, as long as the reader describes the same decoded key-image the same way (the same OpenCV;
// another decoder would flip a few bits more, not break anything).
//
// The code of one key-image: one byte, the descriptor length B (8-32 bytes); then per key-point, in order, the number
// n of bits that differ (0-254) followed by their positions (0 ... 8B - 1, increasing, one byte each), or, when
// n ≥ B (listing them would cost more), the byte 255 followed by the B bytes of the descriptor itself.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

// The code of `descriptors` against `predicted` (both CV_8U, one row per key-point, 8-32 bytes each, the same size).
std::vector<uint8_t> EncodeDescriptorResidual(const cv::Mat& descriptors, const cv::Mat& predicted);

// Why `code` is not a valid code of `count` descriptors (nullopt when it is); `descriptor_bytes` receives B.
std::optional<std::string> CheckDescriptorResidual(const std::vector<uint8_t>& code, size_t count,
                                                   int* descriptor_bytes = nullptr);

// The descriptors `code` holds against `predicted` (one row per key-point), or why it cannot be decoded.
std::optional<std::string> DecodeDescriptorResidual(const std::vector<uint8_t>& code, const cv::Mat& predicted,
                                                    cv::Mat* descriptors);

}  // namespace retrace
