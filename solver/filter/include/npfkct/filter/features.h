// Inputs of the neural process filter (paper section 4.1, figure 15): the scene as a point cloud
// of the known objects and a top-down image of the grid world's odds, and per candidate action the
// robot configuration and the guessed target's 8 face odds; and the score g the network learns.
// Plain arrays only: no libtorch here.
#pragma once

#include <array>
#include <vector>

#include "npfkct/object_search/model.h"
#include "npfkct/solver/rng.h"

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
/// tilt normalised; camera position and viewing direction) then the 8 face odds of object 0.
inline constexpr int kConfigDim = 13;
inline constexpr int kQueryDim = kConfigDim + 8;
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

/// Writes the kQueryDim values of configuration `config` with object 0's face odds `odds`.
void QueryOf(const World& world, const RobotConfig& config, const std::array<float, 8>& odds,
             float* out);

/// Target placements drawn from the grid world's odds, as the model places the guessed target.
std::vector<Vec3> SamplePlacements(const World& world, int count, Rng& rng);

/// The score g of algorithm 4: the fraction of `placements` at which the guessed target (object 0
/// of `s`, moved there) would be seen from `config`, with every other object of `s` occluding.
double VisibilityScore(const ObjectSearchModel& model, const State& s, const RobotConfig& config,
                       const std::vector<Vec3>& placements);

/// Configurations scored exactly, with their queries.
struct ScoredConfigs {
  std::vector<RobotConfig> configs;
  std::vector<float> queries;  ///< configs.size() x kQueryDim.
  std::vector<float> scores;   ///< VisibilityScore of each.
};

/// `n` configurations drawn by SampleConfig, even ones aimed at a placement and odd ones uniform
/// (the mix of the training data and of Net_sam's context), with their queries (object 0's odds
/// of `s`) and exact scores against `placements`.
ScoredConfigs ScoreConfigs(const ObjectSearchModel& model, const State& s,
                           const std::vector<Vec3>& placements, int n, Rng& rng);

/// A configuration whose base is feasible in `world`: uniform over the action box (up to 64
/// draws; the last draw otherwise), or, when `aimed`, looking at one of `placements` from a base
/// 0.6-1.6 m away. The action box is the model's move space.
RobotConfig SampleConfig(const ObjectSearchModel& model, const std::vector<Vec3>& placements,
                         bool aimed, Rng& rng);

}  // namespace npfkct::filter
