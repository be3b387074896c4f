#include "npfkct/sim/simulator.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace npfkct::sim {
namespace {

using object_search::ActionOutcome;
using object_search::kDeclaredObstacle;
using object_search::kDeclaredTarget;
using object_search::KindObject;
using object_search::KindOffset;
using object_search::kMoveKind;
using object_search::ObjectSearchModel;
using object_search::RewardOf;

// Ray-box hit with the face that was entered (0/1: -x/+x, 2/3: -y/+y, 4/5: -z/+z) and the hit
// point in the box frame.
bool HitBox(const Box& b, const Vec3& origin, const Vec3& dir, double* t_hit, int* face,
            Vec3* local_hit) {
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  const Vec3 d = origin - b.center;
  const Vec3 o(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  const Vec3 v(c * dir.x() + s * dir.y(), -s * dir.x() + c * dir.y(), dir.z());
  double lo = 1e-9, hi = std::numeric_limits<double>::infinity();
  int lo_face = -1;
  for (int i = 0; i < 3; ++i) {
    const double half = 0.5 * b.size[i];
    if (std::abs(v[i]) < 1e-15) {
      if (std::abs(o[i]) > half) return false;
      continue;
    }
    double t0 = (-half - o[i]) / v[i];
    double t1 = (half - o[i]) / v[i];
    int f0 = 2 * i, f1 = 2 * i + 1;
    if (t0 > t1) {
      std::swap(t0, t1);
      std::swap(f0, f1);
    }
    if (t0 > lo) {
      lo = t0;
      lo_face = f0;
    }
    hi = std::min(hi, t1);
    if (lo > hi) return false;
  }
  if (lo_face < 0) return false;  // origin inside the box
  *t_hit = lo;
  *face = lo_face;
  *local_hit = o + lo * v;
  return true;
}

Vec3 FaceNormalWorld(const Box& b, int face) {
  Vec3 n = Vec3::Zero();
  n[face / 2] = (face % 2) ? 1.0 : -1.0;
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  return Vec3(c * n.x() - s * n.y(), s * n.x() + c * n.y(), n.z());
}

}  // namespace

// A printed pattern: three coarse octaves of value noise in a palette drawn from the seed, with
// dark contour lines, so that feature matching (SIFT) finds distinctive corners and blobs
// everywhere on the face, and another seed prints a different picture.
Color PatternColor(uint32_t seed, int face, double u, double v) {
  auto hash = [&](uint64_t a, uint64_t b, uint64_t c) {
    return HashMix(static_cast<uint64_t>(seed) * 0x9e3779b97f4a7c15ULL + face * 1000003ULL +
                   a * 7919ULL + b * 104729ULL + c);
  };
  auto noise = [&](int cells) {
    const double gx = u * cells, gy = v * cells;
    const int ix = static_cast<int>(std::floor(gx)), iy = static_cast<int>(std::floor(gy));
    double fx = gx - ix, fy = gy - iy;
    fx = fx * fx * (3 - 2 * fx);
    fy = fy * fy * (3 - 2 * fy);
    auto corner = [&](int x, int y) {
      return (hash(cells, static_cast<uint64_t>(x + 64), static_cast<uint64_t>(y + 64)) & 0xffff) /
             65535.0;
    };
    const double a = corner(ix, iy) + fx * (corner(ix + 1, iy) - corner(ix, iy));
    const double b = corner(ix, iy + 1) + fx * (corner(ix + 1, iy + 1) - corner(ix, iy + 1));
    return a + fy * (b - a);
  };
  // Coarse enough that a 12 cm face still shows its blobs and lines from 1.5 m at 640 x 480.
  const double value = 0.55 * noise(3) + 0.3 * noise(6) + 0.15 * noise(11);
  if (std::fmod(value * 5.0, 1.0) < 0.15) return {25, 25, 30};  // contour lines
  const uint64_t p = hash(0, 0, 0);
  const Color lo = {static_cast<uint8_t>(p % 200), static_cast<uint8_t>((p >> 8) % 200),
                    static_cast<uint8_t>((p >> 16) % 200)};
  const Color hi = {static_cast<uint8_t>(55 + (p >> 24) % 200),
                    static_cast<uint8_t>(55 + (p >> 32) % 200),
                    static_cast<uint8_t>(55 + (p >> 40) % 200)};
  Color c;
  for (int k = 0; k < 3; ++k) c[k] = static_cast<uint8_t>(lo[k] + value * (hi[k] - lo[k]));
  return c;
}

Simulator::Simulator(Scenario scenario, uint64_t seed) : scenario_(std::move(scenario)) {
  preset_ = scenario_.robot;
  camera_ = preset_.camera;
  occupancy_ =
      object_search::OccupancyMap(scenario_.room_min, scenario_.room_max, scenario_.map_resolution);
  for (const Furniture& f : scenario_.furniture) occupancy_.AddBox(f.box);
  robot_ = scenario_.start;
  objects_ = scenario_.objects;
  removed_.assign(objects_.size(), false);
  Rng rng(seed * 0x9e3779b97f4a7c15ULL + 17);
  for (size_t i = 0; i < objects_.size(); ++i) {
    if (scenario_.noise.object_jitter > 0.0) {
      objects_[i].box.center.x() += scenario_.noise.object_jitter * rng.Normal();
      objects_[i].box.center.y() += scenario_.noise.object_jitter * rng.Normal();
    }
    if (objects_[i].target) target_ = static_cast<int>(i);
  }
}

std::vector<Box> Simulator::Occluders(int except) const {
  std::vector<Box> out;
  for (const Furniture& f : scenario_.furniture) out.push_back(f.box);
  for (size_t i = 0; i < objects_.size(); ++i) {
    if (!removed_[i] && static_cast<int>(i) != except) out.push_back(objects_[i].box);
  }
  return out;
}

ExecutionOutcome Simulator::Execute(const HybridAction& action, const object_search::World& world,
                                    Rng& rng) {
  if (action.kind == kMoveKind) {
    if (action.x.size() != 6 || !action.x.allFinite()) {
      ExecutionOutcome out;
      out.reward = RewardOf(world.params, ActionOutcome::kIllegal);
      out.illegal = true;
      out.detail = "malformed move";
      return out;
    }
    return ExecuteMove(ObjectSearchModel::ConfigOf(action.x), world.params, rng);
  }
  const int i = KindObject(action.kind);
  if (action.kind < 1 || i < 1 || i >= static_cast<int>(world.objects.size())) {
    ExecutionOutcome out;
    out.reward = RewardOf(world.params, ActionOutcome::kIllegal);
    out.illegal = true;
    out.detail = "no such object";
    return out;
  }
  return ExecuteOnObject(KindOffset(action.kind), world.objects[i].key, world.objects[i].status,
                         world.params, &world.objects[i].box);
}

int Simulator::FindObject(const std::string& key, const Box* seen) const {
  for (size_t k = 0; k < objects_.size(); ++k) {
    if (objects_[k].name == key) return static_cast<int>(k);
  }
  if (seen == nullptr) return -1;
  // An id the robot's perception made up: the object standing where the robot saw that box.
  int best = -1;
  double best_d = kSameObjectDistance;
  for (size_t k = 0; k < objects_.size(); ++k) {
    if (removed_[k]) continue;
    const double d = (objects_[k].box.center - seen->center).norm();
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(k);
    }
  }
  return best;
}

