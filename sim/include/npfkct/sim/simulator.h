// The built-in world simulator: it plays the role Gazebo plays in the paper. It holds the true
// scene, executes the robot's actions (with pose noise), and observes: either the geometric
// observation (which faces of which objects are visible, with detection scores) for fast
// benchmarking, or rendered RGB-D frames by ray casting (render.h).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/object_search/model.h"
#include "npfkct/sim/scenario.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::sim {

/// What executing one action did in the true world.
struct ExecutionOutcome {
  double reward = 0.0;    ///< The paper's reward table applied to the true scene.
  bool terminal = false;  ///< The target was removed.
  bool success = false;   ///< A discrete action succeeded (declaration correct, removal done).
  bool illegal = false;   ///< The action was illegal in the true world.
  std::string detail;     ///< Human-readable account ("declared box3 obstacle", ...).
};

/// A camera frame rendered by ray casting: 8-bit RGB (row-major, 3 bytes per pixel), depth in
/// metres (0 where nothing was hit within range), and per-pixel ids (-1 floor/none, furniture
/// 1000 + index, scene objects their index).
struct Frame {
  int width = 0;
  int height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;  ///< Pinhole intrinsics.
  object_search::CameraPose pose;         ///< Camera pose in the world frame.
  std::vector<uint8_t> rgb;
  std::vector<float> depth;
  std::vector<int16_t> ids;
};

/// The colour of the printed pattern of an object with texture `seed` on box face `face` (0/1:
/// -x/+x, 2/3: -y/+y, 4/5: -z/+z) at face coordinates (u, v) in [0, 1].
Color PatternColor(uint32_t seed, int face, double u, double v);

/// The simulated world of a scenario.
class Simulator {
 public:
  /// The scene of `scenario`, with its objects jittered by `seed` (noise.object_jitter), so that
  /// a seed reproduces the world exactly.
  Simulator(Scenario scenario, uint64_t seed);

  const Scenario& scenario() const { return scenario_; }
  const RobotConfig& robot() const { return robot_; }
  const std::vector<SceneObject>& objects() const { return objects_; }
  /// Whether scene object i was removed.
  bool removed(int i) const { return removed_[i]; }
  /// Index of the target among the scene objects.
  int target_index() const { return target_; }
  /// The robot's prior knowledge of this scene (map, workspaces, start).
  StatusOr<object_search::World> InitialWorld() const { return sim::InitialWorld(scenario_); }

  /// Executes `action` chosen with knowledge `world` (which maps object indices to scene
  /// objects by key). Moves get pose noise; declarations and removals are judged against the
  /// truth.
  ExecutionOutcome Execute(const HybridAction& action, const object_search::World& world, Rng& rng);
  /// Executes a move to `config` (pose noise added; collisions and joint limits are illegal).
  ExecutionOutcome ExecuteMove(const RobotConfig& config, const object_search::SearchParams& p,
                               Rng& rng);
  /// Executes a declare/remove on the scene object named `name` (or, for an id that perception
  /// made up, the one standing where the robot saw box `seen`): `offset` 0 declares it the
  /// target, 1 an obstacle, 2 removes it; `status` is what the robot has declared it so far.
  ExecutionOutcome ExecuteOnObject(int offset, const std::string& name, int8_t status,
                                   const object_search::SearchParams& p, const Box* seen = nullptr);
  /// The scene object named `key` or, failing that, the one not removed whose center is nearest
  /// to `seen`'s, within kSameObjectDistance; -1 when none.
  int FindObject(const std::string& key, const Box* seen = nullptr) const;
  /// How far a seen box's center may be from an object's for the two to be the same object (m).
  static constexpr double kSameObjectDistance = 0.12;

  /// The geometric observation from the robot's current configuration: every scene object whose
  /// center the camera sees unoccluded, with its estimated box and, for each of its 4 face grids
  /// nearest to the camera that are unoccluded, a noisy detection score (high for the target).
  object_search::RealObservation Observe(Rng& rng) const;

  /// What the camera at `config` sees of scene object i, without noise, by the rule Observe()
  /// applies: empty when the object is removed, its center is outside the frustum or occluded;
  /// else the corners (face grids, 0..7) among its 4 nearest to the camera whose points just
  /// inside the box are in the frustum and unoccluded, or {-1} when none is. Objects whose bit is
  /// set in `ignore` are treated as removed (what a view would show once they are gone).
  std::vector<int> VisibleCorners(int i, const RobotConfig& config, uint64_t ignore = 0) const;

  /// Renders what the head camera sees (default 640 x 480).
  Frame Render(int width = 640, int height = 480) const;

  /// The boxes that occlude the view: furniture and every object not removed.
  std::vector<Box> Occluders(int except = -1) const;

 private:
  Scenario scenario_;
  object_search::RobotDescription preset_;
  object_search::CameraModel camera_;
  object_search::OccupancyMap occupancy_;
  RobotConfig robot_;
  std::vector<SceneObject> objects_;
  std::vector<bool> removed_;
  int target_ = -1;
};

}  // namespace npfkct::sim
