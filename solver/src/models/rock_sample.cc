#include "npfkct/solver/models/rock_sample.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace npfkct::models {

RockSample::RockSample(int size, std::vector<std::pair<int, int>> rocks, std::pair<int, int> start,
                       double half_efficiency_distance, double discount)
    : size_(size),
      rocks_(std::move(rocks)),
      start_(start),
      half_distance_(half_efficiency_distance),
      discount_(discount),
      grid_(static_cast<size_t>(size) * size, -1) {
  for (int i = 0; i < num_rocks(); ++i) grid_[rocks_[i].second * size_ + rocks_[i].first] = i;
  // gamma^d for every Manhattan distance on the grid.
  for (int d = 0; d <= 2 * size_; ++d) discount_powers_.push_back(std::pow(discount_, d));
  const int k = num_rocks();
  if (k <= kMaxExactBoundRocks) {
    // Subsets in increasing order: a subset's value needs only its strict subsets'.
    after_sampling_.assign(static_cast<size_t>(k) << k, 0.0);
    for (uint32_t left = 0; left < (1u << k); ++left) {
      for (int r = 0; r < k; ++r) {
        if (left & (1u << r)) continue;
        after_sampling_[(static_cast<size_t>(r) << k) | left] =
            BestFrom(rocks_[r].first, rocks_[r].second, left);
      }
    }
  }
}

int RockSample::RockDistance(int r, int x, int y) const {
  return std::abs(rocks_[r].first - x) + std::abs(rocks_[r].second - y);
}

double RockSample::ExitValue(int x) const { return 10.0 * discount_powers_[size_ - 1 - x]; }

double RockSample::BestFrom(int x, int y, uint32_t left) const {
  const int k = num_rocks();
  double best = ExitValue(x);
  for (int r = 0; r < k; ++r) {
    if (!(left & (1u << r))) continue;
    const int d = RockDistance(r, x, y);
    const uint32_t rest = left & ~(1u << r);
    // d moves, the sample's +10 at step d, the rest from the rock at step d + 1.
    best = std::max(best,
                    discount_powers_[d] *
                        (10.0 + discount_ * after_sampling_[(static_cast<size_t>(r) << k) | rest]));
  }
  return best;
}

double RockSample::UpperBound(const State& s) const {
  if (s.terminal) return 0.0;
  const uint32_t left = static_cast<uint32_t>(s.good) & ~static_cast<uint32_t>(s.collected);
  if (!after_sampling_.empty()) return BestFrom(s.x, s.y, left);
  double total = ExitValue(s.x);
  for (int r = 0; r < num_rocks(); ++r) {
    if (!(left & (1u << r))) continue;
    total += 10.0 * discount_powers_[RockDistance(r, s.x, s.y)];
  }
  return total;
}

ValuedAction<RockSample::Action> RockSample::DefaultMove(const State& s) const {
  return {kEast, s.terminal ? 0.0 : ExitValue(s.x)};
}

RockSample RockSample::Standard78() {
  return RockSample(7, {{2, 0}, {0, 1}, {3, 1}, {6, 3}, {2, 4}, {3, 4}, {5, 5}, {1, 6}}, {0, 3});
}

RockSample RockSample::Standard1111() {
  return RockSample(
      11, {{0, 3}, {0, 7}, {1, 8}, {2, 4}, {3, 3}, {3, 8}, {4, 3}, {5, 8}, {6, 1}, {9, 3}, {9, 9}},
      {0, 5});
}

int RockSample::RockAt(int x, int y) const { return grid_[y * size_ + x]; }

double RockSample::Efficiency(int x, int y, int i) const {
  const double dx = x - rocks_[i].first;
  const double dy = y - rocks_[i].second;
  return 0.5 * (1.0 + std::exp2(-std::sqrt(dx * dx + dy * dy) / half_distance_));
}

RockSample::State RockSample::SampleInitialState(Rng& rng) const {
  State s;
  s.x = static_cast<int8_t>(start_.first);
  s.y = static_cast<int8_t>(start_.second);
  s.good = static_cast<uint16_t>(rng() & ((1u << num_rocks()) - 1u));
  return s;
}

StepResult<RockSample::State, RockSample::Observation> RockSample::Step(const State& s,
                                                                        const Action& a,
                                                                        Rng& rng) const {
  StepResult<State, Observation> r{s, kNone, 0.0, s.terminal};
  if (s.terminal) return r;
  State& n = r.state;
  switch (a) {
    case kNorth:
      if (n.y + 1 < size_) {
        ++n.y;
      } else {
        r.reward = -100.0;
      }
      return r;
    case kEast:
      if (n.x + 1 < size_) {
        ++n.x;
      } else {
        r.reward = 10.0;
        n.terminal = true;
        r.terminal = true;
      }
      return r;
    case kSouth:
      if (n.y > 0) {
        --n.y;
      } else {
        r.reward = -100.0;
      }
      return r;
    case kWest:
      if (n.x > 0) {
        --n.x;
      } else {
        r.reward = -100.0;
      }
      return r;
    case kSample: {
      const int rock = RockAt(n.x, n.y);
      const uint16_t bit = rock >= 0 ? static_cast<uint16_t>(1u << rock) : 0;
      if (rock < 0 || (n.collected & bit)) {
        r.reward = -100.0;
        return r;
      }
      r.reward = (n.good & bit) ? 10.0 : -10.0;
      n.collected |= bit;
      n.good &= static_cast<uint16_t>(~bit);
      return r;
    }
    default:
      break;
  }
  const int rock = a - kFirstCheck;
  const bool good = (n.good >> rock) & 1u;
  const double eta = Efficiency(n.x, n.y, rock);
  const bool correct = rng.Uniform() < eta;
  r.observation = (good == correct) ? kGood : kBad;
  RecordCheck(s, rock, r.observation, &n);
  return r;
}

