// An ADVT-style planner (Hoerger, Kurniawati, Kroese & Ye 2022): MCTS whose action space at every
// belief node is adaptively partitioned by a Voronoi tree. Each leaf cell is an arm, selected by
// UCB with a cell-diameter bonus; a cell splits in two (the old representative and a new point
// drawn inside it) once c_s n >= (root diameter / cell diameter)^2.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/belief_tree.h"
#include "npfkct/solver/hybrid.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/planner_base.h"

namespace npfkct {

/// Options of the ADVT-style planner. Defaults follow the authors' VDP Tag configuration.
struct AdvtOptions {
  /// Depth, horizon, reuse, particles and belief update settings.
  SearchOptions search;
  /// UCB exploration constant C; NaN means the model's reward range.
  double exploration_c = std::numeric_limits<double>::quiet_NaN();
  /// Weight L of the diameter bonus (L / root diameter) * diam(cell).
  double diameter_coefficient = 5.0;
  /// Split coefficient c_s: split when c_s n >= (root diameter / diam(cell))^2.
  double split_coefficient = 5.0;
  /// Boundary points used to estimate a cell's diameter.
  int diameter_samples = 10;
  /// Random-walk steps used to draw a point inside a cell.
  int walk_steps = 10;
  /// kMax passes the best leaf value of a child up (the authors' default); kMonteCarlo the return.
  enum class Backup { kMonteCarlo, kMax };
  Backup backup = Backup::kMax;
  /// Observation branching.
  ObservationWidening observations;
  /// Draws spent to find a cell representative that passes the model's reasonability check (1: no
  /// check).
  int feasibility_tries = 1;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (Status s = search.Validate(); !s.ok()) return Prefixed("search", s);
    if (Status s = search.RequireOneThread(); !s.ok()) return s;
    if (!std::isnan(exploration_c) && !(exploration_c >= 0.0 && std::isfinite(exploration_c))) {
      return InvalidArgumentError("exploration_c must be >= 0 (or NaN for the reward range)");
    }
    if (feasibility_tries < 1) return InvalidArgumentError("feasibility_tries must be >= 1");
    if (!(diameter_coefficient >= 0.0) || !std::isfinite(diameter_coefficient)) {
      return InvalidArgumentError("diameter_coefficient must be >= 0");
    }
    if (!(split_coefficient > 0.0) || !std::isfinite(split_coefficient)) {
      return InvalidArgumentError("split_coefficient must be > 0");
    }
    if (diameter_samples < 2) return InvalidArgumentError("diameter_samples must be >= 2");
    if (walk_steps < 1) return InvalidArgumentError("walk_steps must be >= 1");
    return Prefixed("observations", observations.Validate());
  }
};

/// The ADVT-style planner over a hybrid-action model (one Voronoi tree per continuous kind; kinds
/// without a continuous part are single cells). The model must outlive the planner.
template <HybridActionModel M>
class Advt : public PlannerBase<Advt<M>, M, AdvtOptions> {
  using Base = PlannerBase<Advt<M>, M, AdvtOptions>;
  NPFKCT_PLANNER_INTERFACE(Base);

 public:
  using Base::Base;

  /// Searches from the current belief within `budget` and recommends an action.
  Decision<Action> Plan(const TerminationCondition& stop, Rng& rng) {
    Decision<Action> d;
    if (Status s = this->Begin(stop, &d); !s.ok()) return Base::Fail(std::move(d), std::move(s));
    if (tree_.root < 0) tree_.root = tree_.NewObsNode();
    max_depth_ = 0;
    d.stats.reused_visits = tree_.obs[tree_.root].n;
    stop_ = &stop;
    d.stats.simulations =
        this->SimulateUntil(stop, rng, [&](const State& s) { Simulate(s, tree_.root, 0, rng); });
    stop_ = nullptr;
    if (tree_.obs[tree_.root].actions.empty()) InitCells(tree_.root, belief_.Sample(rng), rng);
    FillRootStats(tree_, BestTriedRootAction(tree_), max_depth_, &d);
    return FinishSearch(std::move(d), stop);
  }

  int64_t TreeSize() const { return tree_.size(); }
  int64_t RootVisits() const { return tree_.root >= 0 ? tree_.obs[tree_.root].n : 0; }
  /// Leaf cells at the root (the current partition's size).
  int RootCells() const { return tree_.root >= 0 ? tree_.obs[tree_.root].actions.size() : 0; }

 private:
  // A Voronoi cell: the kind's box intersected with the half-spaces {x : d(x, own) <= d(x, other)}
  // of every split on the way from the root cell.
  struct Cell {
    std::vector<std::pair<ActionVec, ActionVec>> constraints;
    double diameter = -1.0;  // cached estimate; < 0 until computed
  };
  using Tree = BeliefTree<M, Cell>;

