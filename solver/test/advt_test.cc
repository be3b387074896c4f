#include "npfkct/solver/advt.h"

#include <gtest/gtest.h>

#include "npfkct/solver/models/vdp_tag.h"
#include "test_models.h"

namespace npfkct {
namespace {

using models::VdpTag;
using testing::PeakSearch;

AdvtOptions PeakOptions() {
  AdvtOptions o;
  o.observations.enabled = false;
  o.search.max_depth = 4;
  o.exploration_c = 0.5;
  o.diameter_coefficient = 0.5;
  o.split_coefficient = 2.0;
  return o;
}

TEST(AdvtOptionsTest, ValidateNamesTheOption) {
  AdvtOptions o;
  o.split_coefficient = 0.0;
  EXPECT_NE(o.Validate().message().find("split_coefficient"), std::string::npos);
  o = {};
  o.diameter_samples = 1;
  EXPECT_NE(o.Validate().message().find("diameter_samples"), std::string::npos);
  o = {};
  o.observations.alpha = 2.0;
  EXPECT_NE(o.Validate().message().find("observations.alpha"), std::string::npos);
}

TEST(AdvtTest, SplitsCellsAndFindsThePeak) {
  PeakSearch model;
  Rng rng(1);
  Advt<PeakSearch> planner(model, PeakOptions());
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20000), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(d.stats.simulations, 20000);
  EXPECT_GT(planner.RootCells(), 10);
  ASSERT_EQ(d.action.kind, 0);
  EXPECT_LT((d.action.x - model.Peak(0)).norm(), 0.1);
  EXPECT_GT(d.value, 0.8);
  // Representatives are distinct points of the box.
  for (size_t i = 0; i < d.root.size(); ++i) {
    for (size_t j = i + 1; j < d.root.size(); ++j) {
      if (d.root[i].action.kind == 0 && d.root[j].action.kind == 0) {
        EXPECT_GT((d.root[i].action.x - d.root[j].action.x).norm(), 0.0);
      }
    }
  }
}

TEST(AdvtTest, DeterministicAndReusesTheTree) {
  PeakSearch model;
  auto run = [&](uint64_t seed) {
    Rng rng(seed);
    Advt<PeakSearch> planner(model, PeakOptions());
    planner.Reset(rng);
    return planner.Plan(Budget::Simulations(3000), rng);
  };
  auto a = run(9), b = run(9);
  EXPECT_EQ(a.action, b.action);
  EXPECT_EQ(a.value, b.value);
  EXPECT_EQ(a.root.size(), b.root.size());

  Rng rng(10);
  Advt<PeakSearch> planner(model, PeakOptions());
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(5000), rng);
  Rng sim(11);
  auto step = model.Step(0, d.action, sim);
  planner.Advance(d.action, step.observation, rng);
  EXPECT_GT(planner.RootVisits(), 0);
  auto d2 = planner.Plan(Budget::Simulations(500), rng);
  EXPECT_EQ(d2.stats.root_visits, d2.stats.reused_visits + 500);
}

TEST(AdvtTest, VdpTagWithObservationWideningHonoursTheBudget) {
  VdpTag tag;
  Rng rng(2);
  AdvtOptions o;
  o.search.max_depth = 10;
  o.search.num_particles = 2000;
  o.observations.k = 5.0;
  o.observations.alpha = 1.0 / 100.0;
  Advt<VdpTag> planner(tag, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Time(40.0), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_LT(d.stats.elapsed_ms, 40.0 + 60.0);
  EXPECT_GT(d.stats.simulations, 100);
  EXPECT_GE(planner.RootCells(), 2);
}

}  // namespace
}  // namespace npfkct
