// The procedural scene generator behind npfkct-scenegen: rooms nobody tuned a planner for.
//
//   const std::string text = GenerateScenarioJson(42);   // a scenario file, reproducible from 42
//   StatusOr<Scenario> s = ParseScenario(text);           // always parses
//
// Seeds are split by use (docs/benchmarks.md lists them): the filter trains on seeds below
// kHeldOutSeedBase, and the benchmark's held-out scenes are kHeldOutSeedBase + 1 ... + 30.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace npfkct::sim {

/// The first held-out seed minus one: benchmark scenes use seeds above it, training data below.
inline constexpr uint64_t kHeldOutSeedBase = 900000;
/// Generator version 2's seeds: its tuning scenes are kTuningV2SeedBase + 1 ... + 30 and its
/// held-out scenes kHeldOutV2SeedBase + 1 ... + 60, stratified by placement (1-20 in the open,
/// 21-40 hidden, 41-60 covered). Training data stays below kHeldOutSeedBase.
inline constexpr uint64_t kTuningV2SeedBase = 850000;
inline constexpr uint64_t kHeldOutV2SeedBase = 930000;

/// How the generated scene hides its target.
enum class TargetPlacement {
  kOpen,     ///< Somewhere on a workspace, in the open.
  kHidden,   ///< Behind one to three tall boxes standing next to it (visible from another side).
  kCovered,  ///< Inside a larger box that must be declared an obstacle and removed first.
};

/// What a generated scene looks like (for logs and tests).
struct SceneSummary {
  std::string robot;  ///< "fetch" or "stretch".
  int furniture = 0;  ///< Pieces of furniture (all workspaces), 1-4.
  int objects = 0;    ///< Objects including the target, 3-40 (version 2: up to 60).
  TargetPlacement placement = TargetPlacement::kOpen;
  /// Version 2: how the target is hidden or covered ("walls", "pocket", "cover",
  /// "stacked covers", "walled cover"; "open").
  std::string variant;
  int decoys = 0;  ///< Version 2: empty covers and wall pockets elsewhere.
};

/// Which laws the generator draws a scene by.
struct SceneOptions {
  /// 1: the first held-out set's laws. 2: besides, decoy covers and wall pockets from the same
  /// size laws (so the cover is not the largest box), immovable large boxes, any yaw for every
  /// object, clutter near the target, stacked covers and walled covers.
  int version = 1;
  /// Forces the target's placement (a stratified held-out set); absent: drawn with the scene.
  std::optional<TargetPlacement> placement;
};

/// The options of generator version 2's scene `seed`: a held-out seed's placement is its stratum.
SceneOptions V2Options(uint64_t seed);

/// A scenario file (JSON text in the format of scenarios/README.md) generated from `seed`: a room
/// with 1-4 pieces of furniture of varied size (0.6-1.6 m x 0.4-0.9 m), height (0.4-1.1 m) and
/// yaw, a base region beside every side, 3-40 objects of varied size, a target that is in the
/// open, hidden behind others or covered by a larger box, a Fetch or a Stretch starting in its
/// rest pose out of sight of every workspace. The same seed gives the same text byte for byte.
/// Every scene is checked to be solvable: the target's face grids can be seen from the base
/// regions once the boxes hiding it are removed.
std::string GenerateScenarioJson(uint64_t seed, SceneSummary* summary = nullptr,
                                 const SceneOptions& options = {});

}  // namespace npfkct::sim
