#include "npfkct/object_search/world.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>

namespace npfkct::object_search {
namespace {

bool Finite(const Box& b) {
  return b.center.allFinite() && std::isfinite(b.yaw) && b.size.allFinite();
}

Status CheckBox(const Box& b, const std::string& field) {
  if (!Finite(b)) return InvalidArgumentError(field + ": not finite");
  if (!(b.size.minCoeff() > 0.0)) return InvalidArgumentError(field + ".size: must be > 0");
  if (b.size.maxCoeff() > 100.0) return InvalidArgumentError(field + ".size: larger than 100 m");
  return OkStatus();
}

// The message of both limits on known objects (a world given whole, one grown by observations).
std::string TooManyObjects(const std::string& field) {
  return field + ": at most " + std::to_string(kMaxKnownObjects) + " objects are supported";
}

}  // namespace

Status SearchParams::Validate() const {
  auto finite = [](double v) { return std::isfinite(v); };
  if (!finite(r_max) || !finite(r_ct) || !finite(r_co) || !finite(r_min) || !finite(r_ill)) {
    return InvalidArgumentError("rewards must be finite");
  }
  if (!(r_max > r_ct && r_ct > r_co && r_co > 0.0 && r_min < 0.0)) {
    return InvalidArgumentError("rewards must satisfy r_max > r_ct > r_co > 0 > r_min");
  }
  if (!(r_ill < 0.0)) return InvalidArgumentError("r_ill must be < 0");
  if (!(discount > 0.0 && discount < 1.0))
    return InvalidArgumentError("discount must be in (0, 1)");
  if (!(c_o > 0.0) || !finite(c_o)) return InvalidArgumentError("c_o must be > 0");
  if (!(eta_std >= 0.0) || !finite(eta_std)) return InvalidArgumentError("eta_std must be >= 0");
  if (!(nu_n <= nu_p) || !finite(nu_n) || !finite(nu_p)) {
    return InvalidArgumentError("nu_n must be <= nu_p");
  }
  if (n_odds < 1 || n_odds > 8) return InvalidArgumentError("n_odds must be in [1, 8]");
  if (!(declare_threshold > 0.0) || !finite(declare_threshold)) {
    return InvalidArgumentError("declare_threshold must be > 0");
  }
  if (!finite(guess_odds)) return InvalidArgumentError("guess_odds must be finite");
  // The guessed target's faces restart at guess_odds after every real step: past the threshold
  // the plan would declare it before anything was seen, an action no observation can follow.
  // Compared as the planner holds them (float): 0.599999995 passed as a double below 0.6.
  if (!(std::abs(static_cast<double>(static_cast<float>(guess_odds))) < declare_threshold)) {
    return InvalidArgumentError(
        "guess_odds must lie strictly between -declare_threshold and "
        "declare_threshold");
  }
  if (!(guess_size > 0.0) || !finite(guess_size))
    return InvalidArgumentError("guess_size must be > 0");
  if (!(guess_moveability >= 0.0 && guess_moveability <= 1.0)) {
    return InvalidArgumentError("guess_moveability must be in [0, 1]");
  }
  if (!(grid_free_delta <= 0.0) || !finite(grid_free_delta)) {
    return InvalidArgumentError("grid_free_delta must be <= 0");
  }
  if (!(grid_min < grid_max) || !finite(grid_min) || !finite(grid_max)) {
    return InvalidArgumentError("grid_min must be < grid_max");
  }
  if (!(detection_max_step > 0.0) || !finite(detection_max_step)) {
    return InvalidArgumentError("detection_max_step must be > 0");
  }
  if (!(face_odds_limit > 0.0) || !finite(face_odds_limit)) {
    return InvalidArgumentError("face_odds_limit must be > 0");
  }
  if (!(static_cast<double>(static_cast<float>(face_odds_limit)) > declare_threshold)) {
    return InvalidArgumentError(
        "face_odds_limit must be > declare_threshold (odds are clamped to it: nothing could "
        "ever be declared)");
  }
  if (max_steps < 1) return InvalidArgumentError("max_steps must be >= 1");
  if (!(base_clearance >= 0.0 && base_clearance <= 1.0)) {
    return InvalidArgumentError("base_clearance must be in [0, 1] m");
  }
  return OkStatus();
}

double RewardOf(const SearchParams& p, ActionOutcome outcome) {
  switch (outcome) {
    case ActionOutcome::kMoved:
      return p.r_min;
    case ActionOutcome::kIllegal:
      return p.r_ill;
    case ActionOutcome::kDeclaredTarget:
      return p.r_ct;
    case ActionOutcome::kDeclaredObstacle:
      return p.r_co;
    case ActionOutcome::kRemovedTarget:
      return p.r_max;
    case ActionOutcome::kRemovedObstacle:
      return 2.0 * p.r_min;
  }
  return p.r_ill;
}

ActionOutcome SuccessfulOutcome(int kind_offset, int8_t status) {
  switch (kind_offset) {
    case kDeclareTargetOffset:
      return ActionOutcome::kDeclaredTarget;
    case kDeclareObstacleOffset:
      return ActionOutcome::kDeclaredObstacle;
    case kRemoveOffset:
      return status == kDeclaredTarget ? ActionOutcome::kRemovedTarget
                                       : ActionOutcome::kRemovedObstacle;
  }
  return ActionOutcome::kIllegal;
}

int8_t StatusAfter(int kind_offset) {
  return kind_offset == kDeclareTargetOffset     ? kDeclaredTarget
         : kind_offset == kDeclareObstacleOffset ? kDeclaredObstacle
                                                 : kRemoved;
}

OccupancyMap::OccupancyMap(Vec2 min, Vec2 max, double resolution)
    : min_(min), max_(max), resolution_(resolution) {
  nx_ = std::max(1, static_cast<int>(std::ceil((max.x() - min.x()) / resolution)));
  ny_ = std::max(1, static_cast<int>(std::ceil((max.y() - min.y()) / resolution)));
  occupied_.assign(static_cast<size_t>(nx_) * ny_, 0);
}

void OccupancyMap::AddBox(const Box& box, double margin) {
  // Only the cells under the box's bounding circle can be inside it.
  const double radius = 0.5 * std::hypot(box.size.x(), box.size.y()) + margin + 2.0 * resolution_;
  const auto range = [&](double center, double origin, int n) {
    const double a = std::floor((center - radius - origin) / resolution_) - 1.0;
    const double b = std::ceil((center + radius - origin) / resolution_) + 1.0;
    return std::pair<int, int>(static_cast<int>(std::clamp(a, 0.0, n - 1.0)),
                               static_cast<int>(std::clamp(b, 0.0, n - 1.0)));
  };
  if (nx_ <= 0 || ny_ <= 0 || !box.center.allFinite()) return;
  const auto [x0, x1] = range(box.center.x(), min_.x(), nx_);
  const auto [y0, y1] = range(box.center.y(), min_.y(), ny_);
  const BoxFrame frame(box);
  for (int iy = y0; iy <= y1; ++iy) {
    for (int ix = x0; ix <= x1; ++ix) {
      const Vec3 p(min_.x() + (ix + 0.5) * resolution_, min_.y() + (iy + 0.5) * resolution_,
                   box.center.z());
      const Vec3 l = frame.ToLocal(p);
      if (std::abs(l.x()) <= frame.half.x() + margin &&
          std::abs(l.y()) <= frame.half.y() + margin) {
        occupied_[iy * nx_ + ix] = 1;
      }
    }
  }
}

template <typename CellHits>
bool OccupancyMap::NoCellHits(double x, double y, double reach, CellHits hits) const {
  if (occupied_.empty()) return true;
  if (x - reach < min_.x() || y - reach < min_.y() || x + reach > max_.x() ||
      y + reach > max_.y()) {
    return false;
  }
  const int x0 = static_cast<int>((x - reach - min_.x()) / resolution_);
  const int x1 = static_cast<int>((x + reach - min_.x()) / resolution_);
  const int y0 = static_cast<int>((y - reach - min_.y()) / resolution_);
  const int y1 = static_cast<int>((y + reach - min_.y()) / resolution_);
  for (int iy = std::max(0, y0); iy <= std::min(ny_ - 1, y1); ++iy) {
    for (int ix = std::max(0, x0); ix <= std::min(nx_ - 1, x1); ++ix) {
      if (occupied_[iy * nx_ + ix] && hits(ix, iy)) return false;
    }
  }
  return true;
}

bool OccupancyMap::DiscFree(double x, double y, double radius) const {
  return NoCellHits(x, y, radius, [&](int ix, int iy) {
    // Distance from the disc center to the cell square.
    const double cx = std::clamp(x, min_.x() + ix * resolution_, min_.x() + (ix + 1) * resolution_);
    const double cy = std::clamp(y, min_.y() + iy * resolution_, min_.y() + (iy + 1) * resolution_);
    return (cx - x) * (cx - x) + (cy - y) * (cy - y) < radius * radius;
  });
}

bool OccupancyMap::FootprintFree(const RobotDescription& robot, double x, double y, double yaw,
                                 double clearance) const {
  if (robot.footprint.empty()) return DiscFree(x, y, robot.footprint_radius + clearance);
  const Eigen::Rotation2Dd turn(yaw);
  std::vector<Vec2> outline;
  for (const Vec2& v : robot.footprint) outline.push_back(Vec2(x, y) + turn * v);
  std::vector<Vec2> cell(4);
  // The cells within the circle around the footprint (its radius) and the clearance.
  return NoCellHits(x, y, robot.footprint_radius + clearance, [&](int ix, int iy) {
    const Vec2 lo = min_ + resolution_ * Vec2(ix, iy);
    cell = {lo, lo + Vec2(resolution_, 0), lo + Vec2(resolution_, resolution_),
            lo + Vec2(0, resolution_)};
    const double d = PolygonDistance(outline, cell);
    return clearance > 0.0 ? d < clearance : d == 0.0;
  });
}

Status OccupancyMap::SetCells(const std::vector<uint8_t>& cells) {
  if (cells.size() != occupied_.size()) {
    return InvalidArgumentError("occupancy: expected " + std::to_string(occupied_.size()) +
                                " cells, got " + std::to_string(cells.size()));
  }
  occupied_ = cells;
  return OkStatus();
}

World World::Make(RobotDescription robot, SearchParams params, std::vector<Box> furniture,
                  OccupancyMap occupancy, std::vector<BaseRegion> base_regions, GridWorld grid,
                  RobotConfig start) {
  World w;
  w.robot = std::move(robot);
  w.camera = w.robot.camera;
  w.params = params;
  w.furniture = std::move(furniture);
  w.occupancy = std::move(occupancy);
  w.base_regions = std::move(base_regions);
  w.grid = std::move(grid);
  w.robot_config = start;
  ObjectKnowledge guess;
  guess.key = "guessed-target";
  guess.box.size = Vec3::Constant(params.guess_size);
  guess.moveability = params.guess_moveability;
  guess.odds.fill(static_cast<float>(params.guess_odds));
  w.objects.push_back(guess);
  w.grid.RebuildSampler();
  return w;
}

Status World::Validate() const {
  if (Status s = params.Validate(); !s.ok()) return Status(s.code(), "params." + s.message());
  if (Status s = grid.Validate(); !s.ok()) return Status(s.code(), "workspaces: " + s.message());
  if (base_regions.empty()) return InvalidArgumentError("base_regions: at least one is needed");
  for (size_t i = 0; i < base_regions.size(); ++i) {
    const auto& r = base_regions[i];
    if (!r.min.allFinite() || !r.max.allFinite() || !(r.min.x() < r.max.x()) ||
        !(r.min.y() < r.max.y())) {
      return InvalidArgumentError("base_regions[" + std::to_string(i) +
                                  "]: min must be below max and finite");
    }
  }
  for (size_t i = 0; i < furniture.size(); ++i) {
    if (Status s = CheckBox(furniture[i], "furniture[" + std::to_string(i) + "]"); !s.ok()) {
      return s;
    }
  }
  if (objects.empty()) return InternalError("objects: the guessed target is missing");
  for (size_t i = 1; i < objects.size(); ++i) {
    if (Status s = CheckBox(objects[i].box, "objects[" + std::to_string(i) + "].box"); !s.ok()) {
      return s;
    }
  }
  if (objects.size() > kMaxObjects) {
    return InvalidArgumentError(TooManyObjects("objects"));
  }
  return OkStatus();
}

std::vector<Box> World::Occluders() const {
  std::vector<Box> out = furniture;
  for (size_t i = 1; i < objects.size(); ++i) {
    if (objects[i].status != kRemoved) out.push_back(objects[i].box);
  }
  return out;
}

bool World::BasePointAt(double pick, double u, double v, double* x, double* y) const {
  double total = 0.0;
  for (const BaseRegion& r : base_regions) total += (r.max - r.min).prod();
  if (!(total > 0.0)) return false;
  double left = pick * total;
  const BaseRegion* region = &base_regions.back();
  for (const BaseRegion& r : base_regions) {
    left -= (r.max - r.min).prod();
    if (left <= 0.0) {
      region = &r;
      break;
    }
  }
  *x = region->min.x() + (region->max.x() - region->min.x()) * u;
  *y = region->min.y() + (region->max.y() - region->min.y()) * v;
  return true;
}

bool World::BaseFeasible(double x, double y, double yaw) const {
  bool in_region = false;
  for (const BaseRegion& r : base_regions) in_region |= r.Contains(x, y);
  return in_region && occupancy.FootprintFree(robot, x, y, yaw, params.base_clearance);
}

bool World::BaseFeasible(double x, double y) const {
  if (robot.footprint.empty()) return BaseFeasible(x, y, 0.0);
  constexpr int kHeadings = 16;
  for (int k = 0; k < kHeadings; ++k) {
    if (BaseFeasible(x, y, 2.0 * std::numbers::pi * k / kHeadings)) return true;
  }
  return false;
}

int World::FindObject(const std::string& key) const {
  for (size_t i = 1; i < objects.size(); ++i) {
    if (objects[i].key == key) return static_cast<int>(i);
  }
  return -1;
}

std::vector<RobotConfig> World::ManualPoses() const {
  std::vector<RobotConfig> poses = discrete_poses;
  if (!poses.empty()) return poses;
  for (const BaseRegion& r : base_regions) {
    RobotConfig c;
    c.x = 0.5 * (r.min.x() + r.max.x());
    c.y = 0.5 * (r.min.y() + r.max.y());
    double best = 1e18;
    for (const Workspace& w : grid.workspaces()) {
      const double d = (w.center - Vec2(c.x, c.y)).squaredNorm();
      if (d < best) {
        best = d;
        c.yaw = std::atan2(w.center.y() - c.y, w.center.x() - c.x);
      }
    }
    poses.push_back(c);
  }
  return poses;
}

namespace {

// The distinct values of `values`, in their order.
std::vector<double> Distinct(std::initializer_list<double> values) {
  std::vector<double> out;
  for (double v : values) {
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  return out;
}

}  // namespace

std::vector<double> World::ManualLifts() const {
  return Distinct({robot.lift_min, 0.5 * (robot.lift_min + robot.lift_max), robot.lift_max});
}

std::vector<std::pair<double, double>> World::ManualHeads() const {
  const std::vector<double> pans =
      Distinct({robot.pan_min, 0.5 * (robot.pan_min + robot.pan_max), robot.pan_max});
  const std::vector<double> tilts = Distinct({0.0, 0.5 * robot.tilt_max, robot.tilt_max});
  std::vector<std::pair<double, double>> out;
  for (double pan : pans) {
    for (double tilt : tilts) out.emplace_back(pan, tilt);
  }
  return out;
}

std::vector<RobotConfig> World::ManualConfigurations() const {
  std::vector<RobotConfig> out;
  for (const RobotConfig& pose : ManualPoses()) {
    for (double lift : ManualLifts()) {
      for (const auto& [pan, tilt] : ManualHeads()) {
        RobotConfig c = pose;
        c.lift = lift;
        c.pan = pan;
        c.tilt = tilt;
        out.push_back(c);
      }
    }
  }
  return out;
}

std::vector<Workspace> PriorMap::Workspaces() const {
  std::vector<Workspace> out;
  for (const Furniture& f : furniture) {
    if (!f.workspace) continue;
    Workspace w;
    w.name = f.name;
    w.center = f.box.center.head<2>();
    w.yaw = f.box.yaw;
    w.length = f.box.size.x();
    w.width = f.box.size.y();
    w.height = f.box.size.z();
    out.push_back(w);
  }
  return out;
}

namespace {

// Whether some point of the base regions is feasible for the base (inside a region, its
// footprint and clearance free), by 4,096 draws spread over the regions by their areas, always
// the same ones: a world whose regions lie inside furniture leaves every planner proposing
// configurations the robot cannot take.
bool AnyBaseFeasible(const World& world) {
  std::mt19937_64 gen(20261127);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int i = 0; i < 4096; ++i) {
    const double pick = uniform(gen), u = uniform(gen), v = uniform(gen);
    double x = 0.0, y = 0.0;
    if (!world.BasePointAt(pick, u, v, &x, &y)) return false;
    if (world.BaseFeasible(x, y)) return true;
  }
  return false;
}

}  // namespace

std::vector<BaseRegion> BaseRegionsAround(const PriorMap& prior) {
  const double inner = prior.robot.footprint_radius + prior.params.base_clearance;
  const double outer = std::max(prior.robot.reach, inner + 0.3);
  std::vector<BaseRegion> out;
  for (const PriorMap::Furniture& f : prior.furniture) {
    if (!f.workspace) continue;
    Vec2 lo = Vec2::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Vec3& corner : f.box.Corners()) {
      lo = lo.cwiseMin(corner.head<2>());
      hi = hi.cwiseMax(corner.head<2>());
    }
    out.push_back({Vec2(lo.x() - outer, lo.y() - inner), Vec2(lo.x() - inner, hi.y() + inner)});
    out.push_back({Vec2(hi.x() + inner, lo.y() - inner), Vec2(hi.x() + outer, hi.y() + inner)});
    out.push_back({Vec2(lo.x() - inner, lo.y() - outer), Vec2(hi.x() + inner, lo.y() - inner)});
    out.push_back({Vec2(lo.x() - inner, hi.y() + inner), Vec2(hi.x() + inner, hi.y() + outer)});
  }
  return out;
}

