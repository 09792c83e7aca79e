#include "retrace/nav/heading_filter.h"

#include <cmath>
#include <stdexcept>

#include <gtest/gtest.h>

namespace retrace {
namespace {

TEST(HeadingFilterTest, NoHeadingBeforeTheFirstEstimate) {
  HeadingFilter filter;
  EXPECT_FALSE(filter.heading().has_value());
  filter.Update(std::nullopt);
  EXPECT_FALSE(filter.heading().has_value());
  EXPECT_EQ(filter.misses(), 1);
}

TEST(HeadingFilterTest, ConstantHeadingStays) {
  HeadingFilter filter;
  for (int i = 0; i < 5; ++i) {
    filter.Update(0.3);
    ASSERT_TRUE(filter.heading().has_value());
    EXPECT_NEAR(*filter.heading(), 0.3, 1e-12);
  }
}

// After a step from 0 to φ the filter holds v = (1 - w)^k u(0) + (1 - (1 - w)^k) u(φ) after k estimates of φ.
TEST(HeadingFilterTest, StepIsFollowedWithRecencyWeights) {
  HeadingFilterOptions options;
  options.new_weight = 0.5;
  HeadingFilter filter(options);
  filter.Update(0.0);
  const double phi = 1.0;
  for (int k = 1; k <= 6; ++k) {
    filter.Update(phi);
    const double old_weight = std::pow(0.5, k);
    const double expected = std::atan2((1 - old_weight) * std::sin(phi), old_weight + (1 - old_weight) * std::cos(phi));
    ASSERT_TRUE(filter.heading().has_value());
    EXPECT_NEAR(*filter.heading(), expected, 1e-12) << "after " << k;
  }
  EXPECT_NEAR(*filter.heading(), phi, 0.02);
  // w = 1: no smoothing.
  options.new_weight = 1.0;
  HeadingFilter raw(options);
  raw.Update(0.2);
  raw.Update(-0.7);
  EXPECT_NEAR(*raw.heading(), -0.7, 1e-12);
}

// Headings almost behind on either side average to behind, not ahead.
TEST(HeadingFilterTest, AveragesAcrossTheWrapAround) {
  HeadingFilter filter;
  filter.Update(3.1);
  filter.Update(-3.1);
  ASSERT_TRUE(filter.heading().has_value());
  EXPECT_NEAR(std::abs(*filter.heading()), M_PI, 1e-9);
  // Opposite estimates of equal weight cancel out: no heading.
  HeadingFilterOptions options;
  options.new_weight = 0.5;
  HeadingFilter opposite(options);
  opposite.Update(M_PI / 2);
  opposite.Update(-M_PI / 2);
  EXPECT_FALSE(opposite.heading().has_value());
}

// Booij 2007 §B.4: relocalize after 10 observations in a row without a heading; a miss keeps the heading and an
// estimate ends the series.
TEST(HeadingFilterTest, RelocalizesAfterTenObservationsWithoutHeading) {
  HeadingFilter filter;
  filter.Update(0.4);
  for (int i = 1; i <= 9; ++i) {
    filter.Update(std::nullopt);
    EXPECT_FALSE(filter.NeedsRelocalization()) << i;
    EXPECT_NEAR(*filter.heading(), 0.4, 1e-12);
  }
  filter.Update(0.4);
  EXPECT_EQ(filter.misses(), 0);
  for (int i = 1; i <= 10; ++i) filter.Update(std::nullopt);
  EXPECT_TRUE(filter.NeedsRelocalization());
  filter.Reset();
  EXPECT_FALSE(filter.NeedsRelocalization());
  EXPECT_FALSE(filter.heading().has_value());
  // Non-finite estimates count as none.
  filter.Update(std::nan(""));
  EXPECT_EQ(filter.misses(), 1);
}

TEST(HeadingFilterTest, OptionsAreChecked) {
  HeadingFilterOptions options;
  options.new_weight = 0.0;
  EXPECT_THROW(HeadingFilter{options}, std::invalid_argument);
  options.new_weight = 0.5;
  options.max_misses = 0;
  EXPECT_THROW(HeadingFilter{options}, std::invalid_argument);
}

}  // namespace
}  // namespace retrace