ExecutionOutcome Simulator::ExecuteMove(const RobotConfig& config,
                                        const object_search::SearchParams& p, Rng& rng) {
  ExecutionOutcome out;
  auto illegal = [&](const std::string& why) {
    out.reward = RewardOf(p, ActionOutcome::kIllegal);
    out.illegal = true;
    out.detail = why;
    return out;
  };
  RobotConfig c = config;
  c.yaw = object_search::WrapAngle(c.yaw);
  if (c.lift < preset_.lift_min - 1e-9 || c.lift > preset_.lift_max + 1e-9 ||
      c.pan < preset_.pan_min - 1e-9 || c.pan > preset_.pan_max + 1e-9 ||
      c.tilt < preset_.tilt_min - 1e-9 || c.tilt > preset_.tilt_max + 1e-9) {
    return illegal("joint limits exceeded");
  }
  if (!occupancy_.FootprintFree(preset_, c.x, c.y, c.yaw, 0.0)) {
    return illegal("base pose collides with the map");
  }
  c.x += scenario_.noise.pose_xy * rng.Normal();
  c.y += scenario_.noise.pose_xy * rng.Normal();
  c.yaw = object_search::WrapAngle(c.yaw + scenario_.noise.pose_yaw * rng.Normal());
  if (occupancy_.FootprintFree(preset_, c.x, c.y, c.yaw, 0.0)) robot_ = c;
  out.reward = RewardOf(p, ActionOutcome::kMoved);
  out.success = true;
  out.detail = "moved";
  return out;
}

