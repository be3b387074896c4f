// Scenario files: the furniture, workspaces, base regions and objects of an object-search world,
// read from JSON (format in scenarios/README.md).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/object_search/world.h"

namespace npfkct::sim {

using object_search::Box;
using object_search::RobotConfig;
using object_search::Vec2;
using object_search::Vec3;

/// An RGB colour.
using Color = std::array<uint8_t, 3>;

/// A piece of furniture of the prior map; its top may be a workspace.
struct Furniture {
  std::string name;
  Box box;                 ///< Stands on the floor: center.z = size.z / 2.
  bool workspace = false;  ///< Whether objects may stand on its top.
  Color color = {140, 110, 80};
};

/// An object of the scene (unknown to the robot until it sees it).
struct SceneObject {
  std::string name;
  Box box;
  Color color = {200, 200, 200};
  bool target = false;
  bool moveable = true;
  /// Seed of the printed pattern on its faces (the target's photo texture); 0: plain colour.
  uint32_t texture_seed = 0;
};

/// Noise of the simulated robot and sensors.
struct SimNoise {
  double pose_xy = 0.02;          ///< Std of the base position after a move (m).
  double pose_yaw = 0.02;         ///< Std of the base yaw after a move (rad).
  double object_jitter = 0.0;     ///< Std of the objects' placement per seed (m).
  double box_estimate = 0.005;    ///< Std of detected box centers and sizes (m).
  double detection = 0.08;        ///< Std of a face's detection score.
  double false_detection = 0.03;  ///< Probability that a face's detection is flipped.
  /// Std of the base pose the robot reports with raw frames (its localization error; m, rad),
  /// which perception's registration corrects.
  double localization_xy = 0.03;
  double localization_yaw = 0.02;
};

/// A complete scenario.
struct Scenario {
  std::string name;
  std::string description;
  /// The robot ("robot" in the file: "fetch", "stretch", a description or a URDF; api::ParseRobot).
  object_search::RobotDescription robot = object_search::RobotDescription::Fetch();
  Vec2 room_min = Vec2(-3, -3);
  Vec2 room_max = Vec2(3, 3);
  double map_resolution = 0.05;
  std::vector<Furniture> furniture;
  std::vector<object_search::BaseRegion> base_regions;
  std::vector<RobotConfig> discrete_poses;
  std::vector<SceneObject> objects;
  RobotConfig start;
  SimNoise noise;
  object_search::SearchParams params;

  /// Checks the scenario; the message names the offending field.
  Status Validate() const;
  /// Checks the prior-map part only (no objects).
  Status ValidateWorld() const;
  /// The workspaces (furniture tops) as grid-world surfaces.
  std::vector<object_search::Workspace> Workspaces() const;
  /// The prior-map part: what the robot knows before it looks.
  object_search::PriorMap Prior() const;
};

/// Parses a scenario from JSON text. Errors are INVALID_ARGUMENT naming the field path, e.g.
/// "objects[2].size: expected 3 numbers".
StatusOr<Scenario> ParseScenario(const std::string& json_text);

/// Reads and parses a scenario file.
StatusOr<Scenario> LoadScenario(const std::string& path);

/// The robot's initial knowledge of a scenario: prior map (furniture boxes, occupancy inflated
/// for nothing else than the footprint check), base regions, grid world over the workspaces, no
/// objects but the guessed target, the robot at the start.
StatusOr<object_search::World> InitialWorld(const Scenario& scenario);

}  // namespace npfkct::sim
