// Geometry of the object-search problem: oriented boxes, rays, robot kinematics and the camera
// frustum (paper section 3 and appendix J).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>

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

/// Kinematic preset of a mobile manipulator's head camera and joint limits.
struct RobotPreset {
  std::string name;
  /// Camera optical center in the base frame at lift 0, pan 0, tilt 0 (x forward, z up).
  Vec3 camera_offset = Vec3(0.1, 0.0, 1.1);
  /// Whether the lift raises the camera (Fetch's torso does; Stretch's lift moves only the arm).
  bool lift_moves_camera = true;
  double lift_min = 0.0, lift_max = 0.4;
  double pan_min = -0.2618, pan_max = 0.2618;  // +-pi/12
  double tilt_min = -0.5, tilt_max = 0.5;
  /// Footprint radius used for collision checks against the occupancy map.
  double footprint_radius = 0.3;
  /// Reach of the manipulator from the base center (moveability).
  double reach = 1.0;

  /// The Fetch robot (torso lift 0..0.4 m raises the head camera).
  static RobotPreset Fetch();
  /// The Stretch robot (camera on a fixed mast; the lift moves only the arm).
  static RobotPreset Stretch();
  /// "fetch" or "stretch".
  static StatusOr<RobotPreset> ByName(const std::string& name);
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

/// The head camera's pose for a robot configuration.
CameraPose CameraPoseFor(const RobotPreset& robot, const RobotConfig& config);

/// Whether a world point lies inside the camera frustum.
bool InFrustum(const CameraModel& camera, const CameraPose& pose, const Vec3& p);
/// InFrustum with camera.TanHalfHorizontal() given, for many points seen by one camera.
bool InFrustum(const CameraModel& camera, const CameraPose& pose, const Vec3& p,
               double tan_half_horizontal);

/// Wraps an angle into [-pi, pi).
double WrapAngle(double a);

}  // namespace npfkct::object_search
