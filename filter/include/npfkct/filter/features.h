// Inputs of the neural process filter (paper section 4.1, figure 15): the scene as a point cloud
// of the known objects and a top-down image of the grid world's odds, and per candidate action the
// robot configuration and the target candidate (the guessed target before detection, the most
// likely detected target after) with its 8 face odds; and the score g the network learns.
// Plain arrays only: no libtorch here.
#pragma once

#include <array>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/object_search/model.h"
#include "npfkct/object_search/proposals.h"

namespace npfkct::filter {

using object_search::ObjectSearchModel;
using object_search::RobotConfig;
using object_search::State;
using object_search::Vec3;
using object_search::World;

/// Points in the object cloud and values per point: x, y, z (scene-normalised), the log-odds of
/// the nearest face grid over the odds limit, and moveability.
inline constexpr int kPoints = 256;
inline constexpr int kPointDim = 5;
/// The top-down image: side in pixels and channels (target odds as probability, furniture height,
/// object height, base feasibility), every value in [0, 1].
inline constexpr int kImageSize = 64;
inline constexpr int kImageChannels = 4;
/// A query (one candidate action): 13 configuration values (x, y, cos yaw, sin yaw, lift, pan,
/// tilt normalised; camera position and viewing direction); 16 values describing the target
/// candidate: 1 when it is the guessed target; for a detected candidate its center, sizes, cos and
/// sin of its yaw, and its center in the camera's frame (depth, left, up) over the camera's far
/// range; then what the frustum alone (no occlusion) would show of it - for the guessed target the
/// share of the probe placements inside the frustum, for a detected one the share of its
/// unconfirmed face grids among the 4 nearest the camera whose points are inside - and the mean
/// position of those points in the image (depth over far, left and up over the frustum's half
/// extents); then the candidate's 8 face odds over the odds limit. Occlusion is the network's to
/// learn from the scene.
inline constexpr int kConfigDim = 13;
inline constexpr int kCandidateDim = 16;
/// Placements drawn once per scene that the frustum features of the guessed target probe.
inline constexpr int kProbePlacements = 32;
inline constexpr int kQueryDim = kConfigDim + kCandidateDim + 8;
/// Actions with a score above this are efficient (paper appendix G).
inline constexpr double kEfficientScore = 0.05;

/// The per-planning-step part of the network's input.
struct SceneFeatures {
  std::vector<float> points;  ///< kPoints x kPointDim, row-major.
  std::vector<float> image;   ///< kImageChannels x kImageSize x kImageSize.
};

/// The scene encoding inputs of a World: points sampled on the surfaces of the known objects
/// (objects 1.., not removed; zeros when there are none) and the top-down image over the map.
SceneFeatures SceneOf(const World& world, Rng& rng);

/// Writes the kQueryDim values of configuration `config` for target candidate `candidate` (an
/// object index of `world`; 0: the guessed target, whose odds are the re-initialised guess odds,
/// probed at `probe`: kProbePlacements placements drawn by SamplePlacements).
void QueryOf(const World& world, const RobotConfig& config, int candidate,
             const std::vector<Vec3>& probe, float* out);

/// Target placements drawn from the grid world's odds, as the model places the guessed target.
std::vector<Vec3> SamplePlacements(const World& world, int count, Rng& rng);

/// The score g the network learns, by the model's own observation rule: for the guessed target
/// (candidate 0), the fraction of `placements` at which object 0 of `s`, moved there, would be
/// seen from `config`; for a detected candidate i, the share of its not yet confirmed face grids
/// (odds at most the declaration threshold) that a view from `config` would update - the model
/// updates the 4 grids nearest to the camera of every object it sees - over min(4, unconfirmed);
/// 0 when all are confirmed.
double TargetScore(const ObjectSearchModel& model, const State& s, int candidate,
                   const RobotConfig& config, const std::vector<Vec3>& placements);

/// The mix of proposals the network is trained on and scores at run time: aimed at the target
/// candidate, at other known objects, and uniform.
object_search::ProposalOptions TrainingProposals();

/// Configurations scored exactly, with their queries.
struct ScoredConfigs {
  std::vector<RobotConfig> configs;
  std::vector<float> queries;  ///< configs.size() x kQueryDim.
  std::vector<float> scores;   ///< TargetScore of each.
};

/// `n` configurations proposed by object_search::ProposeMoves with the training mix, with their
/// queries (probing the guessed target at `probe`) and exact scores for the target candidate of
/// the model's world (the guessed target's against `placements`). Fewer when `stop` (if given)
/// says the search must stop.
ScoredConfigs ScoreConfigs(const ObjectSearchModel& model, const State& s,
                           const std::vector<Vec3>& placements, const std::vector<Vec3>& probe,
                           int n, Rng& rng, const TerminationCondition* stop = nullptr);

}  // namespace npfkct::filter