void RockSample::RecordCheck(const State& before, int rock, Observation o, State* after) const {
  after->evidence[rock] = static_cast<int8_t>(before.evidence[rock] + (o == kGood ? 1 : -1));
  // log(eta / (1 - eta)), capped where the check is certain (eta = 1 at distance 0).
  const double eta = Efficiency(before.x, before.y, rock);
  const float lr = eta >= 1.0 ? 50.0f : static_cast<float>(std::log(eta / (1.0 - eta)));
  after->log_odds[rock] = before.log_odds[rock] + ((o == kGood) ? lr : -lr);
  after->measured[rock] = static_cast<int8_t>(std::min(before.measured[rock] + 1, 100));
  if (before.x == rocks_[rock].first && before.y == rocks_[rock].second) {
    after->certain |= static_cast<uint16_t>(1u << rock);
  }
}

void RockSample::Condition(const State& s, const Action& a, const Observation& o, State* sp) const {
  if (a < kFirstCheck || s.terminal || (o != kGood && o != kBad)) return;
  RecordCheck(s, a - kFirstCheck, o, sp);
}

void RockSample::LegalActions(const State& s, std::vector<int>* out) const {
  out->clear();
  if (s.y + 1 < size_) out->push_back(kNorth);
  out->push_back(kEast);
  if (s.y > 0) out->push_back(kSouth);
  if (s.x > 0) out->push_back(kWest);
  const int here = RockAt(s.x, s.y);
  if (here >= 0 && !((s.collected >> here) & 1u)) out->push_back(kSample);
  for (int i = 0; i < num_rocks(); ++i) {
    if (!((s.collected >> i) & 1u)) out->push_back(kFirstCheck + i);
  }
}

void RockSample::PreferredActions(const State& s, std::vector<int>* out) const {
  out->clear();
  const int here = RockAt(s.x, s.y);
  if (here >= 0 && !((s.collected >> here) & 1u) && s.evidence[here] > 0) {
    out->push_back(kSample);
    return;
  }
  bool any = false, north = false, east = false, south = false, west = false;
  for (int i = 0; i < num_rocks(); ++i) {
    if (((s.collected >> i) & 1u) || s.evidence[i] < 0) continue;
    any = true;
    north |= rocks_[i].second > s.y;
    east |= rocks_[i].first > s.x;
    south |= rocks_[i].second < s.y;
    west |= rocks_[i].first < s.x;
  }
  if (!any) {
    out->push_back(kEast);
    return;
  }
  if (north && s.y + 1 < size_) out->push_back(kNorth);
  if (east) out->push_back(kEast);
  if (south && s.y > 0) out->push_back(kSouth);
  if (west && s.x > 0) out->push_back(kWest);
  for (int i = 0; i < num_rocks(); ++i) {
    if (((s.collected >> i) & 1u) || ((s.certain >> i) & 1u)) continue;  // ProbValuable in {0, 1}
    if (s.measured[i] < 5 && std::abs(s.evidence[i]) < 2) out->push_back(kFirstCheck + i);
  }
}

RockSample::Action RockSample::RolloutAction(const State& s, Rng& rng) const {
  thread_local std::vector<int> actions;
  PreferredActions(s, &actions);
  if (actions.empty()) LegalActions(s, &actions);
  return actions[rng.UniformInt(static_cast<int64_t>(actions.size()))];
}

double RockSample::ObservationLikelihood(const Action& a, const State& sp,
                                         const Observation& o) const {
  if (a < kFirstCheck) return o == kNone ? 1.0 : 0.0;
  if (o == kNone) return 0.0;
  const int rock = a - kFirstCheck;
  const bool good = (sp.good >> rock) & 1u;
  const double eta = Efficiency(sp.x, sp.y, rock);
  return ((o == kGood) == good) ? eta : 1.0 - eta;
}

bool RockSample::Reinvigorate(const State& near, const Action&, const Observation&, Rng& rng,
                              State* out) const {
  if (near.terminal || num_rocks() == 0) return false;
  *out = near;
  const int flip = static_cast<int>(rng.UniformInt(num_rocks()));
  if ((out->collected >> flip) & 1u) return false;
  const bool was_good = (out->good >> flip) & 1u;
  // Posterior ratio P(flipped) / P(current) = exp(-+ log_odds).
  const double log_ratio = was_good ? -out->log_odds[flip] : out->log_odds[flip];
  if (log_ratio < 0.0 && rng.Uniform() >= std::exp(log_ratio)) return false;
  out->good ^= static_cast<uint16_t>(1u << flip);
  return true;
}

}  // namespace npfkct::models
