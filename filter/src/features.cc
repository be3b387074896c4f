#include "npfkct/filter/features.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace npfkct::filter {
namespace {

using object_search::Box;
using object_search::kRemoved;
using object_search::Vec2;

// The square of the floor the features cover: the occupancy map's bounds.
struct Frame2 {
  Vec2 center;
  double half;
  explicit Frame2(const World& w) {
    const Vec2 lo = w.occupancy.min(), hi = w.occupancy.max();
    center = (lo + hi) / 2.0;
    half = std::max({(hi - lo).maxCoeff() / 2.0, 1e-3});
  }
  float X(double x) const { return static_cast<float>((x - center.x()) / half); }
  float Y(double y) const { return static_cast<float>((y - center.y()) / half); }
  Vec2 PixelCenter(int u, int v) const {
    const double step = 2.0 * half / kImageSize;
    return Vec2(center.x() - half + (u + 0.5) * step, center.y() - half + (v + 0.5) * step);
  }
  // Pixel of a point, or false outside the image.
  bool Pixel(double x, double y, int* u, int* v) const {
    const double step = 2.0 * half / kImageSize;
    *u = static_cast<int>(std::floor((x - (center.x() - half)) / step));
    *v = static_cast<int>(std::floor((y - (center.y() - half)) / step));
    return *u >= 0 && *v >= 0 && *u < kImageSize && *v < kImageSize;
  }
};

bool InsideXY(const Box& b, const Vec2& p) {
  const Vec3 local = b.ToLocal(Vec3(p.x(), p.y(), b.center.z()));
  return std::abs(local.x()) <= b.size.x() / 2 && std::abs(local.y()) <= b.size.y() / 2;
}

float Unit(double v) { return static_cast<float>(std::clamp(v, 0.0, 1.0)); }

float Normalised(double v, double lo, double hi) {
  if (!(hi > lo)) return 0.0f;
  return static_cast<float>(2.0 * (v - lo) / (hi - lo) - 1.0);
}

}  // namespace

SceneFeatures SceneOf(const World& world, Rng& rng) {
  SceneFeatures f;
  f.points.assign(kPoints * kPointDim, 0.0f);
  f.image.assign(kImageChannels * kImageSize * kImageSize, 0.0f);
  const Frame2 frame(world);
  auto at = [&](int c, int u, int v) -> float& {
    return f.image[(c * kImageSize + v) * kImageSize + u];
  };
  // Channel 0: the probability that the target stands in a cell, maximum per pixel.
  const auto& grid = world.grid;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    const Vec3 p = grid.CellCenter(cell);
    int u, v;
    if (!frame.Pixel(p.x(), p.y(), &u, &v)) continue;
    const float prob = 1.0f / (1.0f + std::exp(-grid.log_odds(cell)));
    at(0, u, v) = std::max(at(0, u, v), prob);
  }
  std::vector<const Box*> objects;
  for (size_t i = 1; i < world.objects.size(); ++i) {
    if (world.objects[i].status != kRemoved) objects.push_back(&world.objects[i].box);
  }
  for (int v = 0; v < kImageSize; ++v) {
    for (int u = 0; u < kImageSize; ++u) {
      const Vec2 p = frame.PixelCenter(u, v);
      for (const Box& b : world.furniture) {
        if (InsideXY(b, p))
          at(1, u, v) = std::max(at(1, u, v), Unit((b.center.z() + b.size.z() / 2) / 2));
      }
      for (const Box* b : objects) {
        if (InsideXY(*b, p))
          at(2, u, v) = std::max(at(2, u, v), Unit((b->center.z() + b->size.z() / 2) / 2));
      }
      at(3, u, v) = world.BaseFeasible(p.x(), p.y()) ? 1.0f : 0.0f;
    }
  }
  // The object cloud: points on the faces of every known object, round robin.
  std::vector<int> known;
  for (size_t i = 1; i < world.objects.size(); ++i) {
    if (world.objects[i].status != kRemoved) known.push_back(static_cast<int>(i));
  }
  if (known.empty()) return f;
  const float limit = static_cast<float>(world.params.face_odds_limit);
  for (int k = 0; k < kPoints; ++k) {
    const auto& obj = world.objects[known[k % known.size()]];
    const Box& b = obj.box;
    // A face drawn by area, then a point uniform on it (box frame).
    const double sx = b.size.x(), sy = b.size.y(), sz = b.size.z();
    const double areas[3] = {sy * sz, sx * sz, sx * sy};
    double r = rng.Uniform() * (areas[0] + areas[1] + areas[2]);
    const int axis = r < areas[0] ? 0 : (r < areas[0] + areas[1] ? 1 : 2);
    Vec3 local(rng.Uniform(-0.5, 0.5) * sx, rng.Uniform(-0.5, 0.5) * sy,
               rng.Uniform(-0.5, 0.5) * sz);
    local[axis] = (rng.Bernoulli(0.5) ? 0.5 : -0.5) * b.size[axis];
    const double c = std::cos(b.yaw), s = std::sin(b.yaw);
    const Vec3 p =
        b.center + Vec3(c * local.x() - s * local.y(), s * local.x() + c * local.y(), local.z());
    const int corner = (local.x() > 0 ? 1 : 0) | (local.y() > 0 ? 2 : 0) | (local.z() > 0 ? 4 : 0);
    float* out = &f.points[k * kPointDim];
    out[0] = frame.X(p.x());
    out[1] = frame.Y(p.y());
    out[2] = static_cast<float>(p.z() / 2.0);
    out[3] = obj.odds[corner] / limit;
    out[4] = static_cast<float>(obj.moveability);
  }
  return f;
}

