#include "npfkct/object_search/geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace npfkct::object_search {

std::array<Vec3, 8> Box::Corners() const { return BoxFrame(*this).Corners(); }

Vec3 Box::ToLocal(const Vec3& p) const { return BoxFrame(*this).ToLocal(p); }

bool Box::Contains(const Vec3& p, double margin) const {
  return BoxFrame(*this).Contains(p, margin);
}

double Box::Intersect(const Vec3& origin, const Vec3& dir, double t_min, double t_max) const {
  return BoxFrame(*this).Intersect(origin, dir, t_min, t_max);
}

bool Box::BlocksSegment(const Vec3& a, const Vec3& b, double clearance) const {
  return BoxFrame(*this).BlocksSegment(a, b, clearance);
}

BoxFrame::BoxFrame(const Box& box)
    : center(box.center),
      cos_yaw(std::cos(box.yaw)),
      sin_yaw(std::sin(box.yaw)),
      half(0.5 * box.size.x(), 0.5 * box.size.y(), 0.5 * box.size.z()),
      radius(half.norm()) {}

std::array<Vec3, 8> BoxFrame::Corners() const {
  std::array<Vec3, 8> corners;
  const double c = cos_yaw, s = sin_yaw;
  for (int i = 0; i < 8; ++i) {
    const double lx = (i & 1) ? half.x() : -half.x();
    const double ly = (i & 2) ? half.y() : -half.y();
    const double lz = (i & 4) ? half.z() : -half.z();
    corners[i] = center + Vec3(c * lx - s * ly, s * lx + c * ly, lz);
  }
  return corners;
}

Vec3 BoxFrame::ToLocal(const Vec3& p) const {
  const Vec3 d = p - center;
  const double c = cos_yaw, s = sin_yaw;
  return Vec3(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
}

bool BoxFrame::Contains(const Vec3& p, double margin) const {
  const Vec3 l = ToLocal(p);
  return std::abs(l.x()) <= half.x() + margin && std::abs(l.y()) <= half.y() + margin &&
         std::abs(l.z()) <= half.z() + margin;
}

double BoxFrame::Intersect(const Vec3& origin, const Vec3& dir, double t_min, double t_max) const {
  const double c = cos_yaw, s = sin_yaw;
  const Vec3 d = origin - center;
  const Vec3 o(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  const Vec3 v(c * dir.x() + s * dir.y(), -s * dir.x() + c * dir.y(), dir.z());
  double lo = t_min, hi = t_max;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(v[i]) < 1e-15) {
      if (std::abs(o[i]) > half[i]) return -1.0;
      continue;
    }
    double t0 = (-half[i] - o[i]) / v[i];
    double t1 = (half[i] - o[i]) / v[i];
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0);
    hi = std::min(hi, t1);
    if (lo > hi) return -1.0;
  }
  return lo;
}

bool BoxFrame::BlocksSegment(const Vec3& a, const Vec3& b, double clearance) const {
  const Vec3 dir = b - a;
  const double length = dir.norm();
  if (length <= 2 * clearance) return false;
  return BlocksUnitSegment(a, dir / length, length, clearance);
}

bool BoxFrame::BlocksUnitSegment(const Vec3& a, const Vec3& unit, double length,
                                 double clearance) const {
  // A segment passing farther from the center than the bounding sphere (with 1 um to spare for
  // rounding) misses the box: the exact test below would say so, at several divisions' cost.
  const Vec3 to_center = center - a;
  const double along = std::clamp(to_center.dot(unit), 0.0, length);
  if ((to_center - along * unit).squaredNorm() > (radius + 1e-6) * (radius + 1e-6)) return false;
  return Intersect(a, unit, clearance, length - clearance) >= 0.0;
}

RobotPreset RobotPreset::Fetch() {
  RobotPreset r;
  r.name = "fetch";
  r.camera_offset = Vec3(0.15, 0.0, 1.08);
  r.lift_moves_camera = true;
  r.lift_min = 0.0;
  r.lift_max = 0.4;
  r.footprint_radius = 0.3;
  r.reach = 1.0;
  return r;
}

RobotPreset RobotPreset::Stretch() {
  RobotPreset r;
  r.name = "stretch";
  r.camera_offset = Vec3(0.05, 0.0, 1.29);
  r.lift_moves_camera = false;
  r.lift_min = 0.0;
  r.lift_max = 0.4;  // the action's lift range (appendix J); the camera does not follow it
  r.footprint_radius = 0.2;
  r.reach = 0.8;
  return r;
}

StatusOr<RobotPreset> RobotPreset::ByName(const std::string& name) {
  if (name == "fetch") return Fetch();
  if (name == "stretch") return Stretch();
  return InvalidArgumentError("unknown robot '" + name + "' (expected fetch or stretch)");
}

double CameraModel::TanHalfHorizontal() const { return std::tan(0.5 * horizontal_fov); }
double CameraModel::TanHalfVertical() const { return aspect * TanHalfHorizontal(); }

Vec3 CameraPose::ToCamera(const Vec3& p) const {
  const Vec3 d = p - position;
  return Vec3(d.dot(forward), d.dot(left), d.dot(up));
}

CameraPose CameraPoseFor(const RobotPreset& robot, const RobotConfig& config) {
  CameraPose pose;
  const double c = std::cos(config.yaw), s = std::sin(config.yaw);
  const Vec3& off = robot.camera_offset;
  pose.position = Vec3(config.x + c * off.x() - s * off.y(), config.y + s * off.x() + c * off.y(),
                       off.z() + (robot.lift_moves_camera ? config.lift : 0.0));
  const double heading = config.yaw + config.pan;
  const double ch = std::cos(heading), sh = std::sin(heading);
  const double ct = std::cos(config.tilt), st = std::sin(config.tilt);
  // Positive tilt pitches the optical axis down.
  pose.forward = Vec3(ch * ct, sh * ct, -st);
  pose.left = Vec3(-sh, ch, 0.0);
  pose.up = pose.forward.cross(pose.left);
  return pose;
}

bool InFrustum(const CameraModel& camera, const CameraPose& pose, const Vec3& p) {
  return InFrustum(camera, pose, p, camera.TanHalfHorizontal());
}

bool InFrustum(const CameraModel& camera, const CameraPose& pose, const Vec3& p,
               double tan_half_horizontal) {
  const Vec3 q = pose.ToCamera(p);
  const double depth = q.x();
  if (depth < camera.near || depth > camera.far) return false;
  return std::abs(q.y()) <= depth * tan_half_horizontal &&
         std::abs(q.z()) <= depth * (camera.aspect * tan_half_horizontal);
}

double WrapAngle(double a) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  a = std::fmod(a + std::numbers::pi, kTwoPi);
  if (a < 0) a += kTwoPi;
  return a - std::numbers::pi;
}

}  // namespace npfkct::object_search