ExecutionOutcome Simulator::ExecuteOnObject(int offset, const std::string& key, int8_t status,
                                            const object_search::SearchParams& p, const Box* seen) {
  ExecutionOutcome out;
  auto illegal = [&](const std::string& why) {
    out.reward = RewardOf(p, ActionOutcome::kIllegal);
    out.illegal = true;
    out.detail = why;
    return out;
  };
  const int scene = FindObject(key, seen);
  if (scene < 0 || removed_[scene]) return illegal("object '" + key + "' is not in the scene");
  const SceneObject& o = objects_[scene];
  switch (offset) {
    case object_search::kDeclareTargetOffset:
      if (!o.target) return illegal("declared object '" + key + "' the target, which it is not");
      out.reward = RewardOf(p, ActionOutcome::kDeclaredTarget);
      out.success = true;
      out.detail = "declared object '" + key + "' the target";
      return out;
    case object_search::kDeclareObstacleOffset:
      if (o.target) return illegal("declared the target (object '" + key + "') an obstacle");
      out.reward = RewardOf(p, ActionOutcome::kDeclaredObstacle);
      out.success = true;
      out.detail = "declared object '" + key + "' an obstacle";
      return out;
    default:
      if (!o.moveable) return illegal(key + " cannot be moved");
      if (status == kDeclaredTarget && o.target) {
        removed_[scene] = true;
        out.reward = RewardOf(p, ActionOutcome::kRemovedTarget);
        out.terminal = true;
        out.success = true;
        out.detail = "removed the target (object '" + key + "')";
        return out;
      }
      if (status == kDeclaredObstacle && !o.target) {
        removed_[scene] = true;
        out.reward = RewardOf(p, ActionOutcome::kRemovedObstacle);
        out.success = true;
        out.detail = "removed obstacle '" + key + "'";
        return out;
      }
      return illegal("removing undeclared " + key);
  }
}

std::vector<int> Simulator::VisibleCorners(int i, const RobotConfig& config,
                                           uint64_t ignore) const {
  std::vector<int> out;
  if (i < 0 || i >= static_cast<int>(objects_.size()) || removed_[i]) return out;
  const SceneObject& o = objects_[i];
  const object_search::CameraPose pose = object_search::CameraPoseFor(preset_, config);
  if (!object_search::InFrustum(camera_, pose, o.box.center)) return out;
  std::vector<Box> occluders;
  for (const Furniture& f : scenario_.furniture) occluders.push_back(f.box);
  for (size_t k = 0; k < objects_.size(); ++k) {
    if (removed_[k] || static_cast<int>(k) == i || (k < 64 && (ignore >> k & 1u))) continue;
    const Box& b = objects_[k].box;
    // Smaller objects nested inside this one (a covered target) do not hide it.
    if (b.size.prod() < o.box.size.prod() && o.box.Contains(b.center)) continue;
    occluders.push_back(b);
  }
  auto hidden = [&](const Vec3& p) {
    for (const Box& b : occluders) {
      if (b.Contains(p) || b.BlocksSegment(pose.position, p)) return true;
    }
    return false;
  };
  if (hidden(o.box.center)) return out;
  const auto corners = o.box.Corners();
  for (int k : object_search::NearestCorners(corners, pose.position)) {
    const Vec3 p = corners[k] + 0.05 * (o.box.center - corners[k]);
    if (object_search::InFrustum(camera_, pose, p) && !hidden(p)) out.push_back(k);
  }
  // Seen at all: the center is visible even when no corner is.
  if (out.empty()) out.push_back(-1);
  return out;
}

object_search::RealObservation Simulator::Observe(Rng& rng) const {
  object_search::RealObservation obs;
  obs.achieved = robot_;
  for (size_t i = 0; i < objects_.size(); ++i) {
    const std::vector<int> corners = VisibleCorners(static_cast<int>(i), robot_);
    if (corners.empty()) continue;
    const SceneObject& o = objects_[i];
    object_search::ObjectDetection d;
    d.key = o.name;
    d.box = o.box;
    d.box.center += scenario_.noise.box_estimate * Vec3(rng.Normal(), rng.Normal(), rng.Normal());
    d.box.size =
        (d.box.size + scenario_.noise.box_estimate * Vec3(rng.Normal(), rng.Normal(), rng.Normal()))
            .cwiseMax(0.01);
    d.moveability = o.moveable ? 0.95 : 0.05;
    for (int k : corners) {
      if (k < 0) continue;
      double score = o.target ? 0.85 : 0.15;
      if (rng.Bernoulli(scenario_.noise.false_detection)) score = 1.0 - score;
      score = std::clamp(score + scenario_.noise.detection * rng.Normal(), 0.01, 0.99);
      d.faces.push_back({k, score});
    }
    obs.objects.push_back(std::move(d));
  }
  return obs;
}

