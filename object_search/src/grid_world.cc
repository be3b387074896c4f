#include "npfkct/object_search/grid_world.h"

#include <algorithm>
#include <cmath>

namespace npfkct::object_search {

bool Workspace::ContainsXY(const Vec2& p, double margin) const {
  const Vec2 d = p - center;
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double lx = c * d.x() + s * d.y();
  const double ly = -s * d.x() + c * d.y();
  return std::abs(lx) <= 0.5 * length + margin && std::abs(ly) <= 0.5 * width + margin;
}

GridWorld::GridWorld(std::vector<Workspace> workspaces, double resolution, float prior_log_odds)
    : workspaces_(std::move(workspaces)), resolution_(resolution) {
  int offset = 0;
  for (const Workspace& w : workspaces_) {
    const int nx = std::max(1, static_cast<int>(std::ceil(w.length / resolution_ - 1e-9)));
    const int ny = std::max(1, static_cast<int>(std::ceil(w.width / resolution_ - 1e-9)));
    dims_.emplace_back(nx, ny);
    offsets_.push_back(offset);
    offset += nx * ny;
  }
  log_odds_.assign(offset, prior_log_odds);
  RebuildSampler();
}

Status GridWorld::Validate() const {
  if (!(resolution_ > 0.0) || !std::isfinite(resolution_)) {
    return InvalidArgumentError("grid resolution must be > 0");
  }
  if (workspaces_.empty()) return InvalidArgumentError("at least one workspace is needed");
  for (size_t i = 0; i < workspaces_.size(); ++i) {
    const Workspace& w = workspaces_[i];
    if (!(w.length > 0.0) || !(w.width > 0.0) || !std::isfinite(w.length) ||
        !std::isfinite(w.width)) {
      return InvalidArgumentError("workspaces[" + std::to_string(i) + "]: size must be > 0");
    }
    if (!std::isfinite(w.height) || !w.center.allFinite() || !std::isfinite(w.yaw)) {
      return InvalidArgumentError("workspaces[" + std::to_string(i) + "]: not finite");
    }
  }
  if (log_odds_.size() > 5'000'000) {
    return InvalidArgumentError("grid world too large: more than 5e6 cells");
  }
  return OkStatus();
}

int GridWorld::WorkspaceOf(int cell) const {
  const auto it = std::upper_bound(offsets_.begin(), offsets_.end(), cell);
  return static_cast<int>(it - offsets_.begin()) - 1;
}

Vec3 GridWorld::CellCenter(int cell, double lift) const {
  const int w = WorkspaceOf(cell);
  const int local = cell - offsets_[w];
  const int ix = local % dims_[w].first;
  const int iy = local / dims_[w].first;
  const Workspace& ws = workspaces_[w];
  const double lx = -0.5 * ws.length + (ix + 0.5) * ws.length / dims_[w].first;
  const double ly = -0.5 * ws.width + (iy + 0.5) * ws.width / dims_[w].second;
  const double c = std::cos(ws.yaw), s = std::sin(ws.yaw);
  return Vec3(ws.center.x() + c * lx - s * ly, ws.center.y() + s * lx + c * ly, ws.height + lift);
}

void GridWorld::set_log_odds(int cell, float value) { log_odds_[cell] = value; }

Status GridWorld::SetAllLogOdds(const std::vector<float>& values) {
  if (values.size() != log_odds_.size()) {
    return InvalidArgumentError("grid log-odds: expected " + std::to_string(log_odds_.size()) +
                                " cells, got " + std::to_string(values.size()));
  }
  for (size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i])) {
      return InvalidArgumentError("grid log-odds[" + std::to_string(i) + "] is not finite");
    }
  }
  log_odds_ = values;
  RebuildSampler();
  return OkStatus();
}

void GridWorld::RebuildSampler() {
  cumulative_.resize(log_odds_.size());
  double total = 0.0;
  for (size_t i = 0; i < log_odds_.size(); ++i) {
    const double l = static_cast<double>(log_odds_[i]);
    total += sampling_ == GridSampling::kOdds ? std::exp(l) : 1.0 / (1.0 + std::exp(-l));
    cumulative_[i] = total;
  }
}

void GridWorld::SetSampling(GridSampling sampling) {
  sampling_ = sampling;
  RebuildSampler();
}

Vec3 GridWorld::Sample(Rng& rng, double lift) const {
  const double u = rng.Uniform() * cumulative_.back();
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), u);
  const int cell = std::min(static_cast<int>(it - cumulative_.begin()), num_cells() - 1);
  const int w = WorkspaceOf(cell);
  const Workspace& ws = workspaces_[w];
  const double cx = ws.length / dims_[w].first, cy = ws.width / dims_[w].second;
  const double c = std::cos(ws.yaw), s = std::sin(ws.yaw);
  const double dx = rng.Uniform(-0.5, 0.5) * cx, dy = rng.Uniform(-0.5, 0.5) * cy;
  return CellCenter(cell, lift) + Vec3(c * dx - s * dy, s * dx + c * dy, 0.0);
}

std::vector<double> GridWorld::WorkspaceMass() const {
  std::vector<double> mass(workspaces_.size(), 0.0);
  double previous = 0.0;
  for (int i = 0; i < num_cells(); ++i) {
    mass[WorkspaceOf(i)] += cumulative_[i] - previous;
    previous = cumulative_[i];
  }
  const double total = cumulative_.empty() ? 0.0 : cumulative_.back();
  if (total > 0) {
    for (double& m : mass) m /= total;
  }
  return mass;
}

int GridWorld::UpdateFromView(const CameraModel& camera, const CameraPose& pose,
                              const std::vector<Box>& occluders, double lift, float free_delta,
                              float min_log_odds, float max_log_odds) {
  int updated = 0;
  const std::vector<BoxFrame> frames(occluders.begin(), occluders.end());
  const double tan_half_horizontal = camera.TanHalfHorizontal();
  for (int cell = 0; cell < num_cells(); ++cell) {
    const Vec3 p = CellCenter(cell, lift);
    if (!InFrustum(camera, pose, p, tan_half_horizontal)) continue;
    bool hidden = false;
    for (const BoxFrame& b : frames) {
      if (b.Contains(p) || b.BlocksSegment(pose.position, p)) {
        hidden = true;
        break;
      }
    }
    if (hidden) continue;
    log_odds_[cell] = std::clamp(log_odds_[cell] + free_delta, min_log_odds, max_log_odds);
    ++updated;
  }
  RebuildSampler();
  return updated;
}

}  // namespace npfkct::object_search
