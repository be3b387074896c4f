// Geometry of the object-search problem: oriented boxes, rays, robot kinematics and the camera
// frustum (paper section 3 and appendix J).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

#include "npfkct/common/status.h"

namespace npfkct::object_search {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

/// A box standing upright: center, yaw about the vertical axis, and full extents (x, y, z).
struct Box {
  Vec3 center = Vec3::Zero();
  double yaw = 0.0;
  Vec3 size = Vec3::Ones();

  /// The 8 corners: index bit 0 selects +x/-x, bit 1 +y/-y, bit 2 +z/-z (box frame).
  std::array<Vec3, 8> Corners() const;
  /// A point of the world in the box frame.
  Vec3 ToLocal(const Vec3& p) const;
  /// Whether a world point lies inside the box (with `margin` added to every half extent).
  bool Contains(const Vec3& p, double margin = 0.0) const;
  /// Entry parameter t in [t_min, t_max] of the ray origin + t * dir into the box, or -1.
  double Intersect(const Vec3& origin, const Vec3& dir, double t_min, double t_max) const;
  /// Whether the open segment (a, b) crosses the box, ignoring `clearance` at both ends.
  bool BlocksSegment(const Vec3& a, const Vec3& b, double clearance = 1e-6) const;
};

/// The indices of the four of a box's `corners` (Box::Corners' order) nearest to `from`, the
/// nearest first: the face grids a camera at `from` could see.
std::array<int, 4> NearestCorners(const std::array<Vec3, 8>& corners, const Vec3& from);

/// The upright box standing on the floor (bottom at z = 0, top at `height`) whose footprint is
/// the smallest-area rectangle holding the polygon's points (a table top traced in a map): the
/// rectangle along one edge of their convex hull. INVALID_ARGUMENT when the points span no area.
StatusOr<Box> BoxAroundPolygon(const std::vector<Vec2>& polygon, double height);

/// A Box with its yaw's cosine and sine computed once, for tests against many points and rays
/// (the camera's occlusion checks); the same results as the Box methods of the same names.
struct BoxFrame {
  BoxFrame() = default;
  explicit BoxFrame(const Box& box);

  Vec3 center = Vec3::Zero();
  double cos_yaw = 1.0, sin_yaw = 0.0;
  Vec3 half = Vec3::Constant(0.5);     ///< Half extents.
  double radius = 0.8660254037844386;  ///< Of the sphere around the center holding the box.

  /// See Box::Corners.
  std::array<Vec3, 8> Corners() const;
  /// See Box::ToLocal.
  Vec3 ToLocal(const Vec3& p) const;
  /// See Box::Contains.
  bool Contains(const Vec3& p, double margin = 0.0) const;
  /// See Box::Intersect.
  double Intersect(const Vec3& origin, const Vec3& dir, double t_min, double t_max) const;
  /// See Box::BlocksSegment.
  bool BlocksSegment(const Vec3& a, const Vec3& b, double clearance = 1e-6) const;
  /// BlocksSegment for the segment from `a` along the unit vector `unit` for `length` (> 2
  /// clearance), for one segment tested against many boxes.
  bool BlocksUnitSegment(const Vec3& a, const Vec3& unit, double length, double clearance) const;
};

/// A robot configuration: the continuous action space of the paper (base x, y, yaw; lift; head
/// pan and tilt). Positive tilt looks down.
struct RobotConfig {
  double x = 0.0, y = 0.0, yaw = 0.0;
  double lift = 0.0, pan = 0.0, tilt = 0.0;

  friend bool operator==(const RobotConfig&, const RobotConfig&) = default;
};

/// One joint of the chain from a robot's base to its camera, as a URDF joint: the origin of its
/// frame in the parent's (translation, then roll-pitch-yaw, fixed axes), and for a moving joint
/// its axis in its own frame. A moving joint is driven by one of the planner's action dimensions
/// (its role), or held at 0.
struct CameraJoint {
  enum class Type { kFixed, kPrismatic, kRevolute };
  /// The action dimension that drives the joint (RobotConfig's lift, pan or tilt).
  enum class Role { kNone, kLift, kPan, kTilt };
  std::string name;
  Type type = Type::kFixed;
  Role role = Role::kNone;
  Vec3 xyz = Vec3::Zero();
  Vec3 rpy = Vec3::Zero();
  Vec3 axis = Vec3::UnitZ();        ///< Unit length; moving joints only.
  double lower = 0.0, upper = 0.0;  ///< Limits of a moving joint (m or rad).

