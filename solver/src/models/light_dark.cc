#include "npfkct/solver/models/light_dark.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace npfkct::models {

SimpleLightDark::SimpleLightDark(double observation_bin, Leaf leaf)
    : observation_bin_(observation_bin > 0.0 && std::isfinite(observation_bin) ? observation_bin
                                                                               : 0.0),
      leaf_value_(2 * kRadius + 1, 0.0) {
  // Value iteration on the fully observable problem: the leaf value unless kLocalize replaces it.
  std::vector<double> next(leaf_value_.size());
  for (int iter = 0; iter < 2000; ++iter) {
    double change = 0.0;
    for (int s = -kRadius; s <= kRadius; ++s) {
      double best = (s == 0) ? 100.0 : -100.0;
      for (int move : kMoves) {
        if (move == 0) continue;
        const int sp = std::clamp(s + move, -kRadius, kRadius);
        best = std::max(best, -1.0 + Discount() * leaf_value_[sp + kRadius]);
      }
      next[s + kRadius] = best;
      change = std::max(change, std::abs(best - leaf_value_[s + kRadius]));
    }
    leaf_value_.swap(next);
    if (change < 1e-9) break;
  }
  if (leaf == Leaf::kLocalize) {
    const double at_light = leaf_value_[kLight + kRadius];
    // The fewest moves to the light (relaxed until nothing changes), then the light's own value
    // (one move to 0 and the declaration), each move costing 1 and discounted.
    std::vector<int> moves(leaf_value_.size(), 2 * kRadius + 1);
    moves[kLight + kRadius] = 0;
    for (bool changed = true; changed;) {
      changed = false;
      for (int s = -kRadius; s <= kRadius; ++s) {
        for (int move : kMoves) {
          if (move == 0) continue;
          const int to = std::clamp(s + move, -kRadius, kRadius);
          if (moves[to + kRadius] + 1 < moves[s + kRadius]) {
            moves[s + kRadius] = moves[to + kRadius] + 1;
            changed = true;
          }
        }
      }
    }
    for (int s = -kRadius; s <= kRadius; ++s) {
      const double g = std::pow(Discount(), moves[s + kRadius]);
      leaf_value_[s + kRadius] = -(1.0 - g) / (1.0 - Discount()) + g * at_light;
    }
  }
}

SimpleLightDark::State SimpleLightDark::SampleInitialState(Rng& rng) const {
  return static_cast<int>(rng.UniformInt(61)) - 30;
}

StepResult<SimpleLightDark::State, SimpleLightDark::Observation> SimpleLightDark::Step(
    const State& s, const Action& a, Rng& rng) const {
  StepResult<State, Observation> r;
  if (s == kTerminal) {
    r.state = kTerminal;
    r.terminal = true;
  } else if (a == kDeclare) {
    r.reward = (s == 0) ? 100.0 : -100.0;
    r.state = kTerminal;
    r.terminal = true;
  } else {
    r.reward = -1.0;
    r.state = std::clamp(s + kMoves[a], -kRadius, kRadius);
  }
  r.observation = rng.Normal(r.state, NoiseStd(r.state));
  if (observation_bin_ > 0.0) r.observation = std::floor(r.observation / observation_bin_);
  return r;
}

double SimpleLightDark::ObservationLikelihood(const Action&, const State& sp,
                                              const Observation& o) const {
  const double sd = NoiseStd(sp);
  if (observation_bin_ > 0.0) {  // the Gaussian's mass on bin o
    auto cdf = [&](double x) { return 0.5 * std::erfc(-(x - sp) / (sd * std::numbers::sqrt2)); };
    return cdf((o + 1.0) * observation_bin_) - cdf(o * observation_bin_);
  }
  const double z = (o - sp) / sd;
  return std::exp(-0.5 * z * z) / (sd * std::sqrt(2.0 * std::numbers::pi));
}

double SimpleLightDark::HeuristicValue(const State& s) const {
  if (s == kTerminal) return 0.0;
  return leaf_value_[s + kRadius];
}

bool SimpleLightDark::Reinvigorate(const State&, const Action& a, const Observation& o, Rng& rng,
                                   State* out) const {
  if (a == kDeclare || !std::isfinite(o)) return false;
  const double centre = observation_bin_ > 0.0 ? (o + 0.5) * observation_bin_ : o;
  const double guess = rng.Normal(centre, NoiseStd(centre));
  *out = static_cast<int>(std::clamp(std::round(guess), -double{kRadius}, double{kRadius}));
  return true;
}

}  // namespace npfkct::models