StatusOr<World> BuildWorld(const PriorMap& prior) {
  RobotDescription robot = prior.robot;
  if (Status s = robot.Validate(); !s.ok()) {
    const auto& v = s.field_violations();
    return v.empty() ? InvalidFieldError("robot", s.message())
                     : InvalidFieldError("robot." + v[0].field, v[0].description);
  }
  OccupancyMap map(prior.room_min, prior.room_max, prior.map_resolution);
  if (!prior.occupied.empty()) {
    if (Status s = map.SetCells(prior.occupied); !s.ok()) {
      return InvalidFieldError("occupancyGrid", s.message());
    }
  }
  std::vector<Box> furniture;
  for (const PriorMap::Furniture& f : prior.furniture) {
    map.AddBox(f.box);
    furniture.push_back(f.box);
  }
  // The base stands in the room: each region is cut to it (a region kilometres wide made every
  // draw of a base pose fall outside), and one with no part in it is refused.
  const bool derived = prior.base_regions.empty();
  std::vector<BaseRegion> regions = derived ? BaseRegionsAround(prior) : prior.base_regions;
  if (derived) {  // the strips are cut to the room; those wholly outside it go
    std::erase_if(regions, [&](const BaseRegion& r) {
      return !(std::min(r.max.x(), map.max().x()) > std::max(r.min.x(), map.min().x()) &&
               std::min(r.max.y(), map.max().y()) > std::max(r.min.y(), map.min().y()));
    });
    if (regions.empty()) {
      return InvalidFieldError("baseRegions",
                               "needed: no region around the workspaces lies in the room (are the "
                               "workspaces inside the map?)");
    }
  }
  if (!map.cells().empty()) {
    for (size_t i = 0; i < regions.size(); ++i) {
      BaseRegion& r = regions[i];
      if (!r.min.allFinite() || !r.max.allFinite()) continue;  // Validate() names it
      r.min = r.min.cwiseMax(map.min());
      r.max = r.max.cwiseMin(map.max());
      if (!(r.min.x() < r.max.x() && r.min.y() < r.max.y())) {
        return InvalidFieldError("baseRegions[" + std::to_string(i) + "]", "lies outside the room");
      }
    }
  }
  World world =
      World::Make(std::move(robot), prior.params, std::move(furniture), std::move(map),
                  std::move(regions), GridWorld(prior.Workspaces(), kGridResolution), prior.start);
  world.discrete_poses = prior.discrete_poses;
  if (Status s = world.Validate(); !s.ok()) return s;
  if (!AnyBaseFeasible(world)) {
    char radius[32];
    std::snprintf(radius, sizeof radius, "%.2f",
                  world.robot.footprint_radius + world.params.base_clearance);
    return InvalidFieldError("baseRegions",
                             "no point of the base regions leaves the robot's footprint (" +
                                 std::string(radius) +
                                 " m with its clearance) free of the furniture and the walls");
  }
  // The start need not be in a base region, but the footprint must be free.
  if (!world.occupancy.FootprintFree(world.robot, prior.start.x, prior.start.y, prior.start.yaw,
                                     0.0)) {
    return InvalidFieldError("start", "the robot's footprint collides with the map");
  }
  return world;
}

