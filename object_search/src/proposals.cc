#include "npfkct/object_search/proposals.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace npfkct::object_search {
namespace {

// The camera must be this far from the point it aims at (m): inside the frustum's depth range
// (0.5-1.7 m) with a margin for the point's own extent.
constexpr double kMinRange = 0.55;
constexpr double kMaxRange = 1.6;

double MeanOdds(const std::array<float, 8>& odds) {
  double m = 0.0;
  for (float v : odds) m += v;
  return m / 8.0;
}

// A base position drawn uniformly from the base regions (by area), free of the map.
bool SampleBase(const World& w, Rng& rng, double* x, double* y) {
  const double pick = rng.Uniform();
  const double u = rng.Uniform();
  const double v = rng.Uniform();
  return w.BasePointAt(pick, u, v, x, y) && w.BaseFeasible(*x, *y);
}

}  // namespace

int TargetCandidate(const World& world) {
  int best = 0;
  double best_mean = world.params.nu_p;
  for (int i = 1; i < static_cast<int>(world.objects.size()); ++i) {
    const ObjectKnowledge& o = world.objects[i];
    if (o.status == kRemoved || o.status == kDeclaredObstacle) continue;
    if (o.status == kDeclaredTarget) return i;
    const double mean = MeanOdds(o.odds);
    if (mean > best_mean) {
      best_mean = mean;
      best = i;
    }
  }
  return best;
}

uint32_t UnconfirmedFaces(const World& world, int i, double sign) {
  const double t = world.params.declare_threshold;
  const std::array<float, 8> odds =
      i == 0 ? [&] {
        std::array<float, 8> g;
        g.fill(static_cast<float>(world.params.guess_odds));
        return g;
      }()
             : world.objects[i].odds;
  uint32_t mask = 0;
  for (int k = 0; k < 8; ++k) {
    if (!(sign * odds[k] > t)) mask |= 1u << k;
  }
  return mask;
}

Vec3 FacePoint(const Box& box, int k) {
  const Vec3 corner = box.Corners()[k];
  return corner + 0.05 * (box.center - corner);
}

bool AimAt(const World& world, const Vec3& point, Rng& rng, RobotConfig* out) {
  const RobotDescription& r = world.robot;
  for (int tries = 0; tries < 64; ++tries) {
    RobotConfig c;
    if (!SampleBase(world, rng, &c.x, &c.y)) continue;
    c.lift = rng.Uniform(r.lift_min, r.lift_max);
    c.pan = rng.Uniform(r.pan_min, r.pan_max);
    // The camera sits ahead of the base center and turns with the base: refine the heading once
    // from the camera's position.
    double heading = std::atan2(point.y() - c.y, point.x() - c.x);
    Vec3 cam;
    for (int it = 0; it < 2; ++it) {
      c.yaw = WrapAngle(heading - c.pan);
      cam = CameraPoseFor(r, c).position;
      heading = std::atan2(point.y() - cam.y(), point.x() - cam.x());
    }
    c.yaw = WrapAngle(heading - c.pan);
    cam = CameraPoseFor(r, c).position;
    const double range = (point - cam).norm();
    if (range < kMinRange || range > kMaxRange) continue;
    const double horizontal = std::hypot(point.x() - cam.x(), point.y() - cam.y());
    c.tilt = std::clamp(std::atan2(cam.z() - point.z(), horizontal), r.tilt_min, r.tilt_max);
    *out = c;
    return true;
  }
  return false;
}

Status ProposalOptions::Validate() const {
  if (!(target_share >= 0.0 && target_share <= 1.0)) {
    return InvalidArgumentError("target_share must be in [0, 1]");
  }
  if (!(object_share >= 0.0 && object_share <= 1.0 - target_share)) {
    return InvalidArgumentError("object_share must be in [0, 1 - target_share]");
  }
  return OkStatus();
}

