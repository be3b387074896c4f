#include "npfkct/robot/urdf.h"

#include <console_bridge/console.h>
#include <urdf_parser/urdf_parser.h>

#include <algorithm>
#include <cmath>
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/frames.hpp>
#include <numbers>
#include <vector>

namespace npfkct::robot {
namespace {

using object_search::CameraJoint;
using object_search::RobotDescription;
using object_search::Vec3;

KDL::Frame FrameOf(const urdf::Pose& p) {
  return KDL::Frame(
      KDL::Rotation::Quaternion(p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w),
      KDL::Vector(p.position.x, p.position.y, p.position.z));
}

// The camera body's axes in the optical frame's coordinates (x = optical z, y = -optical x,
// z = -optical y), row by row.
const KDL::Rotation kOpticalToBody(0, -1, 0, 0, 0, -1, 1, 0, 0);

// Sets a joint's origin from a KDL frame (translation, roll-pitch-yaw about fixed axes: KDL's
// convention and the URDF's).
void SetOrigin(const KDL::Frame& f, CameraJoint* j) {
  j->xyz = Vec3(f.p.x(), f.p.y(), f.p.z());
  double roll, pitch, yaw;
  f.M.GetRPY(roll, pitch, yaw);
  j->rpy = Vec3(roll, pitch, yaw);
}

// Whether the camera pose of `robot` at the origin with the joints driven by `c` is KDL's pose
// of the same configuration along `chain`, whose moving joints are the description's, in order
// (each held where the description holds it when no action dimension drives it).
bool SameKinematics(const RobotDescription& robot, const KDL::Chain& chain,
                    const object_search::RobotConfig& c) {
  KDL::JntArray q(chain.getNrOfJoints());
  unsigned k = 0;
  for (const CameraJoint& j : robot.chain) {
    if (j.type == CameraJoint::Type::kFixed) continue;
    if (k >= q.rows()) return false;
    q(k++) = j.role == CameraJoint::Role::kLift   ? c.lift
             : j.role == CameraJoint::Role::kPan  ? c.pan
             : j.role == CameraJoint::Role::kTilt ? c.tilt
                                                  : std::clamp(0.0, j.lower, j.upper);
  }
  if (k != q.rows()) return false;
  KDL::ChainFkSolverPos_recursive fk(chain);
  KDL::Frame kdl;
  if (fk.JntToCart(q, kdl) < 0) return false;
  const object_search::CameraPose ours = object_search::CameraPoseFor(robot, c);
  const KDL::Vector x = kdl.M.UnitX(), y = kdl.M.UnitY(), p = kdl.p;
  auto near = [](const Vec3& a, const KDL::Vector& b) {
    return std::abs(a.x() - b.x()) + std::abs(a.y() - b.y()) + std::abs(a.z() - b.z()) < 1e-6;
  };
  return near(ours.position, p) && near(ours.forward, x) && near(ours.left, y);
}

// The deepest nesting of elements in `xml`, counted without parsing it (comments, CDATA,
// declarations and quoted attribute values skipped), stopping once past `limit`. liburdfdom
// parses with TinyXML, which recurses once per level: 50,000 nested elements overflow the stack.
int XmlDepth(std::string_view xml, int limit) {
  int depth = 0, deepest = 0;
  size_t i = 0;
  auto skip_past = [&](std::string_view end, size_t from) {
    const size_t at = xml.find(end, from);
    return at == std::string_view::npos ? xml.size() : at + end.size();
  };
  while ((i = xml.find('<', i)) != std::string_view::npos && deepest <= limit) {
    const std::string_view rest = xml.substr(i);
    if (rest.starts_with("<!--")) {
      i = skip_past("-->", i + 4);
    } else if (rest.starts_with("<![CDATA[")) {
      i = skip_past("]]>", i + 9);
    } else if (rest.starts_with("<?") || rest.starts_with("<!")) {
      i = skip_past(">", i + 2);
    } else if (rest.starts_with("</")) {
      --depth;
      i = skip_past(">", i + 2);
    } else {
      size_t j = i + 1;
      for (char quote = 0; j < xml.size(); ++j) {
        const char c = xml[j];
        if (quote != 0) {
          if (c == quote) quote = 0;
        } else if (c == '"' || c == '\'') {
          quote = c;
        } else if (c == '>') {
          break;
        }
      }
      if (j >= xml.size()) break;
      if (xml[j - 1] != '/') deepest = std::max(deepest, ++depth);
      i = j + 1;
    }
  }
  return deepest;
}

}  // namespace

StatusOr<RobotDescription> DescriptionFromUrdf(std::string_view xml,
                                               const UrdfSelection& selection) {
  if (xml.size() > kMaxUrdfBytes) {
    return InvalidFieldError("urdf", "at most " + std::to_string(kMaxUrdfBytes) + " bytes");
  }
  if (XmlDepth(xml, kMaxUrdfDepth) > kMaxUrdfDepth) {
    return InvalidFieldError("urdf",
                             "elements nested deeper than " + std::to_string(kMaxUrdfDepth));
  }
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  urdf::ModelInterfaceSharedPtr model;
  try {
    model = urdf::parseURDF(std::string(xml));
  } catch (const std::exception&) {
    model = nullptr;
  }
  if (!model) return InvalidFieldError("urdf", "not a URDF robot its parser accepts");
  urdf::LinkConstSharedPtr base = model->getLink(selection.base_link);
  if (!base) return InvalidFieldError("baseLink", "no link '" + selection.base_link + "'");
  urdf::LinkConstSharedPtr camera = model->getLink(selection.camera_link);
  if (!camera) return InvalidFieldError("cameraLink", "no link '" + selection.camera_link + "'");
  // The joints from the camera link up to the base link, then in order from the base.
  std::vector<const urdf::Joint*> path;
  for (urdf::LinkConstSharedPtr link = camera; link != base;) {
    if (!link->parent_joint || path.size() > model->joints_.size()) {
      return InvalidFieldError("cameraLink", "'" + selection.camera_link +
                                                 "' is not below the base link '" +
                                                 selection.base_link + "'");
    }
    path.push_back(link->parent_joint.get());
    link = model->getLink(link->parent_joint->parent_link_name);
    if (!link) return InvalidFieldError("urdf", "a joint's parent link is missing");
  }
  std::reverse(path.begin(), path.end());

  RobotDescription robot;
  robot.name = selection.name;
  robot.footprint_radius = selection.footprint_radius;
  robot.reach = selection.reach;
  const std::pair<const std::string*, CameraJoint::Role> selected[] = {
      {&selection.lift_joint, CameraJoint::Role::kLift},
      {&selection.pan_joint, CameraJoint::Role::kPan},
      {&selection.tilt_joint, CameraJoint::Role::kTilt}};
  const char* fields[] = {"liftJoint", "panJoint", "tiltJoint"};
  for (int k = 0; k < 3; ++k) {
    const std::string& name = *selected[k].first;
    if (name.empty()) continue;
    if (std::none_of(path.begin(), path.end(),
                     [&](const urdf::Joint* j) { return j->name == name; })) {
      return InvalidFieldError(fields[k], "no joint '" + name +
                                              "' between the base link and the "
                                              "camera link");
    }
  }
  // Consecutive fixed joints are composed into the next joint's origin (or a last fixed one).
  KDL::Chain chain;
  KDL::Frame pending = KDL::Frame::Identity();
  for (const urdf::Joint* j : path) {
    const KDL::Frame origin = FrameOf(j->parent_to_joint_origin_transform);
    if (j->type == urdf::Joint::FIXED) {
      pending = pending * origin;
      chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::None), origin));
      continue;
    }
    if (j->type != urdf::Joint::REVOLUTE && j->type != urdf::Joint::CONTINUOUS &&
        j->type != urdf::Joint::PRISMATIC) {
      return InvalidFieldError("urdf", "joint '" + j->name +
                                           "' between the base and the camera is neither fixed, "
                                           "revolute, continuous nor prismatic");
    }
    CameraJoint c;
    c.name = j->name.substr(0, 64);
    c.type = j->type == urdf::Joint::PRISMATIC ? CameraJoint::Type::kPrismatic
                                               : CameraJoint::Type::kRevolute;
    SetOrigin(pending * origin, &c);
    pending = KDL::Frame::Identity();
    c.axis = Vec3(j->axis.x, j->axis.y, j->axis.z);
    if (j->type == urdf::Joint::CONTINUOUS) {
      c.lower = -std::numbers::pi;
      c.upper = std::numbers::pi;
    } else if (j->limits) {
      c.lower = j->limits->lower;
      c.upper = j->limits->upper;
    }
    for (int k = 0; k < 3; ++k) {
      if (*selected[k].first == j->name) {
        c.role = selected[k].second;
        const bool prismatic = c.type == CameraJoint::Type::kPrismatic;
        if (prismatic != (c.role == CameraJoint::Role::kLift)) {
          return InvalidFieldError(
              fields[k], "'" + j->name + "' is " + (prismatic ? "prismatic" : "revolute") +
                             (prismatic ? "; a pan or tilt turns" : "; a lift slides"));
        }
      }
    }
    robot.chain.push_back(c);
    const KDL::Vector axis(c.axis.x(), c.axis.y(), c.axis.z());
    chain.addSegment(
        KDL::Segment(KDL::Joint(j->name, origin.p, origin.M * axis,
                                c.type == CameraJoint::Type::kPrismatic ? KDL::Joint::TransAxis
                                                                        : KDL::Joint::RotAxis),
                     origin));
    if (robot.chain.size() > static_cast<size_t>(RobotDescription::kMaxJoints)) break;
  }
  if (selection.optical_frame) {
    pending = pending * KDL::Frame(kOpticalToBody);
    chain.addSegment(KDL::Segment(KDL::Joint(KDL::Joint::None), KDL::Frame(kOpticalToBody)));
  }
  if (!(pending == KDL::Frame::Identity())) {
    CameraJoint tail;
    tail.name = "camera";
    SetOrigin(pending, &tail);
    robot.chain.push_back(tail);
  }
  if (robot.chain.size() > static_cast<size_t>(RobotDescription::kMaxJoints)) {
    return InvalidFieldError("urdf", "more than " + std::to_string(RobotDescription::kMaxJoints) +
                                         " joints between the base and the camera (fixed ones "
                                         "next to each other count as one)");
  }
  if (Status s = robot.Validate(); !s.ok()) return InvalidFieldError("urdf", s.message());
  // The description's kinematics against KDL's along the URDF's own joints, at the lower and
  // upper limits and the middle of each action dimension.
  for (double t : {0.0, 0.5, 1.0}) {
    object_search::RobotConfig c;
    c.lift = robot.lift_min + t * (robot.lift_max - robot.lift_min);
    c.pan = robot.pan_min + t * (robot.pan_max - robot.pan_min);
    c.tilt = robot.tilt_min + (1.0 - t) * (robot.tilt_max - robot.tilt_min);
    if (!SameKinematics(robot, chain, c)) {
      return InvalidFieldError("urdf", "the chain's kinematics could not be reproduced");
    }
  }
  return robot;
}

}  // namespace npfkct::robot