  friend bool operator==(const CameraJoint&, const CameraJoint&) = default;
};

/// The camera's field of view (paper appendix J: 60 degrees horizontal, aspect 480/600, near
/// 0.5 m, far 1.7 m).
struct CameraModel {
  double horizontal_fov = 1.0471975511965976;  // 60 degrees
  double aspect = 480.0 / 600.0;               // height / width
  double near = 0.5;
  double far = 1.7;

  double TanHalfHorizontal() const;
  double TanHalfVertical() const;

  friend bool operator==(const CameraModel&, const CameraModel&) = default;
};

/// A mobile robot as the planner sees it: a round base on the floor (x forward, z up, at the
/// configuration's x, y, yaw), the chain of joints from it to the camera (whose last frame is the
/// camera's body: x along the optical axis, y left, z up), the limits of the lift, pan and tilt
/// that drive the chain, and the manipulator's reach. A robot without a lift (or pan, tilt) has
/// that action dimension fixed at 0: it plans in one dimension fewer.
struct RobotDescription {
  static constexpr int kMaxJoints = 16;

  std::string name;
  std::vector<CameraJoint> chain;
  /// Limits of the action dimensions, those of the joints that play each role (0 and 0 when no
  /// joint does); set by the chain's joints in Validate(), which a caller must run.
  double lift_min = 0.0, lift_max = 0.0;
  double pan_min = 0.0, pan_max = 0.0;
  double tilt_min = 0.0, tilt_max = 0.0;
  static constexpr int kMaxFootprintVertices = 32;
  /// Footprint radius used for collision checks against the occupancy map; with a polygon
  /// footprint, the radius of the circle around it (set by Validate()).
  double footprint_radius = 0.3;
  /// The base's outline in its own frame (x forward, y left; m), a simple polygon of 3 to
  /// kMaxFootprintVertices vertices; empty: the disc of footprint_radius.
  std::vector<Eigen::Vector2d> footprint;
  /// Reach of the manipulator from the base center (moveability).
  double reach = 1.0;
  /// Its camera's field of view and depth range (what it sees from a configuration).
  CameraModel camera;

  /// The Fetch robot: torso lift 0..0.4 m raising a pan-tilt head.
  static RobotDescription Fetch();
  /// The Stretch robot: a pan-tilt camera on a fixed mast (its lift moves the arm, not the
  /// camera, so it plans without a lift dimension).
  static RobotDescription Stretch();
  /// A shipped description by name: "fetch" or "stretch".
  static StatusOr<RobotDescription> ByName(const std::string& name);
  /// Checks every field (the message names the offending one: "joints[2].axis", ...): a
  /// footprint polygon that is simple, of positive area and within 5 m of the base (its radius
  /// then set from it), at most kMaxJoints joints, finite values, unit-or-nonzero axes
  /// (normalised), lower <= upper, at most one joint per role and roles only on moving joints, a
  /// positive footprint and reach, a camera with a field of view in (0.01, 3] rad, aspect in [0.05,
  /// 20] and 0 < near < far <= 50 m; then sets the action limits from the role joints.
  Status Validate();
  bool has_lift() const { return lift_max > lift_min; }

  friend bool operator==(const RobotDescription&, const RobotDescription&) = default;
};

/// A camera pose: optical center and orthonormal axes (forward, left, up) in the world.
struct CameraPose {
  Vec3 position = Vec3::Zero();
  Vec3 forward = Vec3::UnitX();
  Vec3 left = Vec3::UnitY();
  Vec3 up = Vec3::UnitZ();

  /// A world point in camera coordinates (forward, left, up).
  Vec3 ToCamera(const Vec3& p) const;
};

/// The camera's pose for configuration `config` (its base, and its lift, pan and tilt driving
/// the chain's joints), by the chain's forward kinematics.
CameraPose CameraPoseFor(const RobotDescription& robot, const RobotConfig& config);

/// Whether a world point lies inside the camera frustum.
bool InFrustum(const CameraModel& camera, const CameraPose& pose, const Vec3& p);
/// InFrustum with camera.TanHalfHorizontal() given, for many points seen by one camera.
bool InFrustum(const CameraModel& camera, const CameraPose& pose, const Vec3& p,
               double tan_half_horizontal);

/// Wraps an angle into [-pi, pi).
double WrapAngle(double a);

/// The distance between segments ab and cd (0 when they touch or cross).
double SegmentDistance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                       const Eigen::Vector2d& d);
/// Whether p lies inside the polygon (even-odd rule; a point on an edge may go either way).
bool InsidePolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p);
/// The distance between two polygons (0 when they overlap or one holds the other).
double PolygonDistance(const std::vector<Eigen::Vector2d>& p,
                       const std::vector<Eigen::Vector2d>& q);

}  // namespace npfkct::object_search