void QueryOf(const World& world, const RobotConfig& config, int candidate,
             const std::vector<Vec3>& probe, float* out) {
  const Frame2 frame(world);
  const auto& r = world.robot;
  out[0] = frame.X(config.x);
  out[1] = frame.Y(config.y);
  out[2] = static_cast<float>(std::cos(config.yaw));
  out[3] = static_cast<float>(std::sin(config.yaw));
  out[4] = Normalised(config.lift, r.lift_min, r.lift_max);
  out[5] = Normalised(config.pan, r.pan_min, r.pan_max);
  out[6] = Normalised(config.tilt, r.tilt_min, r.tilt_max);
  const auto pose = object_search::CameraPoseFor(r, config);
  out[7] = frame.X(pose.position.x());
  out[8] = frame.Y(pose.position.y());
  out[9] = static_cast<float>(pose.position.z() / 2.0);
  out[10] = static_cast<float>(pose.forward.x());
  out[11] = static_cast<float>(pose.forward.y());
  out[12] = static_cast<float>(pose.forward.z());
  float* c = out + kConfigDim;
  std::fill(c, c + kCandidateDim, 0.0f);
  const float limit = static_cast<float>(world.params.face_odds_limit);
  float* odds = c + kCandidateDim;
  const double tan_h = world.camera.TanHalfHorizontal(), tan_v = world.camera.TanHalfVertical();
  // The share of `points` inside the frustum and their mean position in the image.
  auto frustum = [&](const std::vector<Vec3>& points, double* share, Vec3* mean) {
    int inside = 0;
    *mean = Vec3::Zero();
    for (const Vec3& p : points) {
      if (!object_search::InFrustum(world.camera, pose, p)) continue;
      const Vec3 q = pose.ToCamera(p);
      *mean += Vec3(q.x() / world.camera.far, q.y() / (q.x() * tan_h), q.z() / (q.x() * tan_v));
      ++inside;
    }
    *share = points.empty() ? 0.0 : static_cast<double>(inside) / points.size();
    if (inside > 0) *mean /= inside;
  };
  double share = 0.0;
  Vec3 mean = Vec3::Zero();
  if (candidate <= 0 || candidate >= static_cast<int>(world.objects.size())) {
    c[0] = 1.0f;  // the guessed target: where it may be is in the image
    frustum(probe, &share, &mean);
    c[12] = static_cast<float>(share);
    for (int k = 0; k < 3; ++k) c[13 + k] = static_cast<float>(mean[k]);
    for (int k = 0; k < 8; ++k) odds[k] = static_cast<float>(world.params.guess_odds) / limit;
    return;
  }
  const Box& b = world.objects[candidate].box;
  c[1] = frame.X(b.center.x());
  c[2] = frame.Y(b.center.y());
  c[3] = static_cast<float>(b.center.z() / 2.0);
  c[4] = static_cast<float>(b.size.x());
  c[5] = static_cast<float>(b.size.y());
  c[6] = static_cast<float>(b.size.z());
  c[7] = static_cast<float>(std::cos(b.yaw));
  c[8] = static_cast<float>(std::sin(b.yaw));
  const Vec3 in_camera = pose.ToCamera(b.center) / world.camera.far;
  c[9] = static_cast<float>(in_camera.x());
  c[10] = static_cast<float>(in_camera.y());
  c[11] = static_cast<float>(in_camera.z());
  // The unconfirmed face grids among the 4 corners nearest the camera, with points in the
  // frustum.
  const uint32_t unconfirmed = object_search::UnconfirmedFaces(world, candidate, +1);
  if (unconfirmed != 0) {
    std::vector<Vec3> points;
    for (int k : object_search::NearestCorners(b.Corners(), pose.position)) {
      if (unconfirmed >> k & 1u) points.push_back(object_search::FacePoint(b, k));
    }
    const size_t candidates = points.size();
    frustum(points, &share, &mean);
    share = share * candidates / std::min(4, std::popcount(unconfirmed));
  }
  c[12] = static_cast<float>(share);
  for (int k = 0; k < 3; ++k) c[13 + k] = static_cast<float>(mean[k]);
  for (int k = 0; k < 8; ++k) odds[k] = world.objects[candidate].odds[k] / limit;
}

