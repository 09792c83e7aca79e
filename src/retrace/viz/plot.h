#pragma once

// Simple charts rendered to images with OpenCV's drawing functions: what a person wants to look at after teach
// (features and σ_p per arc, key-image spacing, the key-image poses) and after repeat (tracked features per arc).
// No plotting dependency is needed; the result is a cv::Mat (BGR) that callers write as PNG.

#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace retrace {

struct PlotSeries {
  enum class Style { kLine, kBars, kPoints, kLinePoints };

  std::string label;      // shown in the legend when not empty
  std::vector<double> x;  // same length as y
  std::vector<double> y;
  Style style = Style::kLine;
  cv::Scalar color = cv::Scalar(180, 90, 30);  // BGR
  int thickness = 2;                           // line width, or point radius
};

// A horizontal reference line, e.g. a threshold.
struct PlotReferenceLine {
  double y = 0.0;
  std::string label;
  cv::Scalar color = cv::Scalar(40, 40, 200);
};

struct PlotOptions {
  int width = 900;  // pixels of the whole image
  int height = 420;
  std::string title;
  std::string x_label;
  std::string y_label;
  // Axis ranges; taken from the data (with a margin) when not set.
  std::optional<double> x_min, x_max, y_min, y_max;
  // Same scale on both axes (for trajectories seen from above).
  bool equal_aspect = false;
  std::vector<PlotReferenceLine> reference_lines;
};

// Renders the series into a chart with axes, ticks, labels and a legend.
cv::Mat RenderPlot(const std::vector<PlotSeries>& series, const PlotOptions& options);

// "Nice" tick positions (1, 2 or 5 times a power of ten) covering [low, high] with about `target_count` ticks.
std::vector<double> NiceTicks(double low, double high, int target_count = 6);

// Distinct colours for series (BGR), cycling after a few.
cv::Scalar SeriesColor(int index);

// The three series of a plot of the camera's offset from the taught path against the truth (repeat --overlay's
// lateral_vs_truth.png, sim drive's lateral.png), drawn as points in this order: the truth (wide, grey), each frame's
// own estimate (small, blue) and the estimate combined over frames (green), labelled `combined_label`.
struct OffsetPlotSeries {
  PlotSeries truth, own, combined;
};
OffsetPlotSeries MakeOffsetPlotSeries(const std::string& combined_label);

}  // namespace retrace