Status ApplyDiscreteOutcome(World* world, int object, int kind_offset, bool success) {
  if (object <= 0 || object >= static_cast<int>(world->objects.size())) {
    return InvalidArgumentError("object " + std::to_string(object) + " does not exist");
  }
  if (kind_offset < 0 || kind_offset > kRemoveOffset) {
    return InvalidArgumentError("unknown discrete action offset " + std::to_string(kind_offset));
  }
  ObjectKnowledge& o = world->objects[object];
  if (!success) {
    if (kind_offset == kRemoveOffset) {
      o.removal_failed = true;
      o.moveability = 0.0;
    }
    return OkStatus();
  }
  o.status = StatusAfter(kind_offset);
  return OkStatus();
}

std::vector<int> SeenCorners(const Box& box, const CameraModel& camera, const CameraPose& pose,
                             const std::vector<Box>& occluders) {
  const auto corners = box.Corners();
  std::vector<int> out;
  for (int k : NearestCorners(corners, pose.position)) {
    const Vec3 p = corners[k] + 0.05 * (box.center - corners[k]);
    if (!InFrustum(camera, pose, p)) continue;
    const bool hidden = std::any_of(occluders.begin(), occluders.end(), [&](const Box& b) {
      return b.BlocksSegment(pose.position, p);
    });
    if (!hidden) out.push_back(k);
  }
  return out;
}

