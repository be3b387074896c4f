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

namespace {

CameraJoint Joint(std::string name, CameraJoint::Type type, CameraJoint::Role role, Vec3 xyz,
                  Vec3 axis, double lower, double upper) {
  CameraJoint j;
  j.name = std::move(name);
  j.type = type;
  j.role = role;
  j.xyz = xyz;
  j.axis = axis;
  j.lower = lower;
  j.upper = upper;
  return j;
}

// The pan-tilt head both shipped robots share (appendix J: pan +-pi/12, tilt +-0.5 rad).
void AddPanTilt(RobotDescription* r) {
  using T = CameraJoint::Type;
  using R = CameraJoint::Role;
  r->chain.push_back(
      Joint("head_pan", T::kRevolute, R::kPan, Vec3::Zero(), Vec3::UnitZ(), -0.2618, 0.2618));
  r->chain.push_back(
      Joint("head_tilt", T::kRevolute, R::kTilt, Vec3::Zero(), Vec3::UnitY(), -0.5, 0.5));
}

Eigen::Matrix3d RpyRotation(const Vec3& rpy) {
  return (Eigen::AngleAxisd(rpy.z(), Vec3::UnitZ()) * Eigen::AngleAxisd(rpy.y(), Vec3::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Vec3::UnitX()))
      .toRotationMatrix();
}

bool Finite(const Vec3& v) { return v.allFinite(); }

// The rotation by q about the unit axis `axis`: written out for the coordinate axes (every
// shipped joint turns about one; the planner computes a camera pose per simulated view), else
// Rodrigues' formula.
Eigen::Matrix3d AxisRotation(const Vec3& axis, double q) {
  const double c = std::cos(q), s = std::sin(q);
  Eigen::Matrix3d r;
  if (axis == Vec3::UnitZ()) {
    r << c, -s, 0, s, c, 0, 0, 0, 1;
  } else if (axis == Vec3::UnitY()) {
    r << c, 0, s, 0, 1, 0, -s, 0, c;
  } else if (axis == Vec3::UnitX()) {
    r << 1, 0, 0, 0, c, -s, 0, s, c;
  } else {
    r = Eigen::AngleAxisd(q, axis).toRotationMatrix();
  }
  return r;
}

}  // namespace

RobotDescription RobotDescription::Fetch() {
  RobotDescription r;
  r.name = "fetch";
  // The camera 0.15 m ahead of the base centre and 1.08 m up at the lowest torso.
  r.chain.push_back(Joint("torso_lift", CameraJoint::Type::kPrismatic, CameraJoint::Role::kLift,
                          Vec3(0.15, 0.0, 1.08), Vec3::UnitZ(), 0.0, 0.4));
  AddPanTilt(&r);
  r.footprint_radius = 0.3;
  r.reach = 1.0;
  (void)r.Validate();  // well-formed (a unit test checks)
  return r;
}

RobotDescription RobotDescription::Stretch() {
  RobotDescription r;
  r.name = "stretch";
  r.chain.push_back(Joint("mast", CameraJoint::Type::kFixed, CameraJoint::Role::kNone,
                          Vec3(0.05, 0.0, 1.29), Vec3::UnitZ(), 0.0, 0.0));
  AddPanTilt(&r);
  r.footprint_radius = 0.2;
  r.reach = 0.8;
  (void)r.Validate();
  return r;
}

StatusOr<RobotDescription> RobotDescription::ByName(const std::string& name) {
  if (name == "fetch") return Fetch();
  if (name == "stretch") return Stretch();
  return InvalidArgumentError("unknown robot '" + name + "' (expected fetch or stretch)");
}