std::vector<Vec3> SamplePlacements(const World& world, int count, Rng& rng) {
  std::vector<Vec3> out;
  out.reserve(count);
  for (int i = 0; i < count; ++i)
    out.push_back(world.grid.Sample(rng, 0.5 * world.params.guess_size));
  return out;
}

double TargetScore(const ObjectSearchModel& model, const State& s, int candidate,
                   const RobotConfig& config, const std::vector<Vec3>& placements) {
  if (s.objects.empty()) return 0.0;
  if (candidate <= 0 || candidate >= static_cast<int>(s.objects.size())) {
    if (placements.empty()) return 0.0;
    State t = s;
    int seen = 0;
    for (const Vec3& p : placements) {
      t.target = p;
      if (model.SeesObject(t, config, 0)) ++seen;
    }
    return static_cast<double>(seen) / static_cast<double>(placements.size());
  }
  const uint32_t unconfirmed = object_search::UnconfirmedFaces(model.world(), candidate, +1);
  if (unconfirmed == 0) return 0.0;
  std::array<std::array<int, 4>, object_search::kMaxObjects> nearest;
  if (!(model.VisibleObjects(s, config, &nearest) >> candidate & 1u)) return 0.0;
  int updated = 0;
  for (int k : nearest[candidate]) updated += (unconfirmed >> k) & 1u;
  return static_cast<double>(updated) / std::min(4, std::popcount(unconfirmed));
}

object_search::ProposalOptions TrainingProposals() {
  object_search::ProposalOptions o;
  o.target_share = 0.5;
  o.object_share = 0.2;
  return o;
}

ScoredConfigs ScoreConfigs(const ObjectSearchModel& model, const State& s,
                           const std::vector<Vec3>& placements, const std::vector<Vec3>& probe,
                           int n, Rng& rng, const TerminationCondition* stop) {
  ScoredConfigs out;
  const int candidate = object_search::TargetCandidate(model.world());
  object_search::ProposeMoves(model, TrainingProposals(), n, rng, &out.configs, nullptr, stop);
  n = static_cast<int>(out.configs.size());
  out.queries.resize(static_cast<size_t>(n) * kQueryDim);
  out.scores.resize(n);
  for (int i = 0; i < n; ++i) {
    // One exact score checks every placement (up to 10,000 of them).
    if (stop != nullptr && stop->ShouldStop(0)) {
      out.configs.resize(i);
      out.queries.resize(static_cast<size_t>(i) * kQueryDim);
      out.scores.resize(i);
      break;
    }
    QueryOf(model.world(), out.configs[i], candidate, probe,
            &out.queries[static_cast<size_t>(i) * kQueryDim]);
    out.scores[i] =
        static_cast<float>(TargetScore(model, s, candidate, out.configs[i], placements));
  }
  return out;
}

}  // namespace npfkct::filter