Frame Simulator::Render(int width, int height) const {
  Frame f;
  f.width = width;
  f.height = height;
  f.fx = 0.5 * width / camera_.TanHalfHorizontal();
  f.fy = 0.5 * height / camera_.TanHalfVertical();
  f.cx = 0.5 * width;
  f.cy = 0.5 * height;
  f.pose = object_search::CameraPoseFor(preset_, robot_);
  f.rgb.assign(static_cast<size_t>(width) * height * 3, 0);
  f.depth.assign(static_cast<size_t>(width) * height, 0.0f);
  f.ids.assign(static_cast<size_t>(width) * height, -1);
  constexpr double kMaxRange = 4.0;
  const Vec3 light = Vec3(0.3, 0.2, 1.0).normalized();
  struct Item {
    Box box;
    Color color;
    uint32_t texture;
    int16_t id;
  };
  std::vector<Item> items;
  for (size_t k = 0; k < scenario_.furniture.size(); ++k) {
    const Furniture& fu = scenario_.furniture[k];
    items.push_back({fu.box, fu.color, 0, static_cast<int16_t>(1000 + k)});
  }
  for (size_t k = 0; k < objects_.size(); ++k) {
    if (removed_[k]) continue;
    items.push_back(
        {objects_[k].box, objects_[k].color, objects_[k].texture_seed, static_cast<int16_t>(k)});
  }
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const Vec3 dir = (f.pose.forward - f.pose.left * ((u + 0.5 - f.cx) / f.fx) +
                        f.pose.up * ((f.cy - v - 0.5) / f.fy));
      const Vec3 unit = dir.normalized();
      double best_t = std::numeric_limits<double>::infinity();
      Color color = {0, 0, 0};
      int16_t id = -1;
      Vec3 normal = Vec3::UnitZ();
      // Floor.
      if (unit.z() < -1e-9) {
        const double t = -f.pose.position.z() / unit.z();
        const Vec3 hit = f.pose.position + t * unit;
        best_t = t;
        const bool check = (static_cast<int>(std::floor(hit.x() * 2)) +
                            static_cast<int>(std::floor(hit.y() * 2))) &
                           1;
        color = check ? Color{185, 185, 180} : Color{160, 160, 155};
      }
      for (const Item& item : items) {
        double t;
        int face;
        Vec3 local;
        if (!HitBox(item.box, f.pose.position, unit, &t, &face, &local) || t >= best_t) continue;
        best_t = t;
        id = item.id;
        normal = FaceNormalWorld(item.box, face);
        color = item.color;
        if (item.texture != 0) {
          const int a = (face / 2 + 1) % 3, b = (face / 2 + 2) % 3;
          const double fu = local[a] / item.box.size[a] + 0.5;
          const double fv = local[b] / item.box.size[b] + 0.5;
          color = PatternColor(item.texture, face, fu, fv);
        }
      }
      const double depth = best_t * unit.dot(f.pose.forward);
      if (!std::isfinite(best_t) || depth > kMaxRange) {
        // Nothing within range: a plain backdrop colour, no depth.
        const size_t idx = static_cast<size_t>(v) * width + u;
        f.rgb[idx * 3] = 200;
        f.rgb[idx * 3 + 1] = 205;
        f.rgb[idx * 3 + 2] = 215;
        continue;
      }
      const double shade = 0.55 + 0.45 * std::max(0.0, normal.dot(light));
      const size_t idx = static_cast<size_t>(v) * width + u;
      for (int ch = 0; ch < 3; ++ch) {
        f.rgb[idx * 3 + ch] = static_cast<uint8_t>(std::clamp(color[ch] * shade, 0.0, 255.0));
      }
      f.depth[idx] = static_cast<float>(depth);
      f.ids[idx] = id;
    }
  }
  return f;
}

}  // namespace npfkct::sim
