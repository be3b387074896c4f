#include "npfkct/sim/oracle.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <utility>

#include "npfkct/object_search/model.h"

namespace npfkct::sim {
namespace {

using object_search::ObjectSearchModel;
using object_search::RobotConfig;
using object_search::Vec2;
using object_search::Vec3;

// Face grids of `odds` past the threshold in the direction `sign` (+1 target, -1 obstacle).
uint32_t ConfirmedMask(const std::array<float, 8>& odds, double sign, double threshold) {
  uint32_t mask = 0;
  for (int k = 0; k < 8; ++k) {
    if (sign * odds[k] > threshold) mask |= 1u << k;
  }
  return mask;
}

HybridAction Move(const RobotConfig& c) {
  HybridAction a;
  a.kind = object_search::kMoveKind;
  a.x = ObjectSearchModel::VecOf(c);
  return a;
}

HybridAction OnObject(int object, int offset) {
  HybridAction a;
  a.kind = object_search::ObjectKind(object, offset);
  return a;
}

}  // namespace

Oracle::Oracle(const Simulator& simulator, OracleOptions options)
    : sim_(simulator), options_(options) {
  auto world = simulator.InitialWorld();
  if (!world.ok()) return;
  for (const object_search::BaseRegion& r : world->base_regions) {
    const double s = options_.base_spacing;
    for (double x = r.min.x() + 0.5 * s; x <= r.max.x(); x += s) {
      for (double y = r.min.y() + 0.5 * s; y <= r.max.y(); y += s) {
        // The reasonability check keeps a clearance beyond the footprint, so that the pose noise
        // of a move cannot push the base into the map (the robot would then stay where it was).
        if (world->BaseFeasible(x, y)) {
          bases_.push_back(Vec2(x, y));
        }
      }
    }
  }
}

const std::vector<RobotConfig>& Oracle::ViewsOf(int object) const {
  auto cached = views_.find(object);
  if (cached != views_.end()) return cached->second;
  const object_search::RobotDescription& preset = sim_.scenario().robot;
  const Vec3 aim = sim_.objects()[object].box.center;
  std::vector<RobotConfig> views;
  const int lifts = std::max(1, options_.lifts), pans = std::max(1, options_.pans);
  for (const Vec2& b : bases_) {
    for (int li = 0; li < lifts; ++li) {
      const double lift =
          lifts == 1 ? preset.lift_min
                     : preset.lift_min + (preset.lift_max - preset.lift_min) * li / (lifts - 1);
      for (int pi = 0; pi < pans; ++pi) {
        const double pan =
            pans == 1 ? 0.0 : preset.pan_min + (preset.pan_max - preset.pan_min) * pi / (pans - 1);
        RobotConfig c;
        c.x = b.x();
        c.y = b.y();
        c.lift = lift;
        c.pan = pan;
        // Aim the optical axis at the object: the camera sits ahead of the base center, so the
        // heading is refined once from the camera's position.
        double heading = std::atan2(aim.y() - b.y(), aim.x() - b.x());
        for (int it = 0; it < 2; ++it) {
          c.yaw = object_search::WrapAngle(heading - pan);
          c.tilt = 0.0;
          const Vec3 cam = object_search::CameraPoseFor(preset, c).position;
          heading = std::atan2(aim.y() - cam.y(), aim.x() - cam.x());
          const double horizontal = std::hypot(aim.x() - cam.x(), aim.y() - cam.y());
          c.tilt = std::clamp(std::atan2(cam.z() - aim.z(), horizontal), preset.tilt_min,
                              preset.tilt_max);
        }
        c.yaw = object_search::WrapAngle(heading - pan);
        views.push_back(c);
      }
    }
  }
  return views_[object] = std::move(views);
}

bool Oracle::Failed(const RobotConfig& c) const {
  for (const RobotConfig& f : failed_views_) {
    if (std::hypot(c.x - f.x, c.y - f.y) < 0.05 &&
        std::abs(object_search::WrapAngle(c.yaw - f.yaw)) < 0.1 &&
        std::abs(c.lift - f.lift) < 0.05 && std::abs(c.pan - f.pan) < 0.05) {
      return true;
    }
  }
  return false;
}

uint32_t Oracle::SeeableCorners(int object, uint64_t ignore) const {
  uint32_t seen = 0;
  for (const RobotConfig& c : ViewsOf(object)) {
    for (int k : sim_.VisibleCorners(object, c, ignore)) {
      if (k >= 0) seen |= 1u << k;
    }
  }
  return seen;
}

bool Oracle::BestView(int object, const std::array<float, 8>& odds, double sign, int needed,
                      uint64_t ignore, RobotConfig* best) const {
  const double threshold = sim_.scenario().params.declare_threshold;
  const uint32_t confirmed = ConfirmedMask(odds, sign, threshold);
  const std::vector<RobotConfig>& views = ViewsOf(object);
  // The unconfirmed face grids each view would see.
  std::vector<uint32_t> gain(views.size(), 0);
  std::array<bool, 256> present{};
  for (size_t v = 0; v < views.size(); ++v) {
    if (Failed(views[v])) continue;
    uint32_t seen = 0;
    for (int k : sim_.VisibleCorners(object, views[v], ignore)) {
      if (k >= 0) seen |= 1u << k;
    }
    gain[v] = seen & ~confirmed;
    present[gain[v]] = true;
  }
  needed = std::max(needed, 1);
  // Views needed to reach `needed` new face grids starting with a view of gain mask m: 1, 2 (with
  // the best partner) or 3 and more; and the face grids the pair covers.
  struct Score {
    int views = 99;
    int covered = 0;
  };
  std::array<Score, 256> score;
  for (uint32_t m = 1; m < 256; ++m) {
    if (!present[m]) continue;
    Score& s = score[m];
    s.covered = std::popcount(m);
    s.views = s.covered >= needed ? 1 : 3;
    if (s.views == 1) continue;
    for (uint32_t w = 1; w < 256; ++w) {
      if (!present[w]) continue;
      const int both = std::popcount(m | w);
      if (both >= needed) s.views = 2;
      s.covered = std::max(s.covered, std::min(both, needed));
    }
  }
  auto better = [&](uint32_t a, uint32_t b) {
    if (score[a].views != score[b].views) return score[a].views < score[b].views;
    if (score[a].covered != score[b].covered) return score[a].covered > score[b].covered;
    return std::popcount(a) > std::popcount(b);
  };
  uint32_t best_mask = 0;
  for (uint32_t m = 1; m < 256; ++m) {
    if (present[m] && (best_mask == 0 || better(m, best_mask))) best_mask = m;
  }
  if (best_mask == 0) return false;
  // Among the views with that mask, the one whose view survives the move's pose noise best: the
  // same face grids seen from the four perturbed poses.
  const double dxy = std::max(0.02, sim_.scenario().noise.pose_xy);
  const double dyaw = std::max(0.02, sim_.scenario().noise.pose_yaw);
  int chosen = -1, chosen_robust = -1, checked = 0;
  for (size_t v = 0; v < views.size() && checked < 24; ++v) {
    if (gain[v] != best_mask) continue;
    ++checked;
    int robust = 0;
    for (int d = 0; d < 4; ++d) {
      RobotConfig c = views[v];
      c.x += (d == 0 ? dxy : d == 1 ? -dxy : 0.0);
      c.y += (d == 2 ? dxy : d == 3 ? -dxy : 0.0);
      c.yaw += (d % 2 == 0 ? dyaw : -dyaw);
      uint32_t seen = 0;
      for (int k : sim_.VisibleCorners(object, c, ignore)) {
        if (k >= 0) seen |= 1u << k;
      }
      robust += (seen & best_mask) == best_mask;
    }
    if (robust > chosen_robust) {
      chosen_robust = robust;
      chosen = static_cast<int>(v);
    }
  }
  *best = views[chosen];
  return true;
}

// Kept in one piece (115 lines): its numbered parts are the four rules of the oracle's policy in
// the class comment, read top to bottom in the order they apply.
HybridAction Oracle::Next(const object_search::World& knowledge) const {
  const object_search::SearchParams& p = knowledge.params;
  const auto& scene = sim_.objects();
  const int target = sim_.target_index();
  auto known = [&](int scene_index) { return knowledge.FindObject(scene[scene_index].name); };
  auto count = [&](const std::array<float, 8>& odds, double sign) {
    return std::popcount(ConfirmedMask(odds, sign, p.declare_threshold));
  };
  // 1. Finish what is ready: remove what was declared, declare what can be.
  for (size_t i = 1; i < knowledge.objects.size(); ++i) {
    const object_search::ObjectKnowledge& o = knowledge.objects[i];
    if (o.status == object_search::kDeclaredTarget) {
      return OnObject(static_cast<int>(i), object_search::kRemoveOffset);
    }
  }
  for (size_t i = 1; i < knowledge.objects.size(); ++i) {
    if (knowledge.objects[i].status == object_search::kDeclaredObstacle) {
      return OnObject(static_cast<int>(i), object_search::kRemoveOffset);
    }
  }
  std::array<float, 8> target_odds{};
  const int kt = known(target);
  if (kt > 0) {
    const object_search::ObjectKnowledge& o = knowledge.objects[kt];
    target_odds = o.odds;
    if (o.status == object_search::kUpdating && count(o.odds, +1) >= p.n_odds) {
      return OnObject(kt, object_search::kDeclareTargetOffset);
    }
  }
  // A view planned last step that confirmed none of the face grids it was for (a slot narrower
  // than the pose noise, faces hidden after all) is not planned again.
  if (last_.object >= 0) {
    const int k = known(last_.object);
    const int now = k > 0 ? count(knowledge.objects[k].odds, last_.sign) : 0;
    if (now <= last_.confirmed) failed_views_.push_back(last_.view);
    last_.object = -1;
  }
  auto planned = [&](int object, double sign, const std::array<float, 8>& odds,
                     const RobotConfig& v) {
    last_ = {object, sign, count(odds, sign), v};
    return Move(v);
  };
  // 2. Look at the target.
  RobotConfig view;
  if (BestView(target, target_odds, +1, p.n_odds - count(target_odds, +1), 0, &view)) {
    return planned(target, +1, target_odds, view);
  }
  // 3. Nothing more of the target can be seen: clear the object whose removal exposes the most
  // (not told the cover: the movable object of the largest footprint).
  int blocker = -1;
  const int considered = std::min(static_cast<int>(scene.size()), 64);
  auto movable = [&](int b) { return b != target && !sim_.removed(b) && scene[b].moveable; };
  // Only what stands near the target can hide it.
  auto distance_to_target = [&](int b) {
    const Vec3 d = scene[b].box.center - scene[target].box.center;
    return std::hypot(d.x(), d.y());
  };
  // Face grids of `object` not in `confirmed` that some view would see once b is gone.
  auto exposed_without = [&](int object, uint32_t confirmed, int b) {
    return std::popcount(SeeableCorners(object, uint64_t{1} << b) & ~confirmed);
  };
  const uint32_t target_confirmed = ConfirmedMask(target_odds, +1, p.declare_threshold);
  if (options_.cover_unknown) {
    double largest = 0.0;
    for (int b = 0; b < considered; ++b) {
      if (!movable(b)) continue;
      const double area = scene[b].box.size.x() * scene[b].box.size.y();
      if (area > largest) {
        largest = area;
        blocker = b;
      }
    }
  } else {
    int best_exposed = 0;
    for (int b = 0; b < considered; ++b) {
      if (!movable(b) || distance_to_target(b) > 0.8) continue;
      const int n = exposed_without(target, target_confirmed, b);
      if (n > best_exposed) {
        best_exposed = n;
        blocker = b;
      }
    }
  }
  // Declares object b as an obstacle if it can be, else moves to see more of it; false if no
  // view sees a face grid of it not yet confirmed.
  HybridAction action;
  auto clear = [&](int b) {
    std::array<float, 8> odds{};
    const int kb = known(b);
    if (kb > 0) {
      odds = knowledge.objects[kb].odds;
      if (knowledge.objects[kb].status == object_search::kUpdating && count(odds, -1) >= p.n_odds) {
        action = OnObject(kb, object_search::kDeclareObstacleOffset);
        return true;
      }
    }
    if (!BestView(b, odds, -1, p.n_odds - count(odds, -1), 0, &view)) return false;
    action = planned(b, -1, odds, view);
    return true;
  };
  // No single removal shows the target (stacked covers, a cage): the fewest nearby movable
  // objects whose removal together does, dropping the farthest first; cleared from the outside
  // in (the first of them whose faces can be confirmed).
  if (blocker < 0 && !options_.cover_unknown) {
    std::vector<int> around;
    uint64_t gone = 0;
    for (int b = 0; b < considered; ++b) {
      if (movable(b) && distance_to_target(b) <= 0.8) {
        around.push_back(b);
        gone |= uint64_t{1} << b;
      }
    }
    auto exposed = [&](uint64_t mask) {
      return std::popcount(SeeableCorners(target, mask) & ~target_confirmed);
    };
    if (exposed(gone) > 0) {
      std::sort(around.begin(), around.end(),
                [&](int a, int b) { return distance_to_target(a) > distance_to_target(b); });
      std::vector<int> needed;
      for (int b : around) {
        if (exposed(gone & ~(uint64_t{1} << b)) > 0) {
          gone &= ~(uint64_t{1} << b);
        } else {
          needed.push_back(b);
        }
      }
      for (auto it = needed.rbegin(); it != needed.rend(); ++it) {
        if (clear(*it)) return action;
      }
    }
  }
  if (blocker >= 0) {
    if (clear(blocker)) return action;
    // Other objects hide the faces of the blocker still to be confirmed (a wall wedged between
    // two others): clear a nearby object, those whose removal exposes the most of the target's
    // and the blocker's unconfirmed faces first, then the nearest. Each step either confirms a
    // face grid or declares or removes an object, so this cannot repeat a useless view.
    const int kb = known(blocker);
    const uint32_t blocker_confirmed =
        kb > 0 ? ConfirmedMask(knowledge.objects[kb].odds, -1, p.declare_threshold) : 0;
    std::vector<std::pair<double, int>> order;  // (-exposed + distance / 10, object)
    for (int b = 0; b < considered; ++b) {
      if (b == blocker || !movable(b)) continue;
      const double distance = distance_to_target(b);
      if (distance > 0.8) continue;
      const int exposed = exposed_without(target, target_confirmed, b) +
                          exposed_without(blocker, blocker_confirmed, b);
      order.emplace_back(-exposed + 0.1 * distance, b);
    }
    std::sort(order.begin(), order.end());
    for (const auto& [unused, b] : order) {
      if (clear(b)) return action;
    }
  }
  // 4. Nothing helps (an unsolvable scene): keep looking at the target from its best view.
  std::array<float, 8> none{};
  if (BestView(target, none, +1, 1, 0, &view)) return Move(view);
  return Move(knowledge.robot_config);
}

int OracleEpisodeSteps(const Scenario& scenario, uint64_t seed, int max_steps) {
  Simulator simulator(scenario, seed);
  auto initial = simulator.InitialWorld();
  if (!initial.ok()) return -1;
  object_search::World world = *initial;
  Rng rng(seed * 104729 + 3);
  if (!object_search::ApplyRealObservation(&world, simulator.Observe(rng)).ok()) return -1;
  const Oracle oracle(simulator);
  for (int t = 1; t <= max_steps; ++t) {
    const HybridAction a = oracle.Next(world);
    const ExecutionOutcome outcome = simulator.Execute(a, world, rng);
    if (outcome.terminal) return t;
    if (a.kind != object_search::kMoveKind && outcome.success) {
      (void)object_search::ApplyDiscreteOutcome(&world, object_search::KindObject(a.kind),
                                                object_search::KindOffset(a.kind), true);
    }
    if (!object_search::ApplyRealObservation(&world, simulator.Observe(rng)).ok()) return -1;
  }
  return -1;
}

namespace {

// The oracle behind the SearchPlanner interface: no belief, no tree; each Plan() asks it for the
// next action given the model's World (the robot's knowledge).
class OraclePlanner final : public object_search::SearchPlanner {
 public:
  OraclePlanner(std::string name, const object_search::ObjectSearchModel& model,
                const Simulator& simulator, OracleOptions options)
      : name_(std::move(name)), model_(model), oracle_(simulator, options), options_(options) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<object_search::State>) override {}
  using SearchPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng&) override {
    Decision<HybridAction> d;
    d.action = oracle_.Next(model_.world());
    d.stats.simulations = 0;
    d.stats.elapsed_ms = stop.ElapsedMs();
    d.stats.cpu_ms = stop.CpuMs();
    return d;
  }
  void AdvanceTo(const HybridAction&, const object_search::Observation&,
                 ParticleBelief<object_search::State>) override {}
  void DropTree() override {}
  int64_t TreeSize() const override { return 0; }
  bool ReusesTree() const override { return false; }
  object_search::OptionList OptionsUsed() const override {
    return {{"base_spacing", options_.base_spacing},
            {"cover_unknown", options_.cover_unknown ? 1.0 : 0.0},
            {"lifts", static_cast<double>(options_.lifts)},
            {"pans", static_cast<double>(options_.pans)}};
  }

 private:
  std::string name_;
  const object_search::ObjectSearchModel& model_;
  Oracle oracle_;
  OracleOptions options_;
};

}  // namespace

Status AddOracleFactories(object_search::PlannerRegistry* registry) {
  for (const char* name : {"oracle", "oracle-cover-unknown"}) {
    const std::string n = name;
    Status s = registry->SetFactory(
        n,
        [n](const object_search::PlannerArgs& args)
            -> StatusOr<std::unique_ptr<object_search::SearchPlanner>> {
          const auto* truth = dynamic_cast<const SceneTruth*>(args.truth);
          if (truth == nullptr) {
            return InvalidArgumentError("planner '" + n + "' must be told the scene's truth");
          }
          // Planner options are the searches' (a run of several planners gives them to each);
          // the oracle searches nothing and reads none.
          OracleOptions options;
          options.cover_unknown = n == "oracle-cover-unknown";
          return std::unique_ptr<object_search::SearchPlanner>(
              new OraclePlanner(n, *args.model, truth->simulator(), options));
        });
    if (!s.ok()) return s;
  }
  return OkStatus();
}

}  // namespace npfkct::sim
