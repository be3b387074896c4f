#include "npfkct/solver/despot.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "npfkct/solver/models/rock_sample.h"
#include "npfkct/solver/models/tag.h"
#include "npfkct/solver/models/tiger.h"

namespace npfkct {
namespace {

using models::RockSample;
using models::Tag;
using models::Tiger;

TEST(DespotOptionsTest, ValidateNamesTheOption) {
  EXPECT_TRUE(DespotOptions{}.Validate().ok());
  DespotOptions o;
  o.num_scenarios = 0;
  EXPECT_NE(o.Validate().message().find("num_scenarios"), std::string::npos);
  o = {};
  o.xi = 1.5;
  EXPECT_NE(o.Validate().message().find("xi"), std::string::npos);
  o = {};
  o.pruning_constant = -1.0;
  EXPECT_NE(o.Validate().message().find("pruning_constant"), std::string::npos);
  o = {};
  o.search.reuse_tree = true;
  EXPECT_NE(o.Validate().message().find("search.reuse_tree"), std::string::npos);
  o = {};
  o.search.threads = 2;
  EXPECT_NE(o.Validate().message().find("search.threads"), std::string::npos);
}

RockSample::State At(int x, int y, int good) {
  RockSample::State s;
  s.x = static_cast<int8_t>(x);
  s.y = static_cast<int8_t>(y);
  s.good = static_cast<uint16_t>(good);
  return s;
}

// The fully observable RockSample(3, 2) by value iteration over (x, y, good rocks left), stepping
// the model itself: an independent check of the closed-form UpperBound.
TEST(DespotTest, RockSampleUpperBoundIsTheFullyObservableValue) {
  const RockSample rs(3, {{1, 0}, {2, 2}}, {0, 1});
  const double gamma = rs.Discount();
  const int n = rs.size();
  auto index = [&](int x, int y, int left) { return (left * n + y) * n + x; };
  std::vector<double> v(static_cast<size_t>(n) * n * 4, 0.0);
  Rng rng(1);
  for (int sweep = 0; sweep < 200; ++sweep) {
    for (int left = 0; left < 4; ++left) {
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const RockSample::State s = At(x, y, left);
          double best = -1e9;
          for (int a = 0; a < RockSample::kFirstCheck; ++a) {
            auto step = rs.Step(s, a, rng);
            double q = step.reward;
            if (!step.terminal) {
              const int next_left = step.state.good & ~step.state.collected;
              q += gamma * v[index(step.state.x, step.state.y, next_left)];
            }
            best = std::max(best, q);
          }
          v[index(x, y, left)] = best;
        }
      }
    }
  }
  for (int left = 0; left < 4; ++left) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const RockSample::State s = At(x, y, left);
        EXPECT_NEAR(rs.UpperBound(s), v[index(x, y, left)], 1e-9)
            << "x " << x << " y " << y << " good " << left;
        // The default move ("go east") is a lower bound.
        EXPECT_LE(rs.DefaultMove(s).value, rs.UpperBound(s) + 1e-12);
        EXPECT_EQ(rs.DefaultMove(s).action, RockSample::kEast);
      }
    }
  }
}

