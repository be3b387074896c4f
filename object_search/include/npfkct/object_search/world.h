// What the robot knows between real steps (the problem configuration alpha(P) and the belief
// summary the planner samples from): map, workspaces, grid world, detected objects and their face
// odds; and the real-step update of that knowledge (paper appendix A and B).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/object_search/geometry.h"
#include "npfkct/object_search/grid_world.h"

namespace npfkct::object_search {

/// Objects a world holds at most, the guessed target (object 0) included: the model's
/// observations are 64-bit masks over them.
inline constexpr int kMaxObjects = 64;
/// Real objects a world can know: kMaxObjects less the guessed target.
inline constexpr int kMaxKnownObjects = kMaxObjects - 1;

/// Object status (paper footnote 2).
enum ObjectStatus : int8_t {
  kRemoved = -2,
  kUpdating = -1,
  kDeclaredObstacle = 0,
  kDeclaredTarget = 1,
};

/// The offsets of the discrete action kinds of object i: kind 1 + 3i + offset (model.h).
inline constexpr int kDeclareTargetOffset = 0;
inline constexpr int kDeclareObstacleOffset = 1;
inline constexpr int kRemoveOffset = 2;

/// Parameters of the object-search POMDP (paper section 3 and appendix J).
struct SearchParams {
  double r_max = 1e5;   ///< Removing the declared target (terminal).
  double r_ct = 5e4;    ///< Correctly declaring the target.
  double r_co = 1e4;    ///< Correctly declaring an obstacle.
  double r_min = -1.0;  ///< Every action (a removal costs 2 r_min).
  double r_ill = -1e3;  ///< Illegal actions.
  double discount = 0.9;
  /// Face-grid update in the belief tree: +-c_o + eta, eta ~ N(0, eta_std^2).
  double c_o = 0.8;
  double eta_std = 0.1;
  /// Mean log-odds thresholds deciding the direction of simulated updates.
  double nu_p = 0.1;
  double nu_n = -0.1;
  /// Declaring needs n_odds face grids past +-declare_threshold.
  int n_odds = 6;
  double declare_threshold = 0.6;
  /// Face odds of the guessed target, re-initialised after every real step.
  double guess_odds = 0.2;
  /// Size of the guessed target cube (m).
  double guess_size = 0.1;
  /// Moveability of the guessed target.
  double guess_moveability = 1.0;
  /// Real-step grid-world update for free (seen, empty) cells, and the clamp.
  double grid_free_delta = -1.0;
  double grid_min = -6.0;
  double grid_max = 6.0;
  /// Real-step face-odds update from a detection score p: log(p / (1 - p)), clamped to this.
  double detection_max_step = 2.0;
  /// Face odds are clamped to +-face_odds_limit.
  double face_odds_limit = 8.0;
  /// Episode length limit (success within this many steps).
  int max_steps = 50;
  /// Clearance (m) the reasonability check keeps between the base's footprint and the map, so
  /// that the pose noise of a move cannot push the robot into furniture (a navigation stack's
  /// inflation radius).
  double base_clearance = 0.05;

  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// What one executed action did; the reward table maps it to a reward.
enum class ActionOutcome {
  kMoved,             ///< A legal move.
  kIllegal,           ///< Any illegal action (collision, wrong declaration, re-removal, ...).
  kDeclaredTarget,    ///< The target correctly declared.
  kDeclaredObstacle,  ///< An obstacle correctly declared.
  kRemovedTarget,     ///< The declared target removed (terminal).
  kRemovedObstacle,   ///< A declared obstacle removed.
};

/// The paper's reward table (section 3): R_min per move, R_ill for illegal actions, R_ct and R_co
/// for correct declarations, R_max for removing the target, 2 R_min for removing an obstacle. The
/// model, the simulator and the server all take rewards from here.
double RewardOf(const SearchParams& p, ActionOutcome outcome);

/// The outcome of a declare/remove (kind offset: 0 declare target, 1 declare obstacle, 2 remove)
/// that succeeded on an object whose status was `status`.
ActionOutcome SuccessfulOutcome(int kind_offset, int8_t status);

/// The status an object takes when a declare/remove of `kind_offset` (0..2) on it succeeds:
/// declared target, declared obstacle, removed.
int8_t StatusAfter(int kind_offset);

/// A 2-D occupancy map of the floor; the base may not stand where its footprint touches an
/// occupied cell.
class OccupancyMap {
 public:
  OccupancyMap() = default;
  /// A free map of [min, max] with square cells of `resolution`.
  OccupancyMap(Vec2 min, Vec2 max, double resolution);
  /// Marks the footprint of an upright box (inflated by `margin`) occupied.
  void AddBox(const Box& box, double margin = 0.0);
  /// Whether a disc of `radius` at (x, y) is free and inside the map.
  bool DiscFree(double x, double y, double radius) const;
  /// Whether the robot's footprint, widened by `clearance`, is free and inside the map with
  /// its base at (x, y) heading `yaw` (DiscFree of footprint_radius + clearance for a robot
  /// without a footprint polygon, whatever the heading).
  bool FootprintFree(const RobotDescription& robot, double x, double y, double yaw,
                     double clearance) const;
  bool Occupied(int ix, int iy) const { return occupied_[iy * nx_ + ix] != 0; }
  int nx() const { return nx_; }
  int ny() const { return ny_; }
  const Vec2& min() const { return min_; }
  const Vec2& max() const { return max_; }
  double resolution() const { return resolution_; }
  const std::vector<uint8_t>& cells() const { return occupied_; }
  /// Replaces the cells (sizes must match).
  Status SetCells(const std::vector<uint8_t>& cells);

