#include "retrace/image/image_utils.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace retrace {

cv::Mat ToGray8(const cv::Mat& image) {
  if (image.empty()) return cv::Mat();
  cv::Mat eight;
  switch (image.depth()) {
    case CV_8U:
      eight = image;
      break;
    case CV_16U:
      image.convertTo(eight, CV_8U, 1.0 / 256.0);
      break;
    case CV_32F:
    case CV_64F:
      image.convertTo(eight, CV_8U, 255.0);
      break;
    default:
      image.convertTo(eight, CV_8U);
      break;
  }
  cv::Mat gray;
  switch (eight.channels()) {
    case 1:
      gray = eight.data == image.data ? eight.clone() : eight;
      break;
    case 3:
      cv::cvtColor(eight, gray, cv::COLOR_BGR2GRAY);
      break;
    case 4:
      cv::cvtColor(eight, gray, cv::COLOR_BGRA2GRAY);
      break;
    default: {
      // Unusual channel counts: take the first channel.
      cv::extractChannel(eight, gray, 0);
      break;
    }
  }
  return gray;
}

double ResizeToWidth(const cv::Mat& image, int width, cv::Mat* out) {
  if (image.empty() || width <= 0 || width == image.cols) {
    *out = image.clone();
    return 1.0;
  }
  const double factor = static_cast<double>(width) / image.cols;
  const int height = std::max(1, static_cast<int>(std::lround(image.rows * factor)));
  cv::resize(image, *out, cv::Size(width, height), 0, 0, factor < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
  return factor;
}

cv::Mat MakeContactSheet(const std::vector<cv::Mat>& images, const std::vector<std::string>& labels, int columns,
                         int thumb_width) {
  if (images.empty() || columns <= 0 || thumb_width <= 0) return cv::Mat();
  int thumb_height = thumb_width * 3 / 4;
  for (const cv::Mat& image : images) {
    if (!image.empty()) {
      thumb_height = std::max(1, static_cast<int>(std::lround(static_cast<double>(image.rows) * thumb_width /
                                                              image.cols)));
      break;
    }
  }
  const int n = static_cast<int>(images.size());
  const int cols = std::min(columns, n);
  const int rows = (n + columns - 1) / columns;
  const int gap = 2;
  cv::Mat sheet(rows * (thumb_height + gap) + gap, cols * (thumb_width + gap) + gap, CV_8UC3, cv::Scalar(40, 40, 40));
  const double font_scale = std::clamp(thumb_width / 320.0, 0.3, 1.0);
  for (int i = 0; i < n; ++i) {
    const cv::Rect cell(gap + (i % columns) * (thumb_width + gap), gap + (i / columns) * (thumb_height + gap),
                        thumb_width, thumb_height);
    cv::Mat roi = sheet(cell);
    roi.setTo(cv::Scalar(0, 0, 0));
    if (!images[i].empty()) {
      cv::Mat bgr = images[i];
      if (bgr.depth() != CV_8U) bgr = ToGray8(bgr);
      if (bgr.channels() == 1) {
        cv::cvtColor(bgr, bgr, cv::COLOR_GRAY2BGR);
      } else if (bgr.channels() == 4) {
        cv::cvtColor(bgr, bgr, cv::COLOR_BGRA2BGR);
      }
      // Fit inside the cell keeping the aspect ratio of this image.
      const double scale = std::min(static_cast<double>(thumb_width) / bgr.cols,
                                    static_cast<double>(thumb_height) / bgr.rows);
      const cv::Size size(std::max(1, static_cast<int>(bgr.cols * scale)),
                          std::max(1, static_cast<int>(bgr.rows * scale)));
      cv::Mat thumb;
      cv::resize(bgr, thumb, size, 0, 0, scale < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
      thumb.copyTo(roi(cv::Rect(0, 0, size.width, size.height)));
    }
    if (i < static_cast<int>(labels.size()) && !labels[i].empty()) {
      int baseline = 0;
      const cv::Size text = cv::getTextSize(labels[i], cv::FONT_HERSHEY_SIMPLEX, font_scale, 1, &baseline);
      cv::rectangle(roi, cv::Rect(0, 0, std::min(thumb_width, text.width + 6), text.height + baseline + 6),
                    cv::Scalar(0, 0, 0), cv::FILLED);
      cv::putText(roi, labels[i], cv::Point(3, text.height + 3), cv::FONT_HERSHEY_SIMPLEX, font_scale,
                  cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
    }
  }
  return sheet;
}

}  // namespace retrace
