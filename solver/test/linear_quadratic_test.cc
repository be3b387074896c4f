// A continuous problem with an analytic optimum: the planners' first actions against the truth.
#include "npfkct/solver/models/linear_quadratic.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include "npfkct/common/stats.h"
#include "npfkct/solver/kct.h"
#include "npfkct/solver/pomcpow.h"

namespace npfkct {
namespace {

using models::LinearQuadratic;

TEST(LinearQuadraticTest, OptimalFirstActionMatchesTheRiccatiRecursionByHand) {
  LinearQuadratic::Params p;
  p.horizon = 1;
  p.rho = 1.0;
  // One step: maximise -(x + a)^2 - a^2, so a = -x / 2.
  EXPECT_NEAR(LinearQuadratic(p).OptimalFirstAction()[0], -0.4, 1e-12);
  p.horizon = 2;
  p.gamma = 1.0;
  // p1 = 1/2, q0 = 3/2, a0 = -(3/2) / (5/2) x = -0.6 x.
  EXPECT_NEAR(LinearQuadratic(p).OptimalFirstAction()[0], -0.6 * 0.8, 1e-12);
  EXPECT_NEAR(LinearQuadratic(p).OptimalFirstAction()[1], -0.6 * -0.5, 1e-12);
}

TEST(LinearQuadraticTest, EvaluatedByMonteCarloTheOptimumBeatsItsNeighbours) {
  const LinearQuadratic model;
  const ActionVec best = model.OptimalFirstAction();
  // The expected return of a first action followed by the optimal linear policy.
  auto value = [&](const ActionVec& a0) {
    Rng rng(1);
    double total = 0.0;
    for (int n = 0; n < 20000; ++n) {
      auto s = model.SampleInitialState(rng);
      HybridAction a{0, a0};
      double discount = 1.0, ret = 0.0;
      for (int t = 0; t < model.params().horizon; ++t) {
        auto step = model.Step(s, a, rng);
        ret += discount * step.reward;
        discount *= model.Discount();
        s = step.state;
        // The optimal gain of the remaining horizon, applied to the true state (the observation
        // noise is small).
        LinearQuadratic::Params rest = model.params();
        rest.horizon = model.params().horizon - t - 1;
        rest.mean0 = s.x;
        if (rest.horizon > 0) a.x = LinearQuadratic(rest).OptimalFirstAction();
      }
      total += ret;
    }
    return total / 20000;
  };
  const double v = value(best);
  for (const ActionVec& d :
       {MakeActionVec({0.1, 0}), MakeActionVec({0, -0.1}), MakeActionVec({-0.1, 0.1})}) {
    EXPECT_GT(v, value(best + d));
  }
}

// First actions of kCT and VOMCPOW with the project's defaults and the same simulations.
TEST(LinearQuadraticTest, KctFirstActionIsAsCloseToTheOptimumAsVomcpows) {
  const LinearQuadratic model;
  const ActionVec best = model.OptimalFirstAction();
  std::vector<double> kct_error, voo_error;
  for (uint64_t seed = 1; seed <= 60; ++seed) {
    {
      KctOptions o;
      o.search.num_particles = 1000;
      KCenterTree<LinearQuadratic> planner(model, o);
      Rng rng(seed);
      planner.Reset(rng);
      auto d = planner.Plan(Budget::Simulations(4000), rng);
      ASSERT_TRUE(d.status.ok()) << d.status.ToString();
      kct_error.push_back((d.action.x - best).norm());
    }
    {
      PomcpowOptions o = VomcpowOptions();
      o.search.num_particles = 1000;
      Pomcpow<LinearQuadratic> planner(model, o);
      Rng rng(seed);
      planner.Reset(rng);
      auto d = planner.Plan(Budget::Simulations(4000), rng);
      ASSERT_TRUE(d.status.ok()) << d.status.ToString();
      voo_error.push_back((d.action.x - best).norm());
    }
  }
  const double kct = Median(kct_error), voo = Median(voo_error);
  std::printf("median distance to the optimum: kCT %.4f, VOMCPOW %.4f\n", kct, voo);
  EXPECT_LE(kct, voo);
}

}  // namespace
}  // namespace npfkct