 private:
  // Whether no occupied cell within `reach` of (x, y) (the square of cells around that disc)
  // `hits`, (x, y) at least `reach` inside the map; a map without cells is free everywhere.
  template <typename CellHits>
  bool NoCellHits(double x, double y, double reach, CellHits hits) const;

  Vec2 min_ = Vec2::Zero(), max_ = Vec2::Zero();
  double resolution_ = 0.05;
  int nx_ = 0, ny_ = 0;
  std::vector<uint8_t> occupied_;
};

/// A rectangle of the floor where the base may be placed.
struct BaseRegion {
  Vec2 min = Vec2::Zero();
  Vec2 max = Vec2::Zero();
  bool Contains(double x, double y) const {
    return x >= min.x() && x <= max.x() && y >= min.y() && y <= max.y();
  }
};

/// What is known of one object (object 0 is the guessed target and has no fixed box).
struct ObjectKnowledge {
  std::string key;              ///< Caller's identifier (perception cluster id, simulator name).
  Box box;                      ///< Estimated oriented bounding box.
  double moveability = 1.0;     ///< Probability that the robot can remove it.
  std::array<float, 8> odds{};  ///< Face-grid log-odds (the box's 8 corners).
  int8_t status = kUpdating;
  /// The robot reported a removal of it that failed: its moveability stays 0 whatever later
  /// detections estimate.
  bool removal_failed = false;
};

/// One face-grid detection of a real observation: corner index 0..7 and the probability that
/// the object is the target as seen on that part.
struct FaceDetection {
  int corner = 0;
  double score = 0.5;
};

/// One object seen in a real step.
struct ObjectDetection {
  std::string key;  ///< Stable identifier across steps (association done by the caller).
  Box box;
  double moveability = 1.0;
  std::vector<FaceDetection> faces;
  /// A score for the object as a whole (a 3D box detector's probability that it is the target),
  /// in place of `faces`: the face grids the camera sees from the achieved configuration get it
  /// (of the box's corners, the four nearest the camera that lie in its frustum and that no
  /// furniture or other detected box hides). NaN: only `faces`.
  double score = std::numeric_limits<double>::quiet_NaN();
};

/// The face grids (box corners 0-7) of `box` that the camera at `pose` sees: of its corners, the
/// four nearest the camera, each taken 5% of the way to the centre, that lie in the frustum and
/// that no box of `occluders` hides.
std::vector<int> SeenCorners(const Box& box, const CameraModel& camera, const CameraPose& pose,
                             const std::vector<Box>& occluders);

/// What the robot learnt in one real step.
struct RealObservation {
  RobotConfig achieved;  ///< The configuration the robot actually reached.
  std::vector<ObjectDetection> objects;
};

/// The robot's knowledge: everything the planner's model samples from.
struct World {
  RobotDescription robot = RobotDescription::Fetch();
  CameraModel camera;
  SearchParams params;
  std::vector<Box> furniture;            ///< Static occluders of the prior map.
  OccupancyMap occupancy;                ///< Where the base may not stand.
  std::vector<BaseRegion> base_regions;  ///< Candidate base rectangles (A_c's base part).
  /// Manually chosen base poses (x, y, yaw) of the discrete baselines (POMCP, GPOMCP).
  std::vector<RobotConfig> discrete_poses;
  GridWorld grid;                        ///< Odds of the target's position.
  std::vector<ObjectKnowledge> objects;  ///< objects[0] is the guessed target.
  RobotConfig robot_config;              ///< The robot's current configuration.
  int steps = 0;                         ///< Real steps taken.

  /// A world with the given map parts, object 0 (the guessed target) only, and the robot at
  /// `start`. The grid world's sampler is built.
  static World Make(RobotDescription robot, SearchParams params, std::vector<Box> furniture,
                    OccupancyMap occupancy, std::vector<BaseRegion> base_regions, GridWorld grid,
                    RobotConfig start);