  void ClearTree() { tree_.Clear(); }

  bool HasTree() const { return tree_.root >= 0; }

  void KeepChild(const Action& a, const Observation& o) {
    int next = -1;
    if (options_.search.reuse_tree && tree_.root >= 0) {
      const int ai = tree_.FindAction(tree_.root, a);
      if (ai >= 0) next = tree_.act[ai].children.Find(o, HashObservation(o));
    }
    if (next < 0) {
      tree_.Clear();
    } else {
      tree_.KeepSubtree(next);
    }
  }

  bool InCell(const BoxSpace& box, const Cell& cell, const ActionVec& x) const {
    if (!box.Contains(x)) return false;
    for (const auto& [own, other] : cell.constraints) {
      if (box.SquaredDistance(x, own) > box.SquaredDistance(x, other)) return false;
    }
    return true;
  }

  // Unit direction in metric coordinates, mapped to box coordinates.
  ActionVec RandomDirection(const BoxSpace& box, Rng& rng) const {
    ActionVec u = ActionVec::Zero(box.dim());
    double norm2 = 0.0;
    do {
      for (int i = 0; i < u.size(); ++i) u[i] = box.fixed(i) ? 0.0 : rng.Normal();
      norm2 = u.squaredNorm();
    } while (norm2 == 0.0 && box.Diameter() > 0.0);
    if (norm2 == 0.0) return u;  // every dimension fixed: nowhere to go
    return (u.array() / std::sqrt(norm2) * box.scale().array()).matrix();
  }

