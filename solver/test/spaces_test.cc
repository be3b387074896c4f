#include "npfkct/solver/spaces.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace npfkct {
namespace {

TEST(BoxSpaceTest, WeightedDistanceAndDiameter) {
  BoxSpace box(MakeActionVec({0, 0}), MakeActionVec({3, 8}), MakeActionVec({1, 2}));
  ASSERT_TRUE(box.Validate().ok());
  EXPECT_DOUBLE_EQ(box.Distance(MakeActionVec({0, 0}), MakeActionVec({3, 8})), 5.0);
  EXPECT_DOUBLE_EQ(box.Diameter(), 5.0);
}

TEST(BoxSpaceTest, PeriodicDimensionWrapsAround) {
  BoxSpace box(MakeActionVec({-std::numbers::pi}), MakeActionVec({std::numbers::pi}));
  box.SetPeriodic(0);
  EXPECT_NEAR(box.Distance(MakeActionVec({3.0}), MakeActionVec({-3.0})), 2 * std::numbers::pi - 6.0,
              1e-12);
  EXPECT_NEAR(box.Clamp(MakeActionVec({3.5}))[0], 3.5 - 2 * std::numbers::pi, 1e-12);
  EXPECT_NEAR(box.Diameter(), std::numbers::pi, 1e-12);
}

TEST(BoxSpaceTest, BallSamplesStayInBallAndBox) {
  BoxSpace box(MakeActionVec({0, 0, 0}), MakeActionVec({1, 1, 1}));
  Rng rng(7);
  const ActionVec center = MakeActionVec({0.95, 0.5, 0.5});
  for (int i = 0; i < 2000; ++i) {
    ActionVec x = box.SampleInBall(center, 0.2, rng);
    EXPECT_TRUE(box.Contains(x));
    EXPECT_LE(box.Distance(x, center), 0.2 + 1e-12);
  }
}

TEST(BoxSpaceTest, BallSamplesAreUniformInRadius) {
  // For a uniform distribution in a 2-D disc, P(r < R / sqrt(2)) = 1/2.
  BoxSpace box(MakeActionVec({-1, -1}), MakeActionVec({1, 1}));
  Rng rng(3);
  int inner = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    ActionVec x = box.SampleInBall(MakeActionVec({0, 0}), 1.0, rng);
    if (x.norm() < 1.0 / std::sqrt(2.0)) ++inner;
  }
  EXPECT_NEAR(static_cast<double>(inner) / n, 0.5, 0.02);
}

TEST(BoxSpaceTest, AZeroWidthDimensionHoldsItsValueAndTheBallIsDrawnInTheOthers) {
  // A robot without a lift: the middle dimension has one value. The ball is then a 2-D disc in
  // the two others, uniform in radius, and every draw is inside the box (it was clamped from a
  // 3-D ball after every try of it missed the zero-width slab).
  BoxSpace box(MakeActionVec({-1, 0.25, -1}), MakeActionVec({1, 0.25, 1}));
  EXPECT_TRUE(box.fixed(1));
  EXPECT_FALSE(box.fixed(0));
  Rng rng(4);
  int inner = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    ActionVec x = box.SampleInBall(MakeActionVec({0, 0.25, 0}), 1.0, rng);
    ASSERT_EQ(x[1], 0.25);
    ASSERT_TRUE(box.Contains(x));
    if (std::hypot(x[0], x[2]) < 1.0 / std::sqrt(2.0)) ++inner;
  }
  EXPECT_NEAR(static_cast<double>(inner) / n, 0.5, 0.02);
  BoxSpace point(MakeActionVec({1, 2}), MakeActionVec({1, 2}));
  EXPECT_EQ(point.SampleInBall(MakeActionVec({1, 2}), 1.0, rng), MakeActionVec({1, 2}));
}

TEST(BoxSpaceTest, ValidateNamesTheProblem) {
  BoxSpace inverted(MakeActionVec({1}), MakeActionVec({0}));
  EXPECT_NE(inverted.Validate().message().find("lower[0] > upper[0]"), std::string::npos);
  BoxSpace bad_scale(MakeActionVec({0}), MakeActionVec({1}), MakeActionVec({0}));
  EXPECT_NE(bad_scale.Validate().message().find("scale[0]"), std::string::npos);
  BoxSpace nan_bound(MakeActionVec({std::nan("")}), MakeActionVec({1}));
  EXPECT_FALSE(nan_bound.Validate().ok());
}

TEST(HybridActionTest, EqualityAndString) {
  HybridAction a{1, MakeActionVec({0.5})};
  HybridAction b{1, MakeActionVec({0.5})};
  HybridAction c{0, MakeActionVec({0.5})};
  EXPECT_EQ(a, b);
  EXPECT_FALSE(a == c);
  EXPECT_EQ(a.ToString(), "1[0.5]");
}

TEST(RngTest, SameSeedSameStream) {
  Rng a(42), b(42), c(43);
  for (int i = 0; i < 10; ++i) {
    const auto x = a();
    EXPECT_EQ(x, b());
    (void)c();
  }
  Rng d(42);
  EXPECT_NE(Rng(43)(), d());
}

TEST(RngTest, MomentsAreRight) {
  Rng rng(1);
  double sum = 0, sum2 = 0, usum = 0;
  const int n = 200000;
  for (int i = 0; i < n; ++i) {
    const double z = rng.Normal();
    sum += z;
    sum2 += z * z;
    usum += rng.Uniform();
  }
  EXPECT_NEAR(sum / n, 0.0, 0.01);
  EXPECT_NEAR(sum2 / n, 1.0, 0.02);
  EXPECT_NEAR(usum / n, 0.5, 0.005);
  for (int i = 0; i < 1000; ++i) {
    const auto k = rng.UniformInt(7);
    EXPECT_GE(k, 0);
    EXPECT_LT(k, 7);
  }
}

}  // namespace
}  // namespace npfkct
