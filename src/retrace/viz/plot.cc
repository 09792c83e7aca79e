#include "retrace/viz/plot.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace retrace {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kGrid(225, 225, 225);

std::string FormatTick(double value, double step) {
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  return fmt::format("{:.{}f}", value, std::max(0, decimals));
}

void PutText(cv::Mat& image, const std::string& text, cv::Point origin, double scale, const cv::Scalar& color,
             int align = 0 /* -1 left, 0 centre, 1 right */) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, kFont, scale, 1, &baseline);
  origin.x -= align == 0 ? size.width / 2 : (align > 0 ? size.width : 0);
  cv::putText(image, text, origin, kFont, scale, color, 1, cv::LINE_AA);
}

}  // namespace

std::vector<double> NiceTicks(double low, double high, int target_count) {
  std::vector<double> ticks;
  if (!(high > low) || !std::isfinite(low) || !std::isfinite(high)) return {low};
  const double raw_step = (high - low) / std::max(1, target_count);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw_step)));
  double step = magnitude;
  for (double factor : {1.0, 2.0, 5.0, 10.0}) {
    step = factor * magnitude;
    if (step >= raw_step) break;
  }
  for (double t = std::ceil(low / step - 1e-9) * step; t <= high + 1e-9 * step; t += step) {
    ticks.push_back(std::abs(t) < 1e-12 * step ? 0.0 : t);
  }
  return ticks;
}

cv::Scalar SeriesColor(int index) {
  static const cv::Scalar kColors[] = {{180, 90, 30}, {30, 120, 230}, {60, 160, 60}, {40, 40, 200},
                                       {150, 80, 150}, {120, 120, 0}, {20, 180, 220}};
  return kColors[index % (sizeof(kColors) / sizeof(kColors[0]))];
}

