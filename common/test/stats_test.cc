#include "npfkct/common/stats.h"

#include <gtest/gtest.h>

#include <cmath>

namespace npfkct {
namespace {

TEST(StatsTest, StudentTQuantilesMatchTables) {
  // Two-sided 95% critical values from standard tables.
  EXPECT_NEAR(StudentTQuantile(0.975, 1), 12.7062, 1e-4);
  EXPECT_NEAR(StudentTQuantile(0.975, 4), 2.7764, 1e-4);
  EXPECT_NEAR(StudentTQuantile(0.975, 19), 2.0930, 1e-4);
  EXPECT_NEAR(StudentTQuantile(0.975, 29), 2.0452, 1e-4);
  EXPECT_NEAR(StudentTQuantile(0.995, 10), 3.1693, 1e-4);
  EXPECT_NEAR(StudentTQuantile(0.975, 1e6), 1.95996, 1e-4);  // tends to the normal quantile
  EXPECT_NEAR(StudentTQuantile(0.025, 19), -2.0930, 1e-4);
  EXPECT_DOUBLE_EQ(StudentTQuantile(0.5, 7), 0.0);
  EXPECT_TRUE(std::isnan(StudentTQuantile(1.0, 7)));
  EXPECT_TRUE(std::isnan(StudentTQuantile(0.9, 0)));
}

TEST(StatsTest, CdfAndIncompleteBetaAgreeWithClosedForms) {
  // df = 1 is the Cauchy distribution: F(t) = 1/2 + atan(t) / pi.
  for (double t : {-3.0, -0.5, 0.0, 0.7, 4.0}) {
    EXPECT_NEAR(StudentTCdf(t, 1), 0.5 + std::atan(t) / M_PI, 1e-12);
  }
  // I_x(1, 1) = x; I_x(a, 1) = x^a.
  EXPECT_NEAR(RegularizedIncompleteBeta(0.3, 1, 1), 0.3, 1e-12);
  EXPECT_NEAR(RegularizedIncompleteBeta(0.6, 3, 1), 0.216, 1e-12);
}

TEST(StatsTest, MeanIntervalUsesStudentsT) {
  const std::vector<double> v = {1, 2, 3, 4, 5};
  const MeanInterval m = MeanWithInterval(v);
  EXPECT_EQ(m.n, 5);
  EXPECT_DOUBLE_EQ(m.mean, 3.0);
  EXPECT_NEAR(m.stddev, std::sqrt(2.5), 1e-12);
  EXPECT_NEAR(m.half_width, 2.7764 * std::sqrt(2.5) / std::sqrt(5.0), 1e-4);
  EXPECT_NEAR(m.StandardError(), std::sqrt(2.5) / std::sqrt(5.0), 1e-12);
  EXPECT_EQ(MeanWithInterval({7}).StandardError(), 0.0);
  EXPECT_EQ(MeanWithInterval({7}).half_width, 0.0);
  EXPECT_EQ(Median({3, 1, 2, 10}), 2.5);
}

TEST(StatsTest, RatioIntervalIsTheDeltaMethodOverUnits) {
  // 1 of 2 and 3 of 4: ratio 4/6, residuals -1/3 and +1/3, variance 2/1 * (2/9) / 36.
  EXPECT_NEAR(RatioHalfWidth95({1, 3}, {2, 4}), 1.959964 * std::sqrt(2.0 * (2.0 / 9.0) / 36.0),
              1e-9);
  // Units with the same ratio leave no spread; one unit or no totals give no interval.
  EXPECT_EQ(RatioHalfWidth95({1, 2}, {2, 4}), 0.0);
  EXPECT_EQ(RatioHalfWidth95({1}, {2}), 0.0);
  EXPECT_EQ(RatioHalfWidth95({0, 0}, {0, 0}), 0.0);
  // More units with the same spread narrow it by about sqrt(n).
  const double two = RatioHalfWidth95({1, 3}, {2, 4});
  const double eight = RatioHalfWidth95({1, 3, 1, 3, 1, 3, 1, 3}, {2, 4, 2, 4, 2, 4, 2, 4});
  EXPECT_NEAR(eight / two, std::sqrt((8.0 / 7.0) / 2.0) / 2.0, 1e-9);
}

}  // namespace
}  // namespace npfkct