TEST(DespotTest, TigerListensThenOpensTheOtherDoor) {
  const Tiger tiger(0.85, 0.95, Tiger::Rollout::kListen);
  DespotOptions o;
  o.search.num_particles = 2000;
  Rng rng(4);
  Despot<Tiger> planner(tiger, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(500), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  EXPECT_EQ(d.action, Tiger::kListen);
  planner.Advance(Tiger::kListen, 0, rng);
  EXPECT_EQ(planner.Plan(Budget::Simulations(500), rng).action, Tiger::kListen);
  planner.Advance(Tiger::kListen, 0, rng);
  // Heard the tiger on the left twice (P = 0.97): open the right door.
  EXPECT_EQ(planner.Plan(Budget::Simulations(500), rng).action, Tiger::kOpenRight);
}

// Tiger with a default policy of a node's scenarios taken together: listen, in every scenario.
struct ListeningTiger : Tiger {
  using Tiger::Tiger;
  mutable int calls = 0;
  void DefaultPolicyActions(const std::vector<int>& states, std::vector<int>* out) const {
    ++calls;
    out->assign(states.size(), Tiger::kListen);
  }
};

TEST(DespotTest, AModelsJointDefaultPolicyGivesTheLowerBound) {
  const ListeningTiger tiger(0.85, 0.95, Tiger::Rollout::kListen);
  DespotOptions o;
  o.max_policy_sim_len = 10;
  Rng rng(4);
  Despot<ListeningTiger> planner(tiger, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(20), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  // Every new belief node asks the policy once per step of its 10-step rollout.
  EXPECT_GE(tiger.calls, 10);
  EXPECT_EQ(tiger.calls % 10, 0);
  // Listening for 10 steps is worth -(1 - 0.95^10) / 0.05 = -8.03; the search keeps the lower
  // bound at least that, and listens first.
  EXPECT_GE(d.value, -(1.0 - std::pow(0.95, 10)) / 0.05 - 1e-9);
  EXPECT_EQ(d.action, Tiger::kListen);
}

TEST(DespotTest, TagShortestPathBoundIsAnUpperBound) {
  // U(s) >= r + gamma U(s') on every transition and U = 0 once tagged: then U is at least the
  // fully observable value, so at least the value of any policy.
  const Tag tag;
  Rng rng(2);
  for (int robot = 0; robot < tag.num_cells(); ++robot) {
    for (int opponent = 0; opponent < tag.num_cells(); ++opponent) {
      const Tag::State s{static_cast<int8_t>(robot), static_cast<int8_t>(opponent), false};
      for (int a = 0; a < tag.NumActions(); ++a) {
        for (int k = 0; k < 20; ++k) {
          auto step = tag.Step(s, a, rng);
          const double next = step.terminal ? 0.0 : tag.UpperBound(step.state);
          EXPECT_GE(tag.UpperBound(s) + 1e-12, step.reward + tag.Discount() * next)
              << "robot " << robot << " opponent " << opponent << " action " << a;
        }
      }
    }
  }
}

TEST(DespotTest, TagTagsOnlyWhenItSeesTheOpponent) {
  const Tag tag;
  Rng rng(3);
  DespotOptions o;
  o.num_scenarios = 100;  // rollouts of up to 90 steps from each scenario of each new node
  Despot<Tag> planner(tag, o);
  planner.Reset(rng);
  // Told it shares its cell with the opponent: tag.
  planner.Advance(Tag::kWest, tag.same_cell(), rng);
  auto d = planner.Plan(Budget::Simulations(30), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  EXPECT_EQ(d.action, Tag::kTag);
  // Told only where it is: a tag there fails for sure, so move.
  planner.Reset(rng);
  planner.Advance(Tag::kWest, 9, rng);
  d = planner.Plan(Budget::Simulations(30), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  EXPECT_NE(d.action, Tag::kTag);
}

TEST(DespotTest, RockSampleSearchTightensTheRootBoundsAndMovesSensibly) {
  const auto rs = RockSample::Standard78();
  Rng rng(6);
  Despot<RockSample> planner(rs, DespotOptions{});
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(300), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(d.stats.simulations, 300);
  // Going east blindly is worth 10 * 0.95^6 = 7.35; the search finds better at the start.
  EXPECT_GT(d.value, 10.0 * std::pow(0.95, 6) + 1.0);
  EXPECT_NE(d.action, RockSample::kWest);
  EXPECT_NE(d.action, RockSample::kSample);
  EXPECT_GT(d.stats.max_depth, 3);
  int64_t trials = 0;
  for (const auto& a : d.root) trials += a.visits;
  EXPECT_EQ(trials, 300);
}

TEST(DespotTest, RegularizationFallsBackToTheDefaultMove) {
  // A pruning constant larger than any reward makes every policy node cost more than it can
  // gain: the regularized value is the default policy's, and its action ("go east") is chosen.
  const auto rs = RockSample::Standard78();
  DespotOptions o;
  o.pruning_constant = 100.0;
  Rng rng(7);
  Despot<RockSample> planner(rs, o);
  planner.Reset(rng);
  auto d = planner.Plan(Budget::Simulations(100), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(d.action, RockSample::kEast);
  EXPECT_NEAR(d.value, 10.0 * std::pow(0.95, 6), 1e-9);
}

TEST(DespotTest, DeterministicUnderAFixedSeed) {
  const auto rs = RockSample::Standard78();
  auto run = [&](uint64_t seed) {
    Rng rng(seed);
    Despot<RockSample> planner(rs, DespotOptions{});
    planner.Reset(rng);
    return planner.Plan(Budget::Simulations(100), rng);
  };
  auto a = run(11), b = run(11), c = run(12);
  ASSERT_EQ(a.root.size(), b.root.size());
  EXPECT_EQ(a.action, b.action);
  EXPECT_EQ(a.value, b.value);
  for (size_t i = 0; i < a.root.size(); ++i) EXPECT_EQ(a.root[i].value, b.root[i].value);
  EXPECT_NE(a.value, c.value);
}

TEST(DespotTest, RejectsAnEmptyBeliefAndBadBudgets) {
  const auto rs = RockSample::Standard78();
  Rng rng(8);
  Despot<RockSample> planner(rs, DespotOptions{});
  EXPECT_EQ(planner.Plan(Budget::Simulations(10), rng).status.code(),
            StatusCode::kFailedPrecondition);
  planner.Reset(rng);
  auto d = planner.Plan(Budget{-5.0, 0}, rng);
  EXPECT_EQ(d.status.code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace npfkct
