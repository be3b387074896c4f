#include "npfkct/solver/pomcpow.h"

#include <gtest/gtest.h>

#include <numbers>

#include "npfkct/solver/models/light_dark.h"
#include "npfkct/solver/models/tiger.h"
#include "npfkct/solver/models/vdp_tag.h"

namespace npfkct {
namespace {

using models::SimpleLightDark;
using models::Tiger;
using models::VdpTag;

PomcpowOptions LightDarkOptions() {
  PomcpowOptions o;
  o.exploration_c = 90.0;
  o.enable_action_pw = false;
  o.observations.k = 5.0;
  o.observations.alpha = 1.0 / 15.0;
  o.search.max_depth = 20;
  o.search.leaf_value = SearchOptions::LeafValue::kHeuristic;
  return o;
}

PomcpowOptions VdpOptions() {
  PomcpowOptions o;
  o.exploration_c = 110.0;
  o.k_action = 30.0;
  o.alpha_action = 1.0 / 30.0;
  o.observations.k = 5.0;
  o.observations.alpha = 1.0 / 100.0;
  o.search.max_depth = 10;
  o.search.num_particles = 2000;
  return o;
}

TEST(PomcpowOptionsTest, ValidateNamesTheOption) {
  PomcpowOptions o;
  o.k_action = 0.0;
  EXPECT_NE(o.Validate().message().find("k_action"), std::string::npos);
  o = {};
  o.alpha_action = 1.5;
  EXPECT_NE(o.Validate().message().find("alpha_action"), std::string::npos);
  o = {};
  o.observations.k = -1.0;
  EXPECT_NE(o.Validate().message().find("observations.k"), std::string::npos);
  o = VomcpowOptions();
  o.voo.uniform_probability = 1.5;
  EXPECT_NE(o.Validate().message().find("voo.uniform_probability"), std::string::npos);
  o = VomcpowOptions();
  o.voo.max_tries = 0;
  EXPECT_NE(o.Validate().message().find("voo.max_tries"), std::string::npos);
}

TEST(PomcpowTest, LightDarkDeclaresOnlyWhenSure) {
  SimpleLightDark ld;
  Rng rng(1);
  Pomcpow<SimpleLightDark> planner(ld, LightDarkOptions());
  planner.SetBelief(ParticleBelief<int>(std::vector<int>(1000, 0)));
  auto d = planner.Plan(Budget::Simulations(5000), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(d.action, SimpleLightDark::kDeclare);
  EXPECT_NEAR(d.value, 100.0, 1e-9);
  // From 20 the only two-move way to 0 is -10, -10.
  planner.SetBelief(ParticleBelief<int>(std::vector<int>(1000, 20)));
  EXPECT_EQ(planner.Plan(Budget::Simulations(5000), rng).action, 0);
  // From the wide initial belief it must not declare blindly.
  planner.Reset(rng);
  d = planner.Plan(Budget::Simulations(20000), rng);
  EXPECT_NE(d.action, SimpleLightDark::kDeclare);
  EXPECT_GT(d.value, 0.0);
  EXPECT_EQ(d.stats.root_actions, 5);
}

TEST(PomcpowTest, HybridBudgetDeterminismAndActionRanges) {
  VdpTag tag;
  auto run = [&](uint64_t seed) {
    Rng rng(seed);
    Pomcpow<VdpTag> planner(tag, VdpOptions());
    planner.Reset(rng);
    return planner.Plan(Budget::Simulations(3000), rng);
  };
  auto a = run(3), b = run(3);
  ASSERT_TRUE(a.status.ok());
  EXPECT_EQ(a.stats.simulations, 3000);
  EXPECT_EQ(a.action, b.action);
  EXPECT_EQ(a.value, b.value);
  ASSERT_EQ(a.root.size(), b.root.size());
  // Action widening: about k_a N^alpha_a actions at the root.
  EXPECT_GE(a.stats.root_actions, 30);
  EXPECT_LE(a.stats.root_actions, 40);
  for (const auto& r : a.root) {
    EXPECT_TRUE(r.action.kind == VdpTag::kMove || r.action.kind == VdpTag::kMoveAndLook);
    ASSERT_EQ(r.action.x.size(), 1);
    EXPECT_GE(r.action.x[0], 0.0);
    EXPECT_LE(r.action.x[0], 2 * std::numbers::pi);
  }
}

TEST(PomcpowTest, VoronoiSamplingConcentratesNearTheBestAction) {
  VdpTag tag;
  Rng rng(4);
  PomcpowOptions o = VdpOptions();
  o.use_voo = true;
  o.voo.uniform_probability = 0.0;  // always sample around the best action
  o.k_action = 8.0;
  o.alpha_action = 0.4;
  Pomcpow<VdpTag> planner(tag, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(4000), rng);
  ASSERT_TRUE(d.status.ok());
  const BoxSpace& box = tag.KindSpace(0);
  int near = 0, same_kind = 0;
  for (const auto& r : d.root) {
    if (r.action.kind != d.action.kind) continue;
    ++same_kind;
    near += box.Distance(r.action.x, d.action.x) < 1.0;
  }
  // Uniform headings would put about 1/pi of them within 1 rad; VOO puts far more.
  EXPECT_GT(same_kind, 10);
  EXPECT_GT(static_cast<double>(near) / same_kind, 0.5);
}

TEST(PomcpowTest, CpuBudgetIsHonoured) {
  // CPU time, which a loaded machine does not stretch (wall time is the benchmarks' business).
  VdpTag tag;
  Rng rng(5);
  PomcpowOptions o = VdpOptions();
  o.search.reuse_tree = false;
  Pomcpow<VdpTag> planner(tag, o);
  planner.Reset(rng);
  ASSERT_TRUE(planner.Plan(Budget::Simulations(30000), rng).status.ok());
  auto d = planner.Plan(Budget::Cpu(30.0), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_GE(d.stats.cpu_ms, 30.0);
  EXPECT_LT(d.stats.cpu_ms, 30.0 + 60.0);
  EXPECT_GT(d.stats.teardown_ms, 0.0);
}

TEST(PomcpowTest, TreeReuseOnDiscreteObservations) {
  const Tiger tiger(0.85, 0.95, Tiger::Rollout::kListen);
  Rng rng(6);
  PomcpowOptions o;
  o.enable_action_pw = false;
  o.observations.k = 2.0;  // at most a handful of observation children
  Pomcpow<Tiger> planner(tiger, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20000), rng);
  ASSERT_EQ(d.action, Tiger::kListen);
  planner.Advance(Tiger::kListen, 1, rng);
  EXPECT_GT(planner.RootVisits(), 1000);
  auto d2 = planner.Plan(Budget::Simulations(1000), rng);
  EXPECT_EQ(d2.stats.root_visits, d2.stats.reused_visits + 1000);
}

}  // namespace
}  // namespace npfkct
