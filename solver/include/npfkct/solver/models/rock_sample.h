// RockSample(n, k) (Smith & Simmons 2004) as implemented in Silver & Veness' POMCP 1.0.
#pragma once

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "npfkct/solver/model.h"

namespace npfkct::models {

/// RockSample: a rover on an n x n grid (x grows east, y grows north) with k rocks of unknown
/// value. Moving east off the grid exits (+10, terminal); other moves off the grid and sampling an
/// empty cell cost 100; sampling a rock pays +10 if good, -10 if bad (it is then collected).
/// Checking rock i returns its true value with efficiency (1 + 2^(-d/20)) / 2. Discount 0.95.
///
/// The state also carries per-rock evidence (#good - #bad check observations and the number of
/// checks), which is history, not hidden state: Silver's 'preferred actions' knowledge uses it.
class RockSample {
 public:
  static constexpr int kMaxRocks = 16;

  struct State {
    int8_t x = 0;
    int8_t y = 0;
    bool terminal = false;
    uint16_t good = 0;                         ///< Bit i: rock i is good.
    uint16_t collected = 0;                    ///< Bit i: rock i has been sampled.
    uint16_t certain = 0;                      ///< Bit i: rock i was checked from distance 0.
    std::array<int8_t, kMaxRocks> evidence{};  ///< #good - #bad observations per rock.
    std::array<int8_t, kMaxRocks> measured{};  ///< Checks per rock.
    /// Log-odds that rock i is good given its check observations (the posterior, since rocks are
    /// independent a priori and each check observes one rock).
    std::array<float, kMaxRocks> log_odds{};

    friend bool operator==(const State&, const State&) = default;
  };
  using Action = int;
  using Observation = int;

  static constexpr int kNorth = 0;
  static constexpr int kEast = 1;
  static constexpr int kSouth = 2;
  static constexpr int kWest = 3;
  static constexpr int kSample = 4;
  static constexpr int kFirstCheck = 5;
  static constexpr int kNone = 0;
  static constexpr int kGood = 1;
  static constexpr int kBad = 2;

  /// A grid of `size` with the given rocks (x, y) and start cell.
  RockSample(int size, std::vector<std::pair<int, int>> rocks, std::pair<int, int> start,
             double half_efficiency_distance = 20.0, double discount = 0.95);
  /// The standard RockSample(7, 8) layout.
  static RockSample Standard78();
  /// The standard RockSample(11, 11) layout.
  static RockSample Standard1111();

  State SampleInitialState(Rng& rng) const;
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return discount_; }
  bool IsTerminal(const State& s) const { return s.terminal; }
  int NumActions() const { return kFirstCheck + num_rocks(); }
  void LegalActions(const State& s, std::vector<int>* out) const;
  /// Silver & Veness' 'smart' knowledge: sample rocks believed good, head towards rocks not
  /// believed bad, check uncertain rocks, exit east when every remaining rock seems bad.
  void PreferredActions(const State& s, std::vector<int>* out) const;
  /// A uniformly random preferred action (legal when there are none).
  Action RolloutAction(const State& s, Rng& rng) const;
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  /// Rewrites the evidence of a check in `sp` (stepped from `s`) as if `o` had been observed.
  void Condition(const State& s, const Action& a, const Observation& o, State* sp) const;
  /// A Metropolis-Hastings move in the spirit of POMCP's local transforms: flip one random
  /// uncollected rock of `near`, accepted with probability min(1, posterior ratio) from the rock's
  /// log-odds, so the belief keeps its posterior while regaining diversity.
  bool Reinvigorate(const State& near, const Action& a, const Observation& o, Rng& rng,
                    State* out) const;
  /// DESPOT's upper bound: the value of `s` with its rocks known, the best order of visiting and
  /// sampling the good rocks left and then exiting east (the fully observable MDP's value, as the
  /// authors' RockSampleMDPParticleUpperBound; for more than 12 rocks the looser sum of each good
  /// rock's discounted reward and the exit's).
  double UpperBound(const State& s) const;
  /// DESPOT's default lower bound for RockSample: go east and exit, worth 10 gamma^(size - 1 - x).
  ValuedAction<Action> DefaultMove(const State& s) const;
  double MinReward() const { return -10.0; }
  double MaxReward() const { return 10.0; }

  int size() const { return size_; }
  int num_rocks() const { return static_cast<int>(rocks_.size()); }
  std::pair<int, int> rock(int i) const { return rocks_[i]; }
  std::pair<int, int> start() const { return start_; }
  /// Sensor efficiency for rock i seen from (x, y).
  double Efficiency(int x, int y, int i) const;

 private:
  int RockAt(int x, int y) const;
  void RecordCheck(const State& before, int rock, Observation o, State* after) const;

  int size_;
  std::vector<std::pair<int, int>> rocks_;
  std::pair<int, int> start_;
  double half_distance_;
  double discount_;
  std::vector<int8_t> grid_;  // rock index per cell or -1
  // The MDP value after sampling rock r with the good rocks `left` still to sample, at
  // [r << num_rocks | left]; empty above kMaxExactBoundRocks.
  std::vector<double> after_sampling_;
  static constexpr int kMaxExactBoundRocks = 12;
  std::vector<double> discount_powers_;  // gamma^d, d = 0 .. 2 size
  double ExitValue(int x) const;
  // Moves from (x, y) to rock r.
  int RockDistance(int r, int x, int y) const;
  // The best of exiting and of sampling each rock of `left` next, from (x, y).
  double BestFrom(int x, int y, uint32_t left) const;
};

}  // namespace npfkct::models
