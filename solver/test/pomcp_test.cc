#include "npfkct/solver/pomcp.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "npfkct/solver/models/rock_sample.h"
#include "npfkct/solver/models/tiger.h"

namespace npfkct {
namespace {

using models::RockSample;
using models::Tiger;

PomcpOptions TigerOptions() {
  PomcpOptions o;
  o.search.num_particles = 2000;
  return o;
}

// Random rollouts open a door two times in three and bury every value under -600; the 'always
// listen' default policy keeps leaf values near the truth.
const Tiger kTiger(0.85, 0.95, Tiger::Rollout::kListen);

TEST(PomcpOptionsTest, ValidateNamesTheOption) {
  PomcpOptions o;
  o.exploration_c = -1.0;
  EXPECT_NE(o.Validate().message().find("exploration_c"), std::string::npos);
  o = {};
  o.search.max_depth = 0;
  EXPECT_NE(o.Validate().message().find("search.max_depth"), std::string::npos);
  o = {};
  o.search.belief.resample_threshold = -1;
  EXPECT_NE(o.Validate().message().find("search.belief.resample_threshold"), std::string::npos);
  o = {};
  o.prior_count = -3;
  EXPECT_NE(o.Validate().message().find("prior_count"), std::string::npos);
}

TEST(PomcpTest, RejectsBadBudgetsAndOptions) {
  Tiger tiger;
  Rng rng(1);
  Pomcp<Tiger> planner(tiger, TigerOptions());
  planner.Reset(rng);
  auto d = planner.Plan(Budget{-5.0, 0}, rng);
  EXPECT_EQ(d.status.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(d.status.message().find("budget.time_ms"), std::string::npos);
  d = planner.Plan(Budget{0.0, 0}, rng);
  EXPECT_EQ(d.status.code(), StatusCode::kInvalidArgument);
  PomcpOptions bad = TigerOptions();
  bad.search.discount_horizon = 0.0;
  Pomcp<Tiger> bad_planner(tiger, bad);
  bad_planner.Reset(rng);
  EXPECT_NE(
      bad_planner.Plan(Budget::Simulations(10), rng).status.message().find("discount_horizon"),
      std::string::npos);
  Pomcp<Tiger> empty(tiger, TigerOptions());
  EXPECT_EQ(empty.Plan(Budget::Simulations(10), rng).status.code(),
            StatusCode::kFailedPrecondition);
}

TEST(PomcpTest, SimulationBudgetIsExact) {
  Tiger tiger;
  Rng rng(2);
  Pomcp<Tiger> planner(tiger, TigerOptions());
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(1234), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(d.stats.simulations, 1234);
  EXPECT_EQ(d.stats.root_visits, 1234);
  EXPECT_EQ(d.stats.root_actions, 3);
  int64_t visits = 0;
  for (const auto& a : d.root) visits += a.visits;
  EXPECT_EQ(visits, 1234);
}

TEST(PomcpTest, CpuBudgetIsHonouredIncludingTeardown) {
  // CPU time of the planning thread, which a loaded machine does not stretch (wall-time budgets
  // are measured by the benchmarks, not asserted here).
  auto rs = RockSample::Standard78();
  Rng rng(3);
  PomcpOptions o;
  o.search.reuse_tree = false;
  Pomcp<RockSample> planner(rs, o);
  planner.Reset(rng);
  ASSERT_TRUE(planner.Plan(Budget::Simulations(100000), rng).status.ok());
  ASSERT_GT(planner.TreeSize(), 100000);
  // The big tree must be torn down inside the next call's 40 ms of CPU.
  auto d = planner.Plan(Budget::Cpu(40.0), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_GT(d.stats.teardown_ms, 0.0);
  EXPECT_GE(d.stats.cpu_ms, 40.0);
  EXPECT_LE(d.stats.teardown_ms, d.stats.elapsed_ms);  // the teardown is inside the budget
  EXPECT_LT(d.stats.cpu_ms, 40.0 + 60.0);  // one simulation of overshoot, generous slack
}

TEST(PomcpTest, DeterministicUnderAFixedSeed) {
  auto rs = RockSample::Standard78();
  auto run = [&](uint64_t seed) {
    Rng rng(seed);
    Pomcp<RockSample> planner(rs, PomcpOptions{});
    planner.Reset(rng);
    return planner.Plan(Budget::Simulations(5000), rng);
  };
  auto a = run(11), b = run(11), c = run(12);
  ASSERT_EQ(a.root.size(), b.root.size());
  EXPECT_EQ(a.action, b.action);
  EXPECT_EQ(a.value, b.value);
  for (size_t i = 0; i < a.root.size(); ++i) {
    EXPECT_EQ(a.root[i].visits, b.root[i].visits);
    EXPECT_EQ(a.root[i].value, b.root[i].value);
  }
  bool differs = a.value != c.value;
  for (size_t i = 0; i < a.root.size(); ++i) differs |= a.root[i].visits != c.root[i].visits;
  EXPECT_TRUE(differs);
}

TEST(PomcpTest, TigerListensThenOpensTheOtherDoor) {
  const Tiger& tiger = kTiger;
  Rng rng(4);
  Pomcp<Tiger> planner(tiger, TigerOptions());
  planner.Reset(rng);
  EXPECT_EQ(planner.Plan(Budget::Simulations(20000), rng).action, Tiger::kListen);
  planner.Advance(Tiger::kListen, 0, rng);
  EXPECT_EQ(planner.Plan(Budget::Simulations(20000), rng).action, Tiger::kListen);
  planner.Advance(Tiger::kListen, 0, rng);
  // Heard the tiger on the left twice (P = 0.97): open the right door.
  EXPECT_EQ(planner.Plan(Budget::Simulations(20000), rng).action, Tiger::kOpenRight);
}

TEST(PomcpTest, TreeReuseKeepsTheMatchingSubtree) {
  const Tiger& tiger = kTiger;
  Rng rng(5);
  Pomcp<Tiger> reuse(tiger, TigerOptions());
  reuse.Reset(rng);
  auto d = reuse.Plan(Budget::Simulations(20000), rng);
  ASSERT_EQ(d.action, Tiger::kListen);
  const int64_t before = reuse.TreeSize();
  reuse.Advance(Tiger::kListen, 0, rng);
  // The new root carries the visits of the old (listen, hear-left) node.
  EXPECT_GT(reuse.RootVisits(), 1000);
  EXPECT_LT(reuse.TreeSize(), before);
  auto reused = reuse.Plan(Budget::Simulations(5000), rng);
  EXPECT_EQ(reused.stats.reused_visits + 5000, reused.stats.root_visits);
  // A fresh tree on the same belief reaches the same decision.
  PomcpOptions fresh_options = TigerOptions();
  fresh_options.search.reuse_tree = false;
  Pomcp<Tiger> fresh(tiger, fresh_options);
  fresh.SetBelief(reuse.belief());
  auto fresh_d = fresh.Plan(Budget::Simulations(20000), rng);
  EXPECT_EQ(fresh_d.action, reused.action);
  EXPECT_NEAR(fresh_d.value, reused.value, 3.0);
  // Without reuse the tree starts empty after a step.
  fresh.Advance(Tiger::kListen, 1, rng);
  EXPECT_EQ(fresh.RootVisits(), 0);
}

TEST(PomcpTest, RockSamplePrefersSensibleActions) {
  auto rs = RockSample::Standard78();
  Rng rng(6);
  Pomcp<RockSample> planner(rs, PomcpOptions{});
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20000), rng);
  ASSERT_TRUE(d.status.ok());
  // Legal at the start (no west, nothing to sample here); checking or moving towards rocks.
  EXPECT_NE(d.action, RockSample::kWest);
  EXPECT_NE(d.action, RockSample::kSample);
  EXPECT_GT(d.value, 0.0);
  EXPECT_GT(d.stats.max_depth, 3);
}

}  // namespace
}  // namespace npfkct
