// Candidate configurations aimed at what is left to see: NPF-kCT's proposals before the neural
// filter (paper algorithm 5 draws its candidates uniformly; aiming them first is ours).
//
//   const int c = TargetCandidate(world);               // 0: the guessed target
//   AimedCandidateSampler aimed(model);                  // a CandidateSampler for KCenterTree
//   RobotConfig view;
//   if (AimAt(world, point, rng, &view)) { ... }         // a feasible base looking at `point`
#pragma once

#include <array>
#include <vector>

#include "npfkct/object_search/model.h"
#include "npfkct/solver/candidates.h"

namespace npfkct::object_search {

/// The object the search is after now: the known object most likely to be the target (the
/// highest mean face odds, when that mean is above nu_p and it is not removed or declared an
/// obstacle), else 0, the guessed target.
int TargetCandidate(const World& world);

/// The face grids (bit k: corner k) of object `i` not yet confirmed in the direction `sign`
/// (+1: odds at most +declare_threshold; -1: at least -declare_threshold).
uint32_t UnconfirmedFaces(const World& world, int i, double sign);

/// A point just inside face grid (corner) `k` of `box`, where the simulator and the perception
/// pipeline look for it.
Vec3 FacePoint(const Box& box, int k);

/// A configuration whose camera looks at `point`: a base drawn uniformly from the base regions
/// (free of the map) whose camera lands 0.55-1.6 m from the point (up to 64 draws), a pan drawn
/// uniformly within the limits with the yaw that brings the point onto the optical axis, the tilt
/// that does the same (clamped to the limits) and a uniform lift. False when no base in range was
/// found.
bool AimAt(const World& world, const Vec3& point, Rng& rng, RobotConfig* out);

/// Settings of the aimed proposals.
struct ProposalOptions {
  /// Share of the move proposals aimed at the target candidate (placements of the guessed
  /// target drawn from the grid world, or the unconfirmed faces of a detected candidate).
  double target_share = 0.7;
  /// Share aimed at the unconfirmed faces of the other known objects (obstacles that may have to
  /// be declared and removed); goes to the target when there are none.
  double object_share = 0.2;
  /// The rest is uniform over the action box with a feasible base.
  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// Which source a proposal came from (ProposeMoves fills one per configuration).
enum class ProposalSource : uint8_t { kTarget, kObject, kUniform };

/// `count` move configurations: aimed at the target candidate, at other known objects' faces, or
/// uniform, by the shares of `options`, each with a feasible base. Fewer when `stop` (if given)
/// says the search must stop, or when a uniform draw finds no feasible base in 64 tries.
void ProposeMoves(const ObjectSearchModel& model, const ProposalOptions& options, int count,
                  Rng& rng, std::vector<RobotConfig>* configs, std::vector<ProposalSource>* sources,
                  const TerminationCondition* stop = nullptr);

/// NPF-kCT's candidate sampler without the neural filter: aimed proposals for the move kind,
/// uniform points for any other continuous kind. `model` must outlive it.
class AimedCandidateSampler final : public CandidateSampler<State> {
 public:
  explicit AimedCandidateSampler(const ObjectSearchModel& model, ProposalOptions options = {})
      : model_(model), options_(options) {}
  Status Sample(const ParticleBelief<State>& belief, int kind, const BoxSpace& box, int count,
                const TerminationCondition& stop, Rng& rng, std::vector<ActionVec>* out,
                CandidateStats* stats) override;

 private:
  const ObjectSearchModel& model_;
  ProposalOptions options_;
};

}  // namespace npfkct::object_search
