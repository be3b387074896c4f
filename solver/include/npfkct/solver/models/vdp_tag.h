// VDP Tag with barriers (Sunberg & Kochenderfer 2018; VDPTag2.jl before its 2025 change).
#pragma once

#include <array>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::models {

/// VDP Tag: an agent at the origin must tag (come within 0.1 of) a target whose motion follows a
/// Van der Pol oscillator (mu = 2, five RK4 steps of 0.1 per decision step, plus N(0, 0.05^2)
/// noise). The agent moves 0.5 per step in any direction and stops at four barriers on the half
/// axes from 0.2 to 3.0. Actions: kind 0 moves, kind 1 moves and looks (costs 5); the continuous
/// part is the heading in [0, 2 pi). Observations: 8 beams of 45 degrees; the beam containing the
/// target reads N(distance, 0.1 if looking else 5), the others N(1, 5). Tag +100 (terminal), else
/// -1 per step. Target starts uniform on [-4, 4]^2. Discount 0.95.
class VdpTag {
 public:
  struct State {
    double ax = 0.0, ay = 0.0;  ///< Agent position.
    double tx = 0.0, ty = 0.0;  ///< Target position.
    bool tagged = false;
    friend bool operator==(const State&, const State&) = default;
  };
  using Action = HybridAction;
  using Observation = std::array<double, 8>;

  static constexpr int kMove = 0;
  static constexpr int kMoveAndLook = 1;

  /// Rollout policy of the leaf estimate.
  enum class Rollout {
    kRandom,    ///< Uniform random kind and heading (POMCPOW paper, 2018).
    kToNextMl,  ///< Head for the target's noise-free next position, never look (VPW paper, 2021).
  };

  explicit VdpTag(Rollout rollout = Rollout::kRandom);

  State SampleInitialState(Rng& rng) const;
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return 0.95; }
  bool IsTerminal(const State& s) const { return s.tagged; }
  void ActionKinds(const State& s, std::vector<int>* out) const;
  const BoxSpace& KindSpace(int /*kind*/) const { return heading_; }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  Action RolloutAction(const State& s, Rng& rng) const;
  /// RolloutFirst's action with the ToNextML rollout: move from the belief's mean agent position
  /// towards the noise-free next position of its mean target (VOOTreeSearch.jl's
  /// RootToNextMLFirst); RolloutAction at a drawn state otherwise.
  Action BeliefRolloutAction(const ParticleBelief<State>& belief, Rng& rng) const;
  double MinReward() const { return -6.0; }
  double MaxReward() const { return 100.0; }

  /// The target position after one decision step without noise.
  static void NextMlTarget(double x, double y, double* nx, double* ny);
  /// Where an agent at (x, y) moving by (dx, dy) ends, stopping short of the barriers.
  static void BarrierStop(double x, double y, double dx, double dy, double* nx, double* ny);
  /// The beam (0..7) that contains direction (dx, dy); beam b covers angles (b, b+1] * 45 deg.
  static int ActiveBeam(double dx, double dy);

 private:
  Rollout rollout_;
  BoxSpace heading_;
};

}  // namespace npfkct::models
