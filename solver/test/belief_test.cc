#include "npfkct/solver/belief.h"

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "npfkct/solver/models/light_dark.h"
#include "npfkct/solver/models/rock_sample.h"
#include "npfkct/solver/models/tiger.h"

namespace npfkct {
namespace {

using models::RockSample;
using models::SimpleLightDark;
using models::Tiger;

double FractionLeft(const ParticleBelief<int>& b) {
  return b.Mean([](int s) { return s == 0 ? 1.0 : 0.0; });
}

TEST(ParticleBeliefTest, MeanWeighsTheParticles) {
  const ParticleBelief<int> b({1, 2, 10}, {1.0, 1.0, 2.0});
  EXPECT_DOUBLE_EQ(b.Mean([](int s) { return static_cast<double>(s); }), (1 + 2 + 20) / 4.0);
  const Eigen::Vector2d m = b.Mean([](int s) { return Eigen::Vector2d(s, -s); });
  EXPECT_DOUBLE_EQ(m[0], 23.0 / 4.0);
  EXPECT_DOUBLE_EQ(m[1], -23.0 / 4.0);
}

TEST(ParticleBeliefTest, LikelihoodUpdateMatchesBayes) {
  Tiger tiger;
  Rng rng(5);
  auto b = ParticleBelief<int>::FromInitial(tiger, 20000, rng);
  auto summary = b.Update(tiger, Tiger::kListen, 0, rng);
  EXPECT_EQ(summary.health, BeliefHealth::kHealthy);
  EXPECT_EQ(summary.num_particles, 20000);
  EXPECT_NEAR(FractionLeft(b), 0.85, 0.01);
  b.Update(tiger, Tiger::kListen, 0, rng);
  // 0.85^2 / (0.85^2 + 0.15^2)
  EXPECT_NEAR(FractionLeft(b), 0.9698, 0.01);
}

TEST(ParticleBeliefTest, RejectionUpdateMatchesBayes) {
  Tiger tiger;
  Rng rng(6);
  auto b = ParticleBelief<int>::FromInitial(tiger, 20000, rng);
  BeliefUpdateOptions options;
  options.method = BeliefUpdateOptions::Method::kRejection;
  auto summary = b.Update(tiger, Tiger::kListen, 1, rng, options);
  EXPECT_EQ(summary.health, BeliefHealth::kHealthy);
  EXPECT_EQ(b.size(), 20000);
  EXPECT_NEAR(FractionLeft(b), 0.15, 0.01);
}

TEST(ParticleBeliefTest, SystematicResamplingKeepsProportions) {
  ParticleBelief<int> b({0, 1, 2}, {0.2, 0.3, 0.5});
  Rng rng(1);
  b.Resample(1000, rng);
  int counts[3] = {0, 0, 0};
  for (int s : b.particles()) ++counts[s];
  EXPECT_NEAR(counts[0], 200, 2);
  EXPECT_NEAR(counts[1], 300, 2);
  EXPECT_NEAR(counts[2], 500, 2);
  EXPECT_DOUBLE_EQ(b.EffectiveSampleSize(), 1000.0);
}

TEST(ParticleBeliefTest, WeightedSamplingFollowsWeights) {
  ParticleBelief<int> b({0, 1}, {1.0, 3.0});
  Rng rng(2);
  int ones = 0;
  for (int i = 0; i < 40000; ++i) ones += b.Sample(rng);
  EXPECT_NEAR(ones / 40000.0, 0.75, 0.01);
  EXPECT_NEAR(b.EffectiveSampleSize(), 16.0 / 10.0, 1e-12);
}

// A model whose observations can contradict every particle and that cannot reinvigorate.
struct Deterministic {
  using State = int;
  using Action = int;
  using Observation = int;
  State SampleInitialState(Rng&) const { return 0; }
  StepResult<State, Observation> Step(const State& s, const Action&, Rng&) const {
    return {s, s, 0.0, false};
  }
  double Discount() const { return 0.9; }
  int NumActions() const { return 1; }
};

TEST(ParticleBeliefTest, DepletionIsAStatusNotACrash) {
  Deterministic model;
  Rng rng(3);
  auto b = ParticleBelief<int>::FromInitial(model, 100, rng);
  auto summary = b.Update(model, 0, 7, rng);  // every particle predicts observation 0
  EXPECT_EQ(summary.health, BeliefHealth::kDepleted);
  EXPECT_EQ(summary.consistent, 0);
  EXPECT_EQ(b.size(), 100);  // the prediction is kept
  EXPECT_STREQ(BeliefHealthName(summary.health), "depleted");
}

TEST(ParticleBeliefTest, DepletedLightDarkBeliefIsReinvigoratedFromTheObservation) {
  SimpleLightDark ld;
  Rng rng(4);
  // Every particle moves onto the light (noise 1e-4), so observing 12.0 is impossible for all.
  ParticleBelief<int> b(std::vector<int>(500, 9));
  auto summary = b.Update(ld, 3, 12.0, rng);
  EXPECT_EQ(summary.health, BeliefHealth::kReinvigorated);
  EXPECT_EQ(summary.consistent, 0);
  EXPECT_EQ(b.size(), 500);
  double mean = 0.0;
  for (int s : b.particles()) mean += s;
  EXPECT_NEAR(mean / 500, 12.0, 0.5);
}

TEST(ParticleBeliefTest, RockSampleReinvigorationAddsDiversity) {
  auto rs = RockSample::Standard78();
  Rng rng(8);
  RockSample::State s = rs.SampleInitialState(rng);
  s.good = 0;  // a belief collapsed on 'all rocks bad'
  ParticleBelief<RockSample::State> b(std::vector<RockSample::State>(400, s));
  BeliefUpdateOptions options;
  options.reinvigoration_fraction = 0.25;
  auto summary = b.Update(rs, RockSample::kEast, RockSample::kNone, rng, options);
  EXPECT_EQ(summary.health, BeliefHealth::kReinvigorated);
  EXPECT_GT(summary.reinvigorated, 50);
  int changed = 0;
  for (const auto& p : b.particles()) changed += (p.good != 0);
  EXPECT_GT(changed, 50);
  for (const auto& p : b.particles()) EXPECT_EQ(p.x, 1);  // moved east, position known
}

TEST(BeliefUpdateOptionsTest, ValidateNamesTheField) {
  BeliefUpdateOptions o;
  o.resample_threshold = 2.0;
  EXPECT_NE(o.Validate().message().find("resample_threshold"), std::string::npos);
  o = {};
  o.num_particles = -1;
  EXPECT_NE(o.Validate().message().find("num_particles"), std::string::npos);
}

}  // namespace
}  // namespace npfkct