cv::Mat RenderPlot(const std::vector<PlotSeries>& series, const PlotOptions& options) {
  cv::Mat image(options.height, options.width, CV_8UC3, cv::Scalar(255, 255, 255));
  // Data ranges.
  double x_low = std::numeric_limits<double>::infinity(), x_high = -x_low;
  double y_low = x_low, y_high = -x_low;
  bool has_bars = false;
  for (const PlotSeries& s : series) {
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x_low = std::min(x_low, s.x[i]);
      x_high = std::max(x_high, s.x[i]);
      y_low = std::min(y_low, s.y[i]);
      y_high = std::max(y_high, s.y[i]);
    }
    has_bars |= s.style == PlotSeries::Style::kBars;
  }
  for (const PlotReferenceLine& line : options.reference_lines) {
    y_low = std::min(y_low, line.y);
    y_high = std::max(y_high, line.y);
  }
  if (!std::isfinite(x_low)) x_low = 0, x_high = 1;
  if (!std::isfinite(y_low)) y_low = 0, y_high = 1;
  if (has_bars) {
    y_low = std::min(y_low, 0.0);
    x_low -= 0.5;
    x_high += 0.5;
  }
  if (x_high - x_low < 1e-12) x_low -= 0.5, x_high += 0.5;
  if (y_high - y_low < 1e-12) y_low -= 0.5, y_high += 0.5;
  const double y_margin = 0.05 * (y_high - y_low);
  if (!has_bars || y_low < 0.0) y_low -= y_margin;
  y_high += y_margin;
  x_low = options.x_min.value_or(x_low);
  x_high = options.x_max.value_or(x_high);
  y_low = options.y_min.value_or(y_low);
  y_high = options.y_max.value_or(y_high);

  // Plot area inside the margins for title, labels and ticks.
  const cv::Rect area(70, options.title.empty() ? 20 : 40, options.width - 90,
                      options.height - (options.title.empty() ? 20 : 40) - 55);
  if (options.equal_aspect) {
    const double units_per_px = std::max((x_high - x_low) / area.width, (y_high - y_low) / area.height);
    const double x_mid = 0.5 * (x_low + x_high), y_mid = 0.5 * (y_low + y_high);
    x_low = x_mid - 0.5 * units_per_px * area.width;
    x_high = x_mid + 0.5 * units_per_px * area.width;
    y_low = y_mid - 0.5 * units_per_px * area.height;
    y_high = y_mid + 0.5 * units_per_px * area.height;
  }
  const auto to_pixel = [&](double x, double y) {
    return cv::Point2d(area.x + (x - x_low) / (x_high - x_low) * area.width,
                       area.y + area.height - (y - y_low) / (y_high - y_low) * area.height);
  };
  constexpr int kShift = 4;  // sub-pixel drawing
  const auto fixed = [&](const cv::Point2d& p) { return cv::Point(cvRound(p.x * 16), cvRound(p.y * 16)); };

  // Grid, ticks and tick labels.
  const std::vector<double> x_ticks = NiceTicks(x_low, x_high, std::max(2, area.width / 90));
  const std::vector<double> y_ticks = NiceTicks(y_low, y_high, std::max(2, area.height / 50));
  const double x_step = x_ticks.size() > 1 ? x_ticks[1] - x_ticks[0] : 1.0;
  const double y_step = y_ticks.size() > 1 ? y_ticks[1] - y_ticks[0] : 1.0;
  for (double t : x_ticks) {
    const cv::Point2d p = to_pixel(t, y_low);
    cv::line(image, cv::Point(cvRound(p.x), area.y), cv::Point(cvRound(p.x), area.y + area.height), kGrid, 1);
    PutText(image, FormatTick(t, x_step), cv::Point(cvRound(p.x), area.y + area.height + 18), 0.42, kInk);
  }
  for (double t : y_ticks) {
    const cv::Point2d p = to_pixel(x_low, t);
    cv::line(image, cv::Point(area.x, cvRound(p.y)), cv::Point(area.x + area.width, cvRound(p.y)), kGrid, 1);
    PutText(image, FormatTick(t, y_step), cv::Point(area.x - 6, cvRound(p.y) + 5), 0.42, kInk, 1);
  }
  cv::rectangle(image, area, kInk, 1);

  // Data, clipped to the plot area.
  cv::Mat canvas = image(area);
  const cv::Point2d origin(area.x, area.y);
  int bar_series = 0, bar_index = 0;
  for (const PlotSeries& s : series) bar_series += s.style == PlotSeries::Style::kBars;
  for (const PlotSeries& s : series) {
    const size_t n = std::min(s.x.size(), s.y.size());
    std::vector<cv::Point> polyline;
    for (size_t i = 0; i < n; ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      const cv::Point2d p = to_pixel(s.x[i], s.y[i]) - origin;
      switch (s.style) {
        case PlotSeries::Style::kBars: {
          const double slot = 0.8 * area.width / (x_high - x_low) / std::max(1, bar_series);
          const double left = p.x - 0.4 * area.width / (x_high - x_low) + bar_index * slot;
          const cv::Point2d base = to_pixel(s.x[i], std::max(y_low, 0.0)) - origin;
          cv::rectangle(canvas, fixed({left, p.y}), fixed({left + 0.9 * slot, base.y}), s.color, cv::FILLED,
                        cv::LINE_AA, kShift);
          break;
        }
        case PlotSeries::Style::kPoints:
          cv::circle(canvas, fixed(p), s.thickness * 16, s.color, cv::FILLED, cv::LINE_AA, kShift);
          break;
        case PlotSeries::Style::kLinePoints:
          cv::circle(canvas, fixed(p), (s.thickness + 2) * 16, s.color, cv::FILLED, cv::LINE_AA, kShift);
          polyline.push_back(fixed(p));
          break;
        case PlotSeries::Style::kLine:
          polyline.push_back(fixed(p));
          break;
      }
    }
    if (polyline.size() > 1) {
      cv::polylines(canvas, polyline, false, s.color, s.thickness, cv::LINE_AA, kShift);
    }
    bar_index += s.style == PlotSeries::Style::kBars;
  }
  for (const PlotReferenceLine& line : options.reference_lines) {
    const double y = to_pixel(x_low, line.y).y;
    for (int x = area.x; x < area.x + area.width; x += 12) {
      cv::line(image, cv::Point(x, cvRound(y)), cv::Point(std::min(x + 6, area.x + area.width), cvRound(y)),
               line.color, 1, cv::LINE_AA);
    }
    if (!line.label.empty()) {
      PutText(image, line.label, cv::Point(area.x + area.width - 4, cvRound(y) - 4), 0.42, line.color, 1);
    }
  }

  // Title, axis labels, legend.
  if (!options.title.empty()) PutText(image, options.title, cv::Point(options.width / 2, 26), 0.6, kInk);
  if (!options.x_label.empty()) {
    PutText(image, options.x_label, cv::Point(area.x + area.width / 2, options.height - 12), 0.5, kInk);
  }
  if (!options.y_label.empty()) {
    // Vertical text: draw horizontally, then rotate the strip.
    int baseline = 0;
    const cv::Size size = cv::getTextSize(options.y_label, kFont, 0.5, 1, &baseline);
    cv::Mat strip(size.height + baseline + 4, size.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(strip, options.y_label, cv::Point(2, size.height + 2), kFont, 0.5, kInk, 1, cv::LINE_AA);
    cv::rotate(strip, strip, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int top = std::max(0, area.y + area.height / 2 - strip.rows / 2);
    if (top + strip.rows <= image.rows && strip.cols <= area.x) {
      strip.copyTo(image(cv::Rect(4, top, strip.cols, strip.rows)));
    }
  }
  int legend_y = area.y + 16;
  for (const PlotSeries& s : series) {
    if (s.label.empty()) continue;
    const cv::Point anchor(area.x + 10, legend_y);
    cv::rectangle(image, anchor + cv::Point(0, -9), anchor + cv::Point(16, 1), s.color, cv::FILLED);
    PutText(image, s.label, anchor + cv::Point(22, 0), 0.45, kInk, -1);
    legend_y += 18;
  }
  return image;
}

OffsetPlotSeries MakeOffsetPlotSeries(const std::string& combined_label) {
  OffsetPlotSeries series;
  series.truth.label = "true offset from the taught path";
  series.truth.color = cv::Scalar(160, 160, 160);
  series.truth.thickness = 5;
  series.own.label = "frame_lateral_m (the frame's own)";
  series.own.color = cv::Scalar(200, 120, 0);
  series.own.thickness = 1;
  series.combined.label = combined_label;
  series.combined.color = cv::Scalar(60, 160, 40);
  series.combined.thickness = 2;
  for (PlotSeries* s : {&series.truth, &series.own, &series.combined}) s->style = PlotSeries::Style::kPoints;
  return series;
}

}  // namespace retrace
