#include "retrace/viz/plot.h"

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(NiceTicks, KnownRanges) {
  EXPECT_EQ(NiceTicks(0.0, 10.0, 5), (std::vector<double>{0, 2, 4, 6, 8, 10}));
  EXPECT_EQ(NiceTicks(0.0, 1.0, 4), (std::vector<double>{0, 0.5, 1.0}));
  const std::vector<double> ticks = NiceTicks(-3.2, 47.0, 6);
  ASSERT_FALSE(ticks.empty());
  EXPECT_DOUBLE_EQ(ticks.front(), 0.0);
  EXPECT_DOUBLE_EQ(ticks.back(), 40.0);
  EXPECT_EQ(NiceTicks(5.0, 5.0).size(), 1u);  // degenerate range: no loop, one tick
}

// Counts pixels of exactly `color` in the image.
int CountColor(const cv::Mat& image, const cv::Scalar& color) {
  cv::Mat mask;
  cv::inRange(image, color, color, mask);
  return cv::countNonZero(mask);
}

TEST(RenderPlot, BarsAreDrawnWithHeightsInProportion) {
  PlotSeries bars;
  bars.x = {0, 1};
  bars.y = {10, 20};
  bars.style = PlotSeries::Style::kBars;
  bars.color = cv::Scalar(0, 200, 0);
  PlotOptions options;
  options.y_min = 0;
  options.y_max = 20;
  const cv::Mat image = RenderPlot({bars}, options);
  ASSERT_EQ(image.size(), cv::Size(options.width, options.height));
  // Column heights of the bar colour in the left and right half of the plot: the second bar is twice the first.
  int left = 0, right = 0;
  for (int x = 0; x < image.cols; ++x) {
    const int height = CountColor(image.col(x), bars.color);
    if (x < image.cols / 2) {
      left = std::max(left, height);
    } else {
      right = std::max(right, height);
    }
  }
  ASSERT_GT(left, 50);
  EXPECT_NEAR(static_cast<double>(right) / left, 2.0, 0.05);
}

TEST(MakeOffsetPlotSeries, ThreeDistinctPointSeriesDrawnOverTheTruth) {
  OffsetPlotSeries series = MakeOffsetPlotSeries("steered");
  EXPECT_EQ(series.combined.label, "steered");
  for (const PlotSeries* s : {&series.truth, &series.own, &series.combined}) {
    EXPECT_EQ(s->style, PlotSeries::Style::kPoints);
  }
  EXPECT_NE(series.truth.color, series.own.color);
  EXPECT_NE(series.own.color, series.combined.color);
  EXPECT_GT(series.truth.thickness, series.combined.thickness);  // the truth stays visible around the estimates
  // Drawn over the truth (first in the list), an estimate lying on it leaves the wider truth visible around it: the
  // right half of the plot, where the estimates equal the truth (and no legend is drawn), shows both colours.
  for (int i = 0; i < 20; ++i) {
    series.truth.x.push_back(i);
    series.truth.y.push_back(1.0);
    series.combined.x.push_back(i);
    series.combined.y.push_back(i < 10 ? 0.5 : 1.0);
  }
  PlotOptions options;
  options.x_min = -0.5;
  options.x_max = 19.5;
  const cv::Mat image = RenderPlot({series.truth, series.own, series.combined}, options);
  const cv::Mat without_truth = RenderPlot({series.own, series.combined}, options);  // the axes' grey stays
  const auto right = [](const cv::Mat& m) { return m.colRange(m.cols / 2, m.cols); };
  EXPECT_GT(CountColor(right(image), series.truth.color), CountColor(right(without_truth), series.truth.color) + 20);
  EXPECT_GT(CountColor(right(image), series.combined.color), 0);
}

TEST(RenderPlot, HandlesEmptyAndNonFiniteData) {
  PlotSeries empty;
  PlotSeries bad;
  bad.x = {0.0, 1.0, 2.0};
  bad.y = {1.0, std::nan(""), 3.0};
  const cv::Mat image = RenderPlot({empty, bad}, PlotOptions());
  EXPECT_FALSE(image.empty());
}

}  // namespace
}  // namespace retrace