  // Largest t (metric units) with from + t u still in the cell, by bisection.
  double DistanceToBoundary(const BoxSpace& box, const Cell& cell, const ActionVec& from,
                            const ActionVec& u) const {
    double lo = 0.0, hi = box.Diameter() + 1.0;
    const double tol = 1e-3 * std::max(box.Diameter(), 1e-9);
    if (InCell(box, cell, box.WrapPeriodic(from + hi * u))) return hi;
    while (hi - lo > tol) {
      const double mid = 0.5 * (lo + hi);
      if (InCell(box, cell, box.WrapPeriodic(from + mid * u))) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    return lo;
  }

  double Diameter(int ai, Rng& rng) {
    auto& an = tree_.act[ai];
    if (an.data.diameter >= 0.0) return an.data.diameter;
    const BoxSpace& box = model_.KindSpace(an.action.kind);
    double diam = 0.0;
    if (box.dim() > 0) {
      std::vector<ActionVec> boundary;
      for (int i = 0; i < options_.diameter_samples; ++i) {
        const ActionVec u = RandomDirection(box, rng);
        const double t = DistanceToBoundary(box, an.data, an.action.x, u);
        boundary.push_back(box.WrapPeriodic(an.action.x + t * u));
      }
      for (size_t i = 0; i < boundary.size(); ++i) {
        for (size_t j = i + 1; j < boundary.size(); ++j) {
          diam = std::max(diam, box.Distance(boundary[i], boundary[j]));
        }
      }
      diam = std::min(diam, box.Diameter());
    }
    an.data.diameter = diam;
    return diam;
  }

  ActionVec SampleInCell(const BoxSpace& box, const Cell& cell, const ActionVec& rep,
                         Rng& rng) const {
    ActionVec x = rep;
    for (int step = 0; step < options_.walk_steps; ++step) {
      const ActionVec u = RandomDirection(box, rng);
      const double t = DistanceToBoundary(box, cell, x, u);
      x = box.WrapPeriodic(x + rng.Uniform() * t * u);
    }
    return x;
  }

  void InitCells(int node, const State& s, Rng& rng) {
    model_.ActionKinds(s, &scratch_);
    // RolloutFirst: at the root, the rollout policy's action represents its kind's first cell.
    HybridAction first;
    first.kind = -1;
    if constexpr (requires { model_.RolloutAction(s, rng); }) {
      if (options_.search.rollout_first && node == tree_.root) {
        first = RolloutFirstAction(model_, belief_, s, rng);
      }
    }
    for (int kind : std::vector<int>(scratch_)) {
      HybridAction a;
      a.kind = kind;
      a.x = kind == first.kind
                ? first.x
                : SampleFeasiblePoint(model_, s, kind, options_.feasibility_tries, rng);
      tree_.NewActNode(node, std::move(a));
    }
  }

  // A point of the cell that passes the reasonability check in s (up to feasibility_tries walks;
  // the last walk's point when none passes).
  ActionVec SampleFeasibleInCell(const State& s, const BoxSpace& box, const Cell& cell,
                                 const ActionVec& rep, int kind, Rng& rng) const {
    ActionVec x = SampleInCell(box, cell, rep, rng);
    for (int t = 1;
         t < options_.feasibility_tries && !IsFeasibleAction(model_, s, HybridAction{kind, x});
         ++t) {
      if (stop_ != nullptr && stop_->ShouldStop(0)) break;  // each walk: walk_steps steps
      x = SampleInCell(box, cell, rep, rng);
    }
    return x;
  }

  // Splits while the cell is large for its visits (up to 64 times). Each split walks walk_steps
  // steps over a constraint list that grows with the splits, so the search's condition is polled
  // before each one.
  void MaybeSplit(int node, int ai, const State& s, Rng& rng) {
    for (int depth = 0; depth < 64; ++depth) {
      const BoxSpace& box = model_.KindSpace(tree_.act[ai].action.kind);
      if (box.dim() == 0) return;
      const double root_diam = box.Diameter();
      const double diam = Diameter(ai, rng);
      if (!(diam > 1e-12 * root_diam)) return;
      const double ratio = diam / root_diam;
      if (options_.split_coefficient * static_cast<double>(tree_.act[ai].n) * ratio * ratio < 1.0) {
        return;
      }
      if (stop_ != nullptr && stop_->ShouldStop(0)) return;
      const ActionVec rep = tree_.act[ai].action.x;
      const ActionVec fresh =
          SampleFeasibleInCell(s, box, tree_.act[ai].data, rep, tree_.act[ai].action.kind, rng);
      if (box.SquaredDistance(fresh, rep) == 0.0) return;
      Cell sibling;
      sibling.constraints = tree_.act[ai].data.constraints;
      sibling.constraints.emplace_back(fresh, rep);
      tree_.act[ai].data.constraints.emplace_back(rep, fresh);
      tree_.act[ai].data.diameter = -1.0;
      HybridAction a;
      a.kind = tree_.act[ai].action.kind;
      a.x = fresh;
      tree_.NewActNode(node, std::move(a), std::move(sibling));
      // Re-test the shrunken cell, as ADVT does.
    }
  }

  int SelectCell(int node, Rng& rng) {
    const auto& on = tree_.obs[node];
    const double log_n = std::log(static_cast<double>(std::max<int64_t>(on.n, 1)));
    int best = on.actions.front();
    double best_score = -std::numeric_limits<double>::infinity();
    for (int ai : on.actions) {
      const auto& an = tree_.act[ai];
      double score = Ucb1(an.q, an.n, log_n, c_);
      if (std::isfinite(score)) {
        const BoxSpace& box = model_.KindSpace(an.action.kind);
        if (box.dim() > 0) {
          score += options_.diameter_coefficient / box.Diameter() * Diameter(ai, rng);
        }
      }
      if (score > best_score) {
        best_score = score;
        best = ai;
      }
    }
    return best;
  }

  double BestLeafValue(int node) const {
    double best = -std::numeric_limits<double>::infinity();
    for (int ai : tree_.obs[node].actions) {
      if (tree_.act[ai].n > 0) best = std::max(best, tree_.act[ai].q);
    }
    return std::isfinite(best) ? best : tree_.obs[node].leaf_value;
  }

  // Returns the value passed to the parent: the return R (Monte Carlo) or the best leaf value.
  double Simulate(const State& s, int node, int depth, Rng& rng) {
    if (IsTerminalState(model_, s) || depth >= options_.search.max_depth ||
        std::pow(model_.Discount(), depth) < options_.search.discount_horizon) {
      return 0.0;
    }
    max_depth_ = std::max(max_depth_, depth);
    if (tree_.obs[node].actions.empty()) InitCells(node, s, rng);
    const int ai = SelectCell(node, rng);
    const Action a = tree_.act[ai].action;
    auto t = tree_.Descend(model_, ai, a, s, options_.observations, 0, rng);
    double total = t.reward;
    if (!t.terminal) {
      double v;
      if (t.new_node) {
        v = LeafEstimate(model_, t.state, depth + 1, options_.search, rng, &scratch_);
        tree_.AddLeafValue(t.child, v);
      } else {
        v = Simulate(t.state, t.child, depth + 1, rng);
      }
      total += model_.Discount() * v;
    }
    ++tree_.obs[node].n;
    auto& an = tree_.act[ai];
    ++an.n;
    an.q += (total - an.q) / static_cast<double>(an.n);
    MaybeSplit(node, ai, s, rng);
    return options_.backup == AdvtOptions::Backup::kMax ? BestLeafValue(node) : total;
  }

  Tree tree_;
  int max_depth_ = 0;
  std::vector<int> scratch_;
  const TerminationCondition* stop_ = nullptr;  // the running Plan()'s
};

}  // namespace npfkct