Status RobotDescription::Validate() {
  if (name.size() > 64) return InvalidFieldError("name", "at most 64 characters");
  if (chain.size() > static_cast<size_t>(kMaxJoints)) {
    return InvalidFieldError("joints", "at most " + std::to_string(kMaxJoints) + " joints");
  }
  if (!footprint.empty()) {
    const size_t n = footprint.size();
    if (n < 3 || n > static_cast<size_t>(kMaxFootprintVertices)) {
      return InvalidFieldError(
          "footprint", "must have 3 to " + std::to_string(kMaxFootprintVertices) + " vertices");
    }
    double area = 0.0, radius = 0.0;
    for (size_t i = 0; i < n; ++i) {
      if (!footprint[i].allFinite() || footprint[i].norm() > 5.0) {
        return InvalidFieldError("footprint[" + std::to_string(i) + "]",
                                 "must be finite and within 5 m of the base");
      }
      const Eigen::Vector2d& a = footprint[i];
      const Eigen::Vector2d& b = footprint[(i + 1) % n];
      area += 0.5 * (a.x() * b.y() - b.x() * a.y());
      radius = std::max(radius, a.norm());
    }
    if (!(std::abs(area) >= 1e-4)) {
      return InvalidFieldError("footprint", "must enclose an area (at least 1 cm^2)");
    }
    for (size_t i = 0; i < n; ++i) {
      for (size_t k = i + 2; k < n; ++k) {
        if (i == 0 && k == n - 1) continue;  // neighbours through the closing edge
        if (SegmentDistance(footprint[i], footprint[i + 1], footprint[k], footprint[(k + 1) % n]) ==
            0.0) {
          return InvalidFieldError("footprint[" + std::to_string(k) + "]",
                                   "the polygon's edges cross (it must be simple)");
        }
      }
    }
    footprint_radius = radius;
  }
  if (!(footprint_radius > 0.0 && footprint_radius <= 5.0)) {
    return InvalidFieldError("footprintRadius", "must be in (0, 5] m");
  }
  if (!(reach >= 0.0 && reach <= 10.0)) return InvalidFieldError("reach", "must be in [0, 10] m");
  if (!(camera.horizontal_fov > 0.01 && camera.horizontal_fov <= 3.0)) {
    return InvalidFieldError("camera.horizontalFov", "must be in (0.01, 3] rad");
  }
  if (!(camera.aspect >= 0.05 && camera.aspect <= 20.0) ||
      !(std::atan(camera.aspect * std::tan(0.5 * camera.horizontal_fov)) < 1.5)) {
    return InvalidFieldError("camera.aspect",
                             "must be in [0.05, 20], the vertical field of view "
                             "under 3 rad");
  }
  if (!(camera.near > 0.0 && camera.near < camera.far)) {
    return InvalidFieldError("camera.near", "must be in (0, far)");
  }
  if (!(camera.far <= 50.0)) return InvalidFieldError("camera.far", "must be at most 50 m");
  double* limits[4][2] = {
      {nullptr, nullptr}, {&lift_min, &lift_max}, {&pan_min, &pan_max}, {&tilt_min, &tilt_max}};
  bool taken[4] = {false, false, false, false};
  for (int k = 1; k < 4; ++k) *limits[k][0] = *limits[k][1] = 0.0;
  for (size_t i = 0; i < chain.size(); ++i) {
    CameraJoint& j = chain[i];
    const std::string at = "joints[" + std::to_string(i) + "].";
    if (j.name.size() > 64) return InvalidFieldError(at + "name", "at most 64 characters");
    if (!Finite(j.xyz) || j.xyz.cwiseAbs().maxCoeff() > 10.0) {
      return InvalidFieldError(at + "xyz", "finite, each within 10 m");
    }
    if (!Finite(j.rpy) || j.rpy.cwiseAbs().maxCoeff() > 10.0) {
      return InvalidFieldError(at + "rpy", "finite, each within 10 rad");
    }
    const int role = static_cast<int>(j.role);
    if (j.type == CameraJoint::Type::kFixed) {
      if (j.role != CameraJoint::Role::kNone) {
        return InvalidFieldError(at + "role", "a fixed joint cannot drive an action dimension");
      }
      continue;
    }
    if (!Finite(j.axis) || j.axis.norm() < 1e-6) {
      return InvalidFieldError(at + "axis", "finite and not zero");
    }
    j.axis.normalize();
    if (!(std::isfinite(j.lower) && std::isfinite(j.upper) && j.lower <= j.upper &&
          std::abs(j.lower) <= 10.0 && std::abs(j.upper) <= 10.0)) {
      return InvalidFieldError(at + "lower", "finite limits, lower <= upper, within 10");
    }
    if (j.role == CameraJoint::Role::kNone) continue;
    if ((j.role == CameraJoint::Role::kLift) != (j.type == CameraJoint::Type::kPrismatic)) {
      return InvalidFieldError(at + "role",
                               "the lift is a prismatic joint, the pan and tilt revolute ones");
    }
    if (taken[role]) return InvalidFieldError(at + "role", "another joint has this role");
    taken[role] = true;
    *limits[role][0] = j.lower;
    *limits[role][1] = j.upper;
  }
  return OkStatus();
}

double CameraModel::TanHalfHorizontal() const { return std::tan(0.5 * horizontal_fov); }
double CameraModel::TanHalfVertical() const { return aspect * TanHalfHorizontal(); }

Vec3 CameraPose::ToCamera(const Vec3& p) const {
  const Vec3 d = p - position;
  return Vec3(d.dot(forward), d.dot(left), d.dot(up));
}

