// Checks of the benchmark models against their published definitions.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "npfkct/solver/models/light_dark.h"
#include "npfkct/solver/models/rock_sample.h"
#include "npfkct/solver/models/tag.h"
#include "npfkct/solver/models/tiger.h"
#include "npfkct/solver/models/vdp_tag.h"

namespace npfkct::models {
namespace {

TEST(TigerTest, RewardsAndReset) {
  Tiger tiger;
  Rng rng(1);
  auto r = tiger.Step(0, Tiger::kListen, rng);
  EXPECT_EQ(r.reward, -1.0);
  EXPECT_EQ(r.state, 0);
  EXPECT_EQ(tiger.Step(0, Tiger::kOpenLeft, rng).reward, -100.0);
  EXPECT_EQ(tiger.Step(0, Tiger::kOpenRight, rng).reward, 10.0);
  int left_after_reset = 0, correct = 0;
  for (int i = 0; i < 10000; ++i) {
    left_after_reset += tiger.Step(0, Tiger::kOpenRight, rng).state == 0;
    correct += tiger.Step(1, Tiger::kListen, rng).observation == 1;
  }
  EXPECT_NEAR(left_after_reset / 10000.0, 0.5, 0.02);
  EXPECT_NEAR(correct / 10000.0, 0.85, 0.01);
  EXPECT_DOUBLE_EQ(tiger.ObservationLikelihood(Tiger::kListen, 1, 0), 0.15);
  EXPECT_DOUBLE_EQ(tiger.ObservationLikelihood(Tiger::kOpenLeft, 1, 0), 0.5);
}

TEST(RockSampleTest, StandardLayout) {
  auto rs = RockSample::Standard78();
  EXPECT_EQ(rs.size(), 7);
  EXPECT_EQ(rs.num_rocks(), 8);
  EXPECT_EQ(rs.NumActions(), 13);
  EXPECT_EQ(rs.start(), std::make_pair(0, 3));
  EXPECT_EQ(rs.rock(0), std::make_pair(2, 0));
  EXPECT_EQ(rs.rock(3), std::make_pair(6, 3));
  EXPECT_EQ(rs.rock(7), std::make_pair(1, 6));
  // Efficiency (1 + 2^(-d/20)) / 2: from the start, rock 3 at (6, 3) is 6 away.
  EXPECT_NEAR(rs.Efficiency(0, 3, 3), 0.5 * (1 + std::exp2(-6.0 / 20.0)), 1e-12);
  EXPECT_DOUBLE_EQ(rs.Efficiency(2, 0, 0), 1.0);
}

TEST(RockSampleTest, MovesExitAndSampling) {
  auto rs = RockSample::Standard78();
  Rng rng(2);
  RockSample::State s = rs.SampleInitialState(rng);
  s.good = 0b00000001;  // only rock 0 is good
  // Walking east 6 times then once more exits with +10.
  for (int i = 0; i < 6; ++i) {
    auto r = rs.Step(s, RockSample::kEast, rng);
    EXPECT_EQ(r.reward, 0.0);
    s = r.state;
  }
  auto exit = rs.Step(s, RockSample::kEast, rng);
  EXPECT_EQ(exit.reward, 10.0);
  EXPECT_TRUE(exit.terminal);
  // Off the grid elsewhere costs 100 and keeps the position.
  RockSample::State w = rs.SampleInitialState(rng);
  auto west = rs.Step(w, RockSample::kWest, rng);
  EXPECT_EQ(west.reward, -100.0);
  EXPECT_EQ(west.state.x, 0);
  // Sampling: good rock +10 then it is collected (and bad); empty cell -100.
  RockSample::State at0 = w;
  at0.x = 2;
  at0.y = 0;
  at0.good = 1;
  auto sample = rs.Step(at0, RockSample::kSample, rng);
  EXPECT_EQ(sample.reward, 10.0);
  EXPECT_EQ(sample.state.collected, 1);
  EXPECT_EQ(rs.Step(sample.state, RockSample::kSample, rng).reward, -100.0);
  at0.good = 0;
  EXPECT_EQ(rs.Step(at0, RockSample::kSample, rng).reward, -10.0);
  EXPECT_EQ(rs.Step(w, RockSample::kSample, rng).reward, -100.0);
}

TEST(RockSampleTest, CheckIsNoisyByDistanceAndTracksEvidence) {
  auto rs = RockSample::Standard78();
  Rng rng(3);
  RockSample::State s = rs.SampleInitialState(rng);
  s.good = 0xff;
  int good = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    good += rs.Step(s, RockSample::kFirstCheck + 3, rng).observation == RockSample::kGood;
  }
  EXPECT_NEAR(static_cast<double>(good) / n, rs.Efficiency(0, 3, 3), 0.01);
  auto r = rs.Step(s, RockSample::kFirstCheck + 1, rng);
  EXPECT_EQ(r.state.measured[1], 1);
  EXPECT_EQ(std::abs(r.state.evidence[1]), 1);
}

TEST(RockSampleTest, LegalAndPreferredActions) {
  auto rs = RockSample::Standard78();
  Rng rng(4);
  RockSample::State s = rs.SampleInitialState(rng);
  std::vector<int> legal;
  rs.LegalActions(s, &legal);
  // At (0, 3): N, E, S (no W, no sample), 8 checks.
  EXPECT_EQ(legal.size(), 3u + 8u);
  std::vector<int> preferred;
  rs.PreferredActions(s, &preferred);
  // No evidence yet: all rocks interesting; W is off the grid.
  EXPECT_NE(std::find(preferred.begin(), preferred.end(), RockSample::kEast), preferred.end());
  EXPECT_EQ(std::find(preferred.begin(), preferred.end(), RockSample::kWest), preferred.end());
  // Every rock believed bad: prefer exiting east.
  for (int i = 0; i < 8; ++i) s.evidence[i] = -2;
  rs.PreferredActions(s, &preferred);
  EXPECT_EQ(preferred, std::vector<int>{RockSample::kEast});
  // Standing on a rock believed good: sample it.
  s.x = 0;
  s.y = 1;
  s.evidence[1] = 2;
  rs.PreferredActions(s, &preferred);
  EXPECT_EQ(preferred, std::vector<int>{RockSample::kSample});
}

TEST(SimpleLightDarkTest, DynamicsRewardsAndObservations) {
  SimpleLightDark ld;
  Rng rng(5);
  auto r = ld.Step(5, 4, rng);  // +10
  EXPECT_EQ(r.state, 15);
  EXPECT_EQ(r.reward, -1.0);
  EXPECT_EQ(ld.Step(58, 4, rng).state, 60);  // clamped
  auto declare = ld.Step(0, SimpleLightDark::kDeclare, rng);
  EXPECT_EQ(declare.reward, 100.0);
  EXPECT_TRUE(declare.terminal);
  EXPECT_EQ(ld.Step(3, SimpleLightDark::kDeclare, rng).reward, -100.0);
  // Near the light observations are precise; far away they are not.
  EXPECT_NEAR(ld.Step(9, 3, rng).observation, 10.0, 1e-2);
  EXPECT_DOUBLE_EQ(SimpleLightDark::NoiseStd(-30), 40.0001);
  for (int i = 0; i < 1000; ++i) {
    const int s0 = ld.SampleInitialState(rng);
    EXPECT_GE(s0, -30);
    EXPECT_LE(s0, 30);
  }
}

TEST(SimpleLightDarkTest, DiscretisedObservationsAreBinsWithTheirGaussianMass) {
  const double bin = 0.5;
  SimpleLightDark ld(bin);
  EXPECT_EQ(ld.observation_bin(), bin);
  Rng rng(7);
  // At 9 the noise is 1.0001: the bin index is floor(o / 0.5), a whole number.
  for (int i = 0; i < 100; ++i) {
    const double o = ld.Step(8, 3, rng).observation;
    EXPECT_EQ(o, std::floor(o));
    EXPECT_GT(o, 9.0 / bin - 12.0);
    EXPECT_LT(o, 9.0 / bin + 12.0);
  }
  // The bins' masses sum to one, and each is the Gaussian's mass on [o, o + 1) * bin.
  double total = 0.0;
  for (int o = -200; o < 200; ++o) total += ld.ObservationLikelihood(3, 9, o);
  EXPECT_NEAR(total, 1.0, 1e-9);
  const double sd = SimpleLightDark::NoiseStd(9);
  const double expected = 0.5 * (std::erf((9.5 - 9.0) / (sd * std::sqrt(2.0))) -
                                 std::erf((9.0 - 9.0) / (sd * std::sqrt(2.0))));
  EXPECT_NEAR(ld.ObservationLikelihood(3, 9, 18.0), expected, 1e-12);
  // An invalid width means continuous observations.
  EXPECT_EQ(SimpleLightDark(-1.0).observation_bin(), 0.0);
}

TEST(SimpleLightDarkTest, MdpValueIsExact) {
  SimpleLightDark ld;
  EXPECT_NEAR(ld.HeuristicValue(0), 100.0, 1e-9);
  EXPECT_NEAR(ld.HeuristicValue(1), -1.0 + 0.95 * 100.0, 1e-9);
  EXPECT_NEAR(ld.HeuristicValue(10), -1.0 + 0.95 * 100.0, 1e-9);
  EXPECT_NEAR(ld.HeuristicValue(11), -1.0 + 0.95 * (-1.0 + 0.95 * 100.0), 1e-9);
}

// The labelled leaf value: the light first by the fewest moves, then 0 and the declaration.
TEST(SimpleLightDarkTest, LocalizeLeafGoesByTheLight) {
  SimpleLightDark ld(0.0, SimpleLightDark::Leaf::kLocalize);
  const double at_light = -1.0 + 0.95 * 100.0;  // -10, then declare
  EXPECT_NEAR(ld.HeuristicValue(10), at_light, 1e-9);
  EXPECT_NEAR(ld.HeuristicValue(0), -1.0 + 0.95 * at_light, 1e-9);  // +10 first
  EXPECT_NEAR(ld.HeuristicValue(9), -1.0 + 0.95 * at_light, 1e-9);  // +1
  // -28: +10 +10 +10 +10 -1 -1 (6 moves), fewer than +10 x3 and +1 x8.
  const double g6 = std::pow(0.95, 6);
  EXPECT_NEAR(ld.HeuristicValue(-28), -(1.0 - g6) / 0.05 + g6 * at_light, 1e-9);
  EXPECT_EQ(ld.HeuristicValue(SimpleLightDark::kTerminal), 0.0);
  // The default leaf is the fully observable value.
  EXPECT_NEAR(SimpleLightDark().HeuristicValue(0), 100.0, 1e-9);
}

TEST(VdpTagTest, TargetFollowsVanDerPolWithRk4) {
  // One RK4 substep by hand from (1, 0): f = (mu (x - x^3/3 - y), x / mu).
  double x = 1.0, y = 0.0;
  double nx, ny;
  VdpTag::NextMlTarget(x, y, &nx, &ny);
  // The oscillator's limit cycle has amplitude about 2; the motion is smooth and bounded.
  EXPECT_GT(nx, 1.0);
  EXPECT_GT(ny, 0.0);
  EXPECT_LT(std::hypot(nx - x, ny - y), 1.0);
  // From the origin (a fixed point) the target does not move.
  VdpTag::NextMlTarget(0.0, 0.0, &nx, &ny);
  EXPECT_EQ(nx, 0.0);
  EXPECT_EQ(ny, 0.0);
}

TEST(VdpTagTest, BarriersStopTheAgent) {
  double nx, ny;
  // Moving up across the +x barrier (y = 0, x in [0.2, 3.0]) stops just below it.
  VdpTag::BarrierStop(1.0, -0.25, 0.0, 0.5, &nx, &ny);
  EXPECT_NEAR(nx, 1.0, 1e-12);
  EXPECT_NEAR(ny, 0.0, 1e-9);
  EXPECT_LT(ny, 0.0);
  // Through the central gap (|x| < 0.2) the agent passes.
  VdpTag::BarrierStop(0.1, -0.25, 0.0, 0.5, &nx, &ny);
  EXPECT_NEAR(ny, 0.25, 1e-9);
  // Beyond the barrier's end (x > 3) it passes too.
  VdpTag::BarrierStop(3.2, -0.25, 0.0, 0.5, &nx, &ny);
  EXPECT_NEAR(ny, 0.25, 1e-9);
}

TEST(VdpTagTest, BeamsRewardsAndLikelihood) {
  EXPECT_EQ(VdpTag::ActiveBeam(1.0, 0.1), 0);
  EXPECT_EQ(VdpTag::ActiveBeam(0.1, 1.0), 1);
  EXPECT_EQ(VdpTag::ActiveBeam(-1.0, -0.1), 4);
  EXPECT_EQ(VdpTag::ActiveBeam(1.0, -0.1), 7);
  EXPECT_EQ(VdpTag::ActiveBeam(1.0, 0.0), 7);  // theta = 0 maps to 2 pi: the last beam
  VdpTag tag;
  Rng rng(6);
  // The target sits on the oscillator's fixed point (0, 0) and only jitters (std 0.05); the agent
  // steps onto it and tags it with probability 1 - exp(-2) = 0.86.
  VdpTag::State s{-0.5, 0.0, 0.0, 0.0, false};
  HybridAction east{VdpTag::kMove, MakeActionVec({0.0})};
  int tags = 0;
  for (int i = 0; i < 200; ++i) {
    auto r = tag.Step(s, east, rng);
    if (r.terminal) {
      ++tags;
      EXPECT_EQ(r.reward, 100.0);
    } else {
      EXPECT_EQ(r.reward, -1.0);
    }
  }
  EXPECT_NEAR(tags / 200.0, 0.86, 0.08);
  HybridAction look{VdpTag::kMoveAndLook, MakeActionVec({std::numbers::pi})};
  auto r = tag.Step(VdpTag::State{0, 0, 3, 3, false}, look, rng);
  EXPECT_EQ(r.reward, -6.0);
  EXPECT_GT(tag.ObservationLikelihood(look, r.state, r.observation), 0.0);
  // A looking observation of a target at (2, 0.5) (beam 0, distance 2.06): far more likely under
  // the true state than under a target mirrored into beam 3.
  const VdpTag::State truth{0, 0, 2.0, 0.5, false};
  VdpTag::Observation o;
  for (int b = 0; b < 8; ++b) o[b] = 1.0 + 5.0 * rng.Normal();
  o[0] = std::hypot(2.0, 0.5) + 0.1 * rng.Normal();
  const VdpTag::State mirrored{0, 0, -2.0, 0.5, false};
  EXPECT_GT(tag.ObservationLikelihood(look, truth, o),
            1e3 * tag.ObservationLikelihood(look, mirrored, o));
  // Without looking the beam is noisy (std 5) and the two states are hard to tell apart.
  const double ratio =
      tag.ObservationLikelihood(HybridAction{VdpTag::kMove, MakeActionVec({0})}, truth, o) /
      tag.ObservationLikelihood(HybridAction{VdpTag::kMove, MakeActionVec({0})}, mirrored, o);
  EXPECT_LT(ratio, 10.0);
}

TEST(TagTest, PineausFloor) {
  const Tag tag;
  ASSERT_EQ(tag.num_cells(), 29);
  // The room's nine cells are columns 5-7 of rows 0-2; the corridor is rows 3-4, columns 0-9.
  int room = 0;
  for (int i = 0; i < tag.num_cells(); ++i) {
    if (tag.y(i) < 3) {
      ++room;
      EXPECT_GE(tag.x(i), 5);
      EXPECT_LE(tag.x(i), 7);
    }
  }
  EXPECT_EQ(room, 9);
  // On this floor the shortest path is the Manhattan distance; walls stop a move.
  for (int i = 0; i < tag.num_cells(); ++i) {
    for (int j = 0; j < tag.num_cells(); ++j) {
      EXPECT_EQ(tag.Distance(i, j), std::abs(tag.x(i) - tag.x(j)) + std::abs(tag.y(i) - tag.y(j)));
    }
  }
  EXPECT_EQ(tag.Distance(0, 28), 2 + 4 + 2);  // (5, 0) to (9, 4)
  EXPECT_EQ(tag.Neighbour(0, Tag::kNorth), 0);
  EXPECT_EQ(tag.Neighbour(0, Tag::kWest), 0);
}

TEST(TagTest, RewardsObservationsAndTheOpponentRunningAway) {
  const Tag tag;
  Rng rng(3);
  const int corner = 9;  // (0, 3), the corridor's west end
  ASSERT_EQ(tag.x(corner), 0);
  ASSERT_EQ(tag.y(corner), 3);
  Tag::State s{static_cast<int8_t>(corner), static_cast<int8_t>(corner), false};
  auto r = tag.Step(s, Tag::kTag, rng);
  EXPECT_EQ(r.reward, 10.0);
  EXPECT_TRUE(r.terminal);
  EXPECT_EQ(r.observation, tag.same_cell());
  // A failed tag costs 10 and the robot stays; a move costs 1 and is observed.
  s.opponent = 15;  // (6, 3)
  r = tag.Step(s, Tag::kTag, rng);
  EXPECT_EQ(r.reward, -10.0);
  EXPECT_FALSE(r.terminal);
  EXPECT_EQ(r.state.robot, corner);
  r = tag.Step(s, Tag::kEast, rng);
  EXPECT_EQ(r.reward, -1.0);
  EXPECT_EQ(r.state.robot, tag.Neighbour(corner, Tag::kEast));
  EXPECT_EQ(r.observation, r.state.robot);
  EXPECT_DOUBLE_EQ(tag.ObservationLikelihood(Tag::kEast, r.state, r.state.robot), 1.0);
  EXPECT_DOUBLE_EQ(tag.ObservationLikelihood(Tag::kEast, r.state, tag.same_cell()), 0.0);
  // Robot at the corridor's west end, opponent at (2, 3) in the same row: 0.4 east, 0.2 south,
  // 0.2 north (a wall: stays), 0.2 stays.
  s.opponent = 11;
  ASSERT_EQ(tag.x(11), 2);
  ASSERT_EQ(tag.y(11), 3);
  int moved_east = 0, stayed = 0, went_south = 0;
  const int trials = 20000;
  for (int i = 0; i < trials; ++i) {
    const int o = tag.Step(s, Tag::kTag, rng).state.opponent;
    moved_east += o == tag.Neighbour(11, Tag::kEast);
    stayed += o == 11;
    went_south += o == tag.Neighbour(11, Tag::kSouth);
  }
  EXPECT_NEAR(moved_east / static_cast<double>(trials), 0.4, 0.02);
  EXPECT_NEAR(went_south / static_cast<double>(trials), 0.2, 0.02);
  EXPECT_NEAR(stayed / static_cast<double>(trials), 0.4, 0.02);
}

TEST(TagTest, DefaultPolicyChasesTheMostCommonOpponentCell) {
  const Tag tag;
  // The robot at the corridor's west end (cell 9); most scenarios put the opponent at (2, 3)
  // (cell 11), one at (0, 4) (cell 19), one shares the robot's cell.
  std::vector<Tag::State> states = {{9, 11, false}, {9, 11, false}, {9, 19, false}, {9, 9, false}};
  std::vector<int> actions;
  tag.DefaultPolicyActions(states, &actions);
  ASSERT_EQ(actions.size(), states.size());
  EXPECT_EQ(actions[0], Tag::kEast);
  EXPECT_EQ(actions[1], Tag::kEast);
  EXPECT_EQ(actions[2], Tag::kEast);  // the most common cell, not its own
  EXPECT_EQ(actions[3], Tag::kTag);   // it observes that it shares the opponent's cell
  // Where the most common cell is a scenario's own robot cell (before the first observation the
  // robot's cell differs between scenarios), the next most common: from (2, 3) towards (0, 4).
  states = {{9, 11, false}, {9, 11, false}, {11, 19, false}};
  tag.DefaultPolicyActions(states, &actions);
  EXPECT_EQ(actions[0], Tag::kEast);
  EXPECT_EQ(actions[2], Tag::kSouth);
}

TEST(TagTest, UpperBoundAndRolloutAndReinvigoration) {
  const Tag tag;
  Rng rng(5);
  Tag::State s{9, 9, false};
  EXPECT_DOUBLE_EQ(tag.UpperBound(s), 10.0);
  EXPECT_EQ(tag.RolloutAction(s, rng), Tag::kTag);
  s.opponent = 11;  // two moves east
  EXPECT_NEAR(tag.UpperBound(s), -1.0 - 0.95 + 10.0 * 0.95 * 0.95, 1e-12);
  for (int i = 0; i < 100; ++i) {
    const int a = tag.RolloutAction(s, rng);
    EXPECT_NE(a, Tag::kTag);
    EXPECT_NE(tag.Neighbour(s.robot, a), s.robot);  // never into a wall
  }
  Tag::State out;
  ASSERT_TRUE(tag.Reinvigorate(s, Tag::kEast, 10, rng, &out));
  EXPECT_EQ(out.robot, 10);
  EXPECT_EQ(out.opponent, 11);
  ASSERT_TRUE(tag.Reinvigorate(s, Tag::kEast, 11, rng, &out));
  EXPECT_EQ(out.robot, 11);
  EXPECT_NE(out.opponent, 11);
  ASSERT_TRUE(tag.Reinvigorate(s, Tag::kEast, tag.same_cell(), rng, &out));
  EXPECT_EQ(out.robot, out.opponent);
  EXPECT_FALSE(tag.Reinvigorate(s, Tag::kEast, tag.same_cell() + 1, rng, &out));
}

}  // namespace
}  // namespace npfkct::models
