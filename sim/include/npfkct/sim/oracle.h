// The oracle: the ceiling of a scene in the benchmark. It is told the true world (every object's
// box, which one is the target, which can be moved) and plans the shortest legal action sequence
// by the simulator's own observation rule.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <vector>

#include "npfkct/object_search/planner_registry.h"
#include "npfkct/object_search/world.h"
#include "npfkct/sim/simulator.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::sim {

/// Settings of the oracle's candidate views.
struct OracleOptions {
  /// Spacing of the grid of base positions laid over every base region (m).
  double base_spacing = 0.08;
  /// Lift heights tried at every base position (between the robot's limits, both included).
  int lifts = 3;
  /// Head pans tried (between the limits, both included); every view's yaw aims the camera at
  /// the object it wants to see, so pan only matters near the joint limits.
  int pans = 3;
  /// Not told which object covers the target: when no view can see an unconfirmed face grid of
  /// the target, clear the movable object of the largest footprint instead of the one whose
  /// removal exposes the most (a ceiling told the layout, not the target's box).
  bool cover_unknown = false;
};

/// The oracle planner. Each step it looks at the robot's knowledge (what has been seen, which face
/// grids are confirmed) and the truth, and takes the action that finishes the search soonest:
/// remove the declared target; declare the target once n_odds of its face grids are confirmed;
/// otherwise the view that confirms the most target face grids, chosen with a two-view lookahead
/// so that the fewest views reach n_odds. When no view can see an unconfirmed face grid of the
/// target, it finds the movable object whose removal would expose the most (the cover of a
/// covered target), looks at it until it can be declared an obstacle, declares and removes it;
/// when no single removal exposes the target (stacked covers, a cage), the fewest nearby objects
/// whose removal together does, from the outside in. A view that confirmed none of the face
/// grids it was planned for (a slot narrower than the pose noise) is not planned again. It
/// replans after every step from what the robot actually observed, so pose noise
/// and false detections cost it steps as they cost any planner; it is a ceiling, not an exact
/// optimum. Next() keeps what the last steps did: one oracle per trial.
class Oracle {
 public:
  /// An oracle for `simulator`'s scene (which must outlive it).
  explicit Oracle(const Simulator& simulator, OracleOptions options = {});

  /// The next action given the robot's knowledge. Objects of the knowledge are matched to scene
  /// objects by key (the geometric observation's detection ids are the scene object names).
  HybridAction Next(const object_search::World& knowledge) const;

  /// The face grids (bit k: corner k) of scene object `object` that some candidate view sees,
  /// with the objects whose bit is set in `ignore` treated as gone.
  uint32_t SeeableCorners(int object, uint64_t ignore = 0) const;

  /// The candidate base positions (x, y) the oracle considers.
  const std::vector<object_search::Vec2>& bases() const { return bases_; }

 private:
  // The candidate views aimed at scene object `object` (computed once per object).
  const std::vector<object_search::RobotConfig>& ViewsOf(int object) const;
  // The best view to confirm face grids of scene object `object` (whose knowledge odds are
  // `odds`, sign +1 for the target, -1 for an obstacle), treating objects in `ignore` as gone;
  // false when no view sees an unconfirmed face grid.
  bool BestView(int object, const std::array<float, 8>& odds, double sign, int needed,
                uint64_t ignore, object_search::RobotConfig* best) const;

  const Simulator& sim_;
  OracleOptions options_;
  std::vector<object_search::Vec2> bases_;
  mutable std::map<int, std::vector<object_search::RobotConfig>> views_;
  // Whether `c` is (within the pose noise of) a view that confirmed nothing.
  bool Failed(const object_search::RobotConfig& c) const;

  // What the last step planned (Next is called once per step of one trial): the view, the object
  // and direction it was to confirm, and how many face grids were confirmed before; and the
  // views that confirmed nothing.
  struct Planned {
    int object = -1;
    double sign = 1.0;
    int confirmed = 0;
    object_search::RobotConfig view;
  };
  mutable Planned last_;
  mutable std::vector<object_search::RobotConfig> failed_views_;
};

/// Steps the oracle takes to remove the target in `scenario` with the simulator seeded by `seed`
/// (the bench's episode: a first look, then the oracle's action, its execution and observation
/// each step), or -1 when it has not within `max_steps`.
int OracleEpisodeSteps(const Scenario& scenario, uint64_t seed, int max_steps);

/// The true scene of a benchmark trial, for the planners that are told it (the oracles).
class SceneTruth final : public object_search::Truth {
 public:
  /// The scene of `simulator` (which must outlive it).
  explicit SceneTruth(const Simulator& simulator) : simulator_(simulator) {}
  const Simulator& simulator() const { return simulator_; }

 private:
  const Simulator& simulator_;
};

/// Gives the registry's oracles their factory ("oracle"; "oracle-cover-unknown" with
/// cover_unknown): an Oracle of the SceneTruth that PlannerArgs::truth carries, behind the
/// SearchPlanner interface (each Plan() is Next() on the model's World, the robot's knowledge;
/// planner options are ignored).
Status AddOracleFactories(object_search::PlannerRegistry* registry);

}  // namespace npfkct::sim