Status ApplyRealObservation(World* world, const RealObservation& observation) {
  const SearchParams& p = world->params;
  const RobotConfig& c = observation.achieved;
  if (!std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.yaw) ||
      !std::isfinite(c.lift) || !std::isfinite(c.pan) || !std::isfinite(c.tilt)) {
    return InvalidArgumentError("robot state: not finite");
  }
  for (size_t i = 0; i < observation.objects.size(); ++i) {
    const ObjectDetection& d = observation.objects[i];
    const std::string field = "objects[" + std::to_string(i) + "]";
    if (d.key.empty()) return InvalidArgumentError(field + ".id: empty");
    if (Status s = CheckBox(d.box, field); !s.ok()) return s;
    if (!(d.moveability >= 0.0 && d.moveability <= 1.0)) {
      return InvalidArgumentError(field + ".moveability: must be in [0, 1]");
    }
    if (!std::isnan(d.score)) {
      if (!(d.score >= 0.0 && d.score <= 1.0)) {
        return InvalidArgumentError(field + ".score: must be in [0, 1]");
      }
      if (!d.faces.empty()) {
        return InvalidArgumentError(field + ".score: give per-face scores or one score, not both");
      }
    }
    for (size_t k = 0; k < d.faces.size(); ++k) {
      const FaceDetection& f = d.faces[k];
      if (f.corner < 0 || f.corner > 7) {
        return InvalidArgumentError(field + ".faces[" + std::to_string(k) +
                                    "].corner: must be in [0, 7]");
      }
      if (!(f.score >= 0.0 && f.score <= 1.0)) {
        return InvalidArgumentError(field + ".faces[" + std::to_string(k) +
                                    "].score: must be in [0, 1]");
      }
    }
    if (world->FindObject(d.key) < 0 && world->objects.size() >= kMaxObjects) {
      return ResourceExhaustedError(TooManyObjects(field));
    }
  }
  // Everything is valid: apply.
  world->robot_config = c;
  world->robot_config.yaw = WrapAngle(c.yaw);
  const CameraPose pose = CameraPoseFor(world->robot, world->robot_config);
  for (size_t i = 0; i < observation.objects.size(); ++i) {
    const ObjectDetection& d = observation.objects[i];
    std::vector<FaceDetection> whole;  // a score for the whole object: the faces seen get it
    if (!std::isnan(d.score)) {
      std::vector<Box> occluders = world->furniture;
      for (size_t j = 0; j < observation.objects.size(); ++j) {
        if (j != i) occluders.push_back(observation.objects[j].box);
      }
      for (int k : SeenCorners(d.box, world->camera, pose, occluders)) {
        whole.push_back({k, d.score});
      }
    }
    int index = world->FindObject(d.key);
    if (index < 0) {
      ObjectKnowledge o;
      o.key = d.key;
      world->objects.push_back(o);
      index = static_cast<int>(world->objects.size()) - 1;
    }
    ObjectKnowledge& o = world->objects[index];
    o.box = d.box;
    o.moveability = o.removal_failed ? 0.0 : d.moveability;
    for (const FaceDetection& f : whole.empty() ? d.faces : whole) {
      const double q = std::clamp(f.score, 1e-6, 1.0 - 1e-6);
      const double step =
          std::clamp(std::log(q / (1.0 - q)), -p.detection_max_step, p.detection_max_step);
      o.odds[f.corner] = static_cast<float>(
          std::clamp(o.odds[f.corner] + step, -p.face_odds_limit, p.face_odds_limit));
    }
  }
  world->grid.UpdateFromView(world->camera, pose, world->Occluders(), 0.5 * p.guess_size,
                             static_cast<float>(p.grid_free_delta), static_cast<float>(p.grid_min),
                             static_cast<float>(p.grid_max));
  ++world->steps;
  return OkStatus();
}

}  // namespace npfkct::object_search