  /// Checks the parts; the message names the offending one.
  Status Validate() const;
  /// Occluding boxes: furniture and every object not removed (object 0 excluded).
  std::vector<Box> Occluders() const;
  /// Whether the base may stand at (x, y) heading `yaw`: inside a base region, and its
  /// footprint plus params.base_clearance free in the occupancy map.
  bool BaseFeasible(double x, double y, double yaw) const;
  /// Whether it may stand at (x, y) with some heading (of 16 for a footprint polygon; any for
  /// a disc).
  bool BaseFeasible(double x, double y) const;
  /// The base position that three numbers in [0, 1) pick: `pick` a base region by area, `u` and
  /// `v` the point inside it (uniform draws give a point uniform over the regions). False when
  /// the regions have no area.
  bool BasePointAt(double pick, double u, double v, double* x, double* y) const;
  /// Index of the object with this key, or -1.
  int FindObject(const std::string& key) const;
  /// The manual base poses (x, y, yaw) of the discrete baselines: discrete_poses, or each base
  /// region's center facing the nearest workspace.
  std::vector<RobotConfig> ManualPoses() const;
  /// The manual lift heights: lowest, middle, highest (one when the robot has no lift).
  std::vector<double> ManualLifts() const;
  /// The manual head orientations (pan, tilt): 3 pans (both limits and the middle) x 3 tilts
  /// (level, half-way down, lowest), each without repeats (a robot without a pan has one).
  std::vector<std::pair<double, double>> ManualHeads() const;
  /// Every manual pose x lift x head orientation (4 x 3 x 9 = 108 with four poses).
  std::vector<RobotConfig> ManualConfigurations() const;
};

/// The resolution of the workspaces' grid world (paper: 2 cm).
inline constexpr double kGridResolution = 0.02;

/// What the robot knows of a room before it looks: the prior map of a scenario file or of a
/// session's creation request.
struct PriorMap {
  /// A piece of furniture; its top is a workspace (a grid-world surface) when `workspace`.
  struct Furniture {
    std::string name;
    Box box;  ///< Stands on the floor: center.z = size.z / 2.
    bool workspace = false;
  };
  RobotDescription robot = RobotDescription::Fetch();
  Vec2 room_min = Vec2(-3, -3);
  Vec2 room_max = Vec2(3, 3);
  double map_resolution = 0.05;
  std::vector<Furniture> furniture;
  /// Where the base may stand; empty: around each workspace (BaseRegionsAround).
  std::vector<BaseRegion> base_regions;
  std::vector<RobotConfig> discrete_poses;
  RobotConfig start;
  SearchParams params;
  /// The cells of a SLAM occupancy grid the base may not stand on (occupied or unknown: 1),
  /// row by row from room_min at map_resolution, covering the room; empty: the room is free
  /// but for the furniture.
  std::vector<uint8_t> occupied;

  /// The furniture tops that are workspaces, as grid-world surfaces.
  std::vector<Workspace> Workspaces() const;
};

/// Base regions around the workspaces of `prior`, for a map that gives none: four strips along
/// the sides of each workspace's footprint (its axis-aligned bounds), from the robot's footprint
/// radius plus the base clearance out to its reach (at least 0.3 m wide), as the paper's scenes
/// place them.
std::vector<BaseRegion> BaseRegionsAround(const PriorMap& prior);

/// The robot's initial knowledge of a prior map: the occupancy map of the room with the furniture,
/// the base regions, the grid world over the workspaces (kGridResolution), no object but the
/// guessed target, the robot at the start. Errors are INVALID_ARGUMENT; those about one part carry
/// it as a field violation ("start", "robot"). Each base region is cut to the room; a region with
/// no part in it ("baseRegions[i]") or regions with no point free for the robot's footprint
/// ("baseRegions") are refused.
/// The caller bounds the sizes (cells, pieces) before calling: this allocates what they ask for.
StatusOr<World> BuildWorld(const PriorMap& prior);

/// Applies the outcome of a declare/remove action executed for real (`success` says whether the
/// robot managed it). Status changes follow the paper: declared target 1, obstacle 0, removed -2.
/// A removal that failed marks the object unremovable (moveability 0 from then on): the model's
/// removal of a moveable object never fails, so the planner would otherwise try it again.
Status ApplyDiscreteOutcome(World* world, int object, int kind_offset, bool success);

/// The real-step update (paper appendix A): the robot's configuration, detected objects (new ones
/// appended), face odds from detection scores, and the grid world from the camera's view.
Status ApplyRealObservation(World* world, const RealObservation& observation);

}  // namespace npfkct::object_search
