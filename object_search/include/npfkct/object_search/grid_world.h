// The workspace grid world G_f of the guessed target (paper section 3 and appendix A): log-odds
// cells over every workspace surface, sampled to place the guessed target, updated after each
// real step by what the camera saw.
#pragma once

#include <string>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/common/status.h"
#include "npfkct/object_search/geometry.h"

namespace npfkct::object_search {

/// A horizontal rectangular surface where objects may stand (a table top, a shelf board).
struct Workspace {
  std::string name;
  Vec2 center = Vec2::Zero();
  double yaw = 0.0;
  double length = 1.0;   ///< Extent along the workspace's x axis.
  double width = 1.0;    ///< Extent along its y axis.
  double height = 0.75;  ///< Height of the surface above the floor.

  /// Whether the (x, y) point lies on the surface (with `margin` added to every side).
  bool ContainsXY(const Vec2& p, double margin = 0.0) const;
};

/// How a cell's log-odds l becomes its weight when the guessed target is placed.
enum class GridSampling {
  kProbability,  ///< sigmoid(l): a cell never weighs more than twice an unseen one.
  kOdds,         ///< exp(l), the paper's rule (appendix A): in proportion to the odds.
};

/// Log-odds cells over all workspaces.
class GridWorld {
 public:
  GridWorld() = default;
  /// Cells of `resolution` metres over every workspace, each starting at `prior_log_odds`.
  GridWorld(std::vector<Workspace> workspaces, double resolution = 0.02,
            float prior_log_odds = 0.0f);

  /// Checks the workspaces and the resolution.
  Status Validate() const;

  const std::vector<Workspace>& workspaces() const { return workspaces_; }
  double resolution() const { return resolution_; }
  int num_cells() const { return static_cast<int>(log_odds_.size()); }
  /// Cells along the x and y axes of workspace w.
  int cells_x(int w) const { return dims_[w].first; }
  int cells_y(int w) const { return dims_[w].second; }
  /// The flat index of cell (ix, iy) of workspace w.
  int Index(int w, int ix, int iy) const { return offsets_[w] + iy * dims_[w].first + ix; }
  /// The workspace of a flat cell index.
  int WorkspaceOf(int cell) const;
  /// The point at the center of a cell, `lift` metres above the surface.
  Vec3 CellCenter(int cell, double lift = 0.0) const;
  float log_odds(int cell) const { return log_odds_[cell]; }
  void set_log_odds(int cell, float value);
  const std::vector<float>& all_log_odds() const { return log_odds_; }
  /// Replaces every cell value (sizes must match).
  Status SetAllLogOdds(const std::vector<float>& values);

  /// Recomputes the sampling distribution after the odds changed: P(cell) proportional to the
  /// weight sampling() gives its log-odds.
  void RebuildSampler();
  /// Sets the rule of the sampling distribution (default kProbability) and rebuilds it.
  void SetSampling(GridSampling sampling);
  GridSampling sampling() const { return sampling_; }
  /// A target position: a cell drawn from the sampling distribution, a point uniform inside it,
  /// `lift` metres above the surface. Requires RebuildSampler() after the last change.
  Vec3 Sample(Rng& rng, double lift) const;
  /// Probability mass of each workspace under the sampling distribution.
  std::vector<double> WorkspaceMass() const;

  /// The real-step update: every cell whose target-center point (`lift` above the surface) is
  /// inside the frustum and not hidden behind `occluders` moves by `free_delta` (negative: the
  /// target is not there), clamped to [min, max]; occluded cells keep their value. Returns the
  /// number of updated cells and rebuilds the sampler.
  int UpdateFromView(const CameraModel& camera, const CameraPose& pose,
                     const std::vector<Box>& occluders, double lift, float free_delta,
                     float min_log_odds, float max_log_odds);

 private:
  std::vector<Workspace> workspaces_;
  double resolution_ = 0.02;
  std::vector<std::pair<int, int>> dims_;
  std::vector<int> offsets_;
  std::vector<float> log_odds_;
  std::vector<double> cumulative_;
  GridSampling sampling_ = GridSampling::kProbability;
};

}  // namespace npfkct::object_search