void ProposeMoves(const ObjectSearchModel& model, const ProposalOptions& options, int count,
                  Rng& rng, std::vector<RobotConfig>* configs, std::vector<ProposalSource>* sources,
                  const TerminationCondition* stop) {
  const World& w = model.world();
  const BoxSpace& box = model.KindSpace(kMoveKind);
  const int target = TargetCandidate(w);
  const uint32_t target_faces = target > 0 ? UnconfirmedFaces(w, target, +1) : 0;
  // Other known objects whose faces could still be confirmed as an obstacle's.
  std::vector<std::pair<int, uint32_t>> others;
  for (int i = 1; i < static_cast<int>(w.objects.size()); ++i) {
    if (i == target || w.objects[i].status != kUpdating) continue;
    const uint32_t faces = UnconfirmedFaces(w, i, -1);
    if (faces != 0) others.push_back({i, faces});
  }
  const int n_object =
      others.empty() ? 0 : static_cast<int>(std::lround(options.object_share * count));
  const int n_target = std::min(
      count - n_object,
      static_cast<int>(std::lround(
          (options.target_share + (others.empty() ? options.object_share : 0.0)) * count)));
  auto random_face = [&](uint32_t faces) {
    int pick = static_cast<int>(rng.UniformInt(std::popcount(faces)));
    for (int k = 0; k < 8; ++k) {
      if ((faces >> k & 1u) && pick-- == 0) return k;
    }
    return 0;
  };
  for (int n = 0; n < count; ++n) {
    // An aimed proposal may try many bases (a sparse world costs ~0.1 ms each).
    if (stop != nullptr && n % 32 == 31 && stop->ShouldStop(0)) break;
    RobotConfig c;
    ProposalSource source = ProposalSource::kUniform;
    bool aimed = false;
    if (n < n_target) {
      source = ProposalSource::kTarget;
      const Vec3 point = target > 0 && target_faces != 0
                             ? FacePoint(w.objects[target].box, random_face(target_faces))
                             : w.grid.Sample(rng, 0.5 * w.params.guess_size);
      aimed = AimAt(w, point, rng, &c);
    } else if (n < n_target + n_object) {
      source = ProposalSource::kObject;
      const auto& [i, faces] = others[rng.UniformInt(static_cast<int64_t>(others.size()))];
      aimed = AimAt(w, FacePoint(w.objects[i].box, random_face(faces)), rng, &c);
    }
    if (!aimed) {
      source = ProposalSource::kUniform;
      bool feasible = false;
      for (int tries = 0; tries < 64 && !feasible; ++tries) {
        c = ObjectSearchModel::ConfigOf(box.SampleUniform(rng));
        feasible = w.BaseFeasible(c.x, c.y, c.yaw);
      }
      // A world where hardly any base is free: no proposal rather than one the robot cannot
      // take (the filter kept those, and the search answered a base inside the furniture).
      if (!feasible) continue;
    }
    configs->push_back(c);
    if (sources != nullptr) sources->push_back(source);
  }
}

Status AimedCandidateSampler::Sample(const ParticleBelief<State>& belief, int kind,
                                     const BoxSpace& box, int count,
                                     const TerminationCondition& stop, Rng& rng,
                                     std::vector<ActionVec>* out, CandidateStats* stats) {
  if (kind != kMoveKind) {
    UniformCandidateSampler<State> uniform;
    return uniform.Sample(belief, kind, box, count, stop, rng, out, stats);
  }
  std::vector<RobotConfig> configs;
  ProposeMoves(model_, options_, count, rng, &configs, nullptr, &stop);
  for (const RobotConfig& c : configs) out->push_back(box.Clamp(ObjectSearchModel::VecOf(c)));
  if (stats != nullptr) {
    stats->sampled += static_cast<int>(configs.size());
    stats->accepted += static_cast<int>(configs.size());
  }
  return OkStatus();
}

}  // namespace npfkct::object_search
