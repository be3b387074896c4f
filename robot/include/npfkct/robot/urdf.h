// A robot description (object_search::RobotDescription) from the robot's URDF: the joints from
// its base link to its camera link, the ones the planner drives named by the caller.
//
//   UrdfSelection s;
//   s.base_link = "base_link";
//   s.camera_link = "head_camera_rgb_optical_frame";
//   s.optical_frame = true;
//   s.lift_joint = "torso_lift_joint";
//   s.pan_joint = "head_pan_joint";
//   s.tilt_joint = "head_tilt_joint";
//   StatusOr<RobotDescription> fetch = DescriptionFromUrdf(xml, s);
#pragma once

#include <string>
#include <string_view>

#include "npfkct/common/status.h"
#include "npfkct/object_search/geometry.h"

namespace npfkct::robot {

/// What of a URDF the planner uses.
struct UrdfSelection {
  /// The mobile base's link, whose frame stands on the floor at the robot's centre (x forward,
  /// z up): the configuration's x, y and yaw place it.
  std::string base_link;
  /// The camera's link. Its frame is the camera's body (x along the optical axis, y left, z up),
  /// or, with optical_frame, its optical frame (z along the axis, x right, y down; REP 103).
  std::string camera_link;
  bool optical_frame = false;
  /// The joints the planner's lift, pan and tilt drive (empty: the robot has none, and plans in
  /// one dimension fewer). Every other moving joint between the two links is held at the value
  /// in its limits nearest 0.
  std::string lift_joint, pan_joint, tilt_joint;
  /// The description's name, footprint and reach (the URDF does not say them).
  std::string name = "urdf";
  double footprint_radius = 0.3;
  double reach = 1.0;
};

/// Bytes of a URDF accepted (its XML is parsed whole), and how deep its elements may nest (a
/// URDF nests about six deep; the parser recurses once per level).
inline constexpr size_t kMaxUrdfBytes = 1 << 20;
inline constexpr int kMaxUrdfDepth = 64;

/// The description of the URDF `xml`: the joints on the path from selection.base_link down to
/// selection.camera_link (consecutive fixed joints composed into one), the selected joints given
/// their roles and their URDF limits (a continuous joint: +-pi). Errors are INVALID_ARGUMENT
/// naming the field ("urdf", "baseLink", "cameraLink", "liftJoint", ...): XML that is not a URDF,
/// a link or joint it lacks, a camera link not below the base link, a selected joint off that path
/// or of the wrong type (the lift prismatic, the pan and tilt revolute or continuous), a floating
/// or planar joint on the path, more than RobotDescription::kMaxJoints joints.
StatusOr<object_search::RobotDescription> DescriptionFromUrdf(std::string_view xml,
                                                              const UrdfSelection& selection);

}  // namespace npfkct::robot