CameraPose CameraPoseFor(const RobotDescription& robot, const RobotConfig& config) {
  // The base on the floor, turned by its yaw; then each joint's origin and motion.
  Eigen::Matrix3d r = AxisRotation(Vec3::UnitZ(), config.yaw);
  Vec3 t(config.x, config.y, 0.0);
  for (const CameraJoint& j : robot.chain) {
    t += r * j.xyz;
    if (!j.rpy.isZero()) r = r * RpyRotation(j.rpy);
    if (j.type == CameraJoint::Type::kFixed) continue;
    double q = 0.0;
    switch (j.role) {
      case CameraJoint::Role::kLift:
        q = config.lift;
        break;
      case CameraJoint::Role::kPan:
        q = config.pan;
        break;
      case CameraJoint::Role::kTilt:
        q = config.tilt;
        break;
      case CameraJoint::Role::kNone:
        q = std::clamp(0.0, j.lower, j.upper);
        break;
    }
    if (j.type == CameraJoint::Type::kPrismatic) {
      t += r * (q * j.axis);
    } else {
      r = r * AxisRotation(j.axis, q);
    }
  }
  CameraPose pose;
  pose.position = t;
  pose.forward = r.col(0);
  pose.left = r.col(1);
  pose.up = r.col(2);
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

namespace {

// The distance from p to segment ab.
double PointSegmentDistance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                            const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double length2 = ab.squaredNorm();
  const double t = length2 > 0.0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

// The sign of the turn a -> b -> c: > 0 left, < 0 right, 0 collinear.
double Turn(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  const Eigen::Vector2d u = b - a, v = c - a;
  return u.x() * v.y() - u.y() * v.x();
}

}  // namespace

double SegmentDistance(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                       const Eigen::Vector2d& d) {
  const double d1 = Turn(c, d, a), d2 = Turn(c, d, b), d3 = Turn(a, b, c), d4 = Turn(a, b, d);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) {
    return 0.0;  // they cross
  }
  return std::min({PointSegmentDistance(a, c, d), PointSegmentDistance(b, c, d),
                   PointSegmentDistance(c, a, b), PointSegmentDistance(d, a, b)});
}

bool InsidePolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p) {
  bool inside = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y())) {
      inside = !inside;
    }
  }
  return inside;
}

double PolygonDistance(const std::vector<Eigen::Vector2d>& p,
                       const std::vector<Eigen::Vector2d>& q) {
  if (p.empty() || q.empty()) return std::numeric_limits<double>::infinity();
  if (InsidePolygon(p, q[0]) || InsidePolygon(q, p[0])) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < p.size(); ++i) {
    for (size_t k = 0; k < q.size(); ++k) {
      best =
          std::min(best, SegmentDistance(p[i], p[(i + 1) % p.size()], q[k], q[(k + 1) % q.size()]));
      if (best == 0.0) return 0.0;
    }
  }
  return best;
}

double WrapAngle(double a) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  a = std::fmod(a + std::numbers::pi, kTwoPi);
  if (a < 0) a += kTwoPi;
  return a - std::numbers::pi;
}

std::array<int, 4> NearestCorners(const std::array<Vec3, 8>& corners, const Vec3& from) {
  std::array<std::pair<double, int>, 8> by_distance;
  for (int k = 0; k < 8; ++k) by_distance[k] = {(corners[k] - from).squaredNorm(), k};
  std::partial_sort(by_distance.begin(), by_distance.begin() + 4, by_distance.end());
  return {by_distance[0].second, by_distance[1].second, by_distance[2].second,
          by_distance[3].second};
}

StatusOr<Box> BoxAroundPolygon(const std::vector<Vec2>& polygon, double height) {
  if (polygon.size() < 3) return InvalidArgumentError("a polygon needs 3 points or more");
  // The convex hull (Andrew's monotone chain), counter-clockwise.
  std::vector<Vec2> points = polygon;
  std::sort(points.begin(), points.end(), [](const Vec2& a, const Vec2& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  std::vector<Vec2> hull(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {  // lower hull
    while (k >= 2 && Turn(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {  // upper hull
    while (k >= lower && Turn(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k > 1 ? k - 1 : k);
  if (hull.size() < 3) return InvalidArgumentError("the polygon's points span no area");
  // The smallest rectangle has a side along an edge of the hull.
  double best_area = std::numeric_limits<double>::infinity();
  Box best;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Vec2 edge = hull[(i + 1) % hull.size()] - hull[i];
    const double yaw = std::atan2(edge.y(), edge.x());
    const double c = std::cos(yaw), s = std::sin(yaw);
    Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Vec2& p : hull) {
      const Vec2 q(c * p.x() + s * p.y(), -s * p.x() + c * p.y());
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    const Vec2 size = hi - lo;
    if (size.x() * size.y() < best_area) {
      best_area = size.x() * size.y();
      const Vec2 mid = 0.5 * (lo + hi);
      best.center = Vec3(c * mid.x() - s * mid.y(), s * mid.x() + c * mid.y(), 0.5 * height);
      best.size = Vec3(size.x(), size.y(), height);
      best.yaw = yaw;
    }
  }
  if (!(best_area > 0.0)) return InvalidArgumentError("the polygon's points span no area");
  return best;
}

}  // namespace npfkct::object_search
