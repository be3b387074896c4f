// The k-center clustering tree of NPF-kCT (paper section 4.2, algorithms 1-3 and 6).
//
// Every observation node keeps a dynamic action list L(node) of hyperspheres (center, range) of the
// continuous action space, plus the discrete actions (range 0). The list starts from candidate
// actions (uniform, or filtered by the neural process network) clustered into hyperspheres by
// k-means with the elbow method. An episode picks the entry maximising
//   U = Qhat / value_scale + w1 sqrt(log N / N_a) + w2 range,
// refines it once N_a >= 1 / (C_r range^2) and range > D_lim by k-means of the actions tried in it
// (radii clamped by f_lim; the subtree is copied for every new sphere and each copy keeps only the
// episodes of its cluster), executes a point drawn uniformly in the sphere, and backs up by
// Monte Carlo or Bellman (algorithm 6).
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/belief_tree.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/clustering.h"
#include "npfkct/solver/hybrid.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/planner.h"

namespace npfkct {

/// Options of the k-center clustering tree. Defaults follow the paper's appendix J.
struct KctOptions {
  /// Depth, horizon, reuse, particles and belief update settings.
  SearchOptions search;
  /// Clusters per refinement (k).
  int k = 3;
  /// UCB coefficient w1 (on values divided by value_scale).
  double w1 = std::numbers::sqrt2;
  /// Range coefficient w2.
  double w2 = 0.5;
  /// Scale dividing Qhat in U; NaN means the model's reward range.
  double value_scale = std::numeric_limits<double>::quiet_NaN();
  /// Refinement exploration constant C_r: refine once N_a >= 1 / (C_r range^2).
  double c_r = 0.05;
  /// Minimum radius D_lim: spheres of this range or less are never refined.
  double d_lim = 0.2;
  /// f_lim coefficients: refined radii are clamped to [w2_bar, w1_bar] x the parent range.
  double w1_bar = 0.6;
  double w2_bar = 0.3;
  /// Backup rule (paper algorithm 6).
  enum class Backup { kMonteCarlo, kBellman };
  Backup backup = Backup::kMonteCarlo;
  /// Candidate actions drawn per continuous kind and planning step.
  int num_candidates = 256;
  /// Upper bound of k_i for the elbow method on the candidates.
  int max_initial_clusters = 8;
  /// How the executed action is drawn from the best root sphere.
  enum class FinalAction {
    kUniformInSphere,  ///< Uniform in the sphere, rejecting infeasible points (paper).
    kCenter,           ///< The sphere's center (when feasible).
  };
  FinalAction final_action = FinalAction::kUniformInSphere;
  /// Draws tried by Action_sam before it falls back to the center.
  int max_feasibility_tries = 100;
  /// Draws tried inside the tree to find a point of a sphere that passes the model's
  /// reasonability check (1: no check in the tree, the paper's behaviour).
  int tree_feasibility_tries = 8;
  /// Observation branching.
  ObservationWidening observations;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (Status s = search.Validate(); !s.ok()) return Prefixed("search", s);
    if (k < 2) return InvalidArgumentError("k must be >= 2");
    if (!(w1 >= 0.0) || !std::isfinite(w1)) return InvalidArgumentError("w1 must be >= 0");
    if (!(w2 >= 0.0) || !std::isfinite(w2)) return InvalidArgumentError("w2 must be >= 0");
    if (!std::isnan(value_scale) && !(value_scale > 0.0 && std::isfinite(value_scale))) {
      return InvalidArgumentError("value_scale must be > 0 (or NaN for the reward range)");
    }
    if (!(c_r > 0.0) || !std::isfinite(c_r)) return InvalidArgumentError("c_r must be > 0");
    if (!(d_lim > 0.0) || !std::isfinite(d_lim)) return InvalidArgumentError("d_lim must be > 0");
    if (!(w2_bar >= 0.0 && w2_bar < w1_bar && w1_bar <= 1.0)) {
      return InvalidArgumentError("w1_bar and w2_bar must satisfy 0 <= w2_bar < w1_bar <= 1");
    }
    if (num_candidates < 1) return InvalidArgumentError("num_candidates must be >= 1");
    if (max_initial_clusters < 1) {
      return InvalidArgumentError("max_initial_clusters must be >= 1");
    }
    if (max_feasibility_tries < 1) {
      return InvalidArgumentError("max_feasibility_tries must be >= 1");
    }
    if (tree_feasibility_tries < 1) {
      return InvalidArgumentError("tree_feasibility_tries must be >= 1");
    }
    return Prefixed("observations", observations.Validate());
  }
};

/// f_lim of the paper (equation 4): clamps a refined radius to [w2_bar, w1_bar] x parent_range,
/// and never below d_lim.
inline double FLim(double radius, double parent_range, const KctOptions& o) {
  double r = radius;
  if (r >= o.w1_bar * parent_range) {
    r = o.w1_bar * parent_range;
  } else if (r <= o.w2_bar * parent_range) {
    r = o.w2_bar * parent_range;
  }
  return std::max(r, o.d_lim);
}

/// A hypersphere of a continuous kind: its center and range.
struct Hypersphere {
  int kind = 0;
  ActionVec center;
  double range = 0.0;
};

/// The k-center clustering tree planner over a hybrid-action model. The model must outlive it.
template <HybridActionModel M>
class KCenterTree {
 public:
  using State = typename M::State;
  using Action = HybridAction;
  using Observation = typename M::Observation;

  /// A planner whose candidates come from `sampler` (uniform when null).
  KCenterTree(const M& model, KctOptions options,
              std::shared_ptr<CandidateSampler<State>> sampler = nullptr)
      : model_(model), options_(std::move(options)), sampler_(std::move(sampler)) {
    if (!sampler_) sampler_ = std::make_shared<UniformCandidateSampler<State>>();
    scale_ = std::isnan(options_.value_scale) ? RewardRange(model_, 1.0) : options_.value_scale;
  }

  void Reset(Rng& rng) {
    belief_ = ParticleBelief<State>::FromInitial(model_, options_.search.num_particles, rng);
    tree_.Clear();
  }
  void SetBelief(ParticleBelief<State> belief) {
    belief_ = std::move(belief);
    tree_.Clear();
  }
  const ParticleBelief<State>& belief() const { return belief_; }
  const KctOptions& options() const { return options_; }
  /// Replaces the candidate sampler (e.g. with the neural filter).
  void SetSampler(std::shared_ptr<CandidateSampler<State>> sampler) {
    if (sampler) sampler_ = std::move(sampler);
  }
  /// What the candidate sampler did in the last Plan().
  const CandidateStats& candidate_stats() const { return candidate_stats_; }
  /// The hyperspheres built from the candidates in the last Plan(), per kind.
  const std::map<int, std::vector<Hypersphere>>& spheres() const { return spheres_; }
  /// The root sphere the last decision came from (kind, center, range).
  Hypersphere last_sphere() const { return last_sphere_; }

  /// Plans within a budget of its own (a condition created here, which nobody can cancel).
  Decision<Action> Plan(const Budget& budget, Rng& rng) {
    TerminationCondition stop(budget);
    return Plan(stop, rng);
  }

  /// Plans within `budget` (algorithm 1, lines 3-18) and recommends an executable action.
  Decision<Action> Plan(const TerminationCondition& stop, Rng& rng) {
    Decision<Action> d;
    d.stats.budget_exhausted = false;
    if (Status s = options_.Validate(); !s.ok()) return Fail(std::move(d), std::move(s));
    if (Status s = stop.budget().Validate(); !s.ok()) return Fail(std::move(d), std::move(s));
    if (belief_.empty()) return Fail(std::move(d), FailedPreconditionError("belief is empty"));
    if constexpr (!HasObservationLikelihood<M>) {
      if (options_.observations.enabled) {
        return Fail(std::move(d),
                    InvalidArgumentError("observations.enabled needs the model's observation "
                                         "likelihood; use exact observation matching"));
      }
    }
    if (!options_.search.reuse_tree && tree_.root >= 0) {
      const auto t0 = Clock::now();
      tree_.Clear();
      d.stats.teardown_ms = MillisSince(t0);
    }
    max_depth_ = 0;
    refinements_ = 0;
    candidate_stats_ = {};
    spheres_.clear();
    // Net_sam + k-clustering for the kinds legal at the root, then Update(T, C_a, R_a).
    model_.ActionKinds(belief_.Sample(rng), &scratch_);
    for (int kind : std::vector<int>(scratch_)) {
      if (Status s = EnsureSpheres(kind, rng); !s.ok()) return Fail(std::move(d), std::move(s));
    }
    if (tree_.root < 0) {
      tree_.root = tree_.NewObsNode();
    } else {
      AddSpheresToTree();
      if (Status s = EnsureRootKinds(belief_.Sample(rng), rng); !s.ok()) {
        return Fail(std::move(d), std::move(s));
      }
    }
    d.stats.reused_visits = tree_.obs[tree_.root].n;

    int64_t sims = 0;
    while (!stop.ShouldStop(sims)) {
      const State& s = belief_.Sample(rng);
      if (!IsTerminalState(model_, s)) {
        Status status = OkStatus();
        Simulate(s, tree_.root, 0, next_episode_++, rng, &status);
        if (!status.ok()) return Fail(std::move(d), std::move(status));
      }
      ++sims;
    }
    d.stats.simulations = sims;
    d.stats.budget_exhausted = true;
    d.stats.refinements = refinements_;
    const State& s0 = belief_.Sample(rng);
    if (tree_.obs[tree_.root].actions.empty()) {
      if (Status s = InitList(tree_.root, s0, rng); !s.ok()) return Fail(std::move(d), s);
    }
    if (tree_.obs[tree_.root].actions.empty()) {
      return Fail(std::move(d), FailedPreconditionError("no legal action at the root"));
    }
    int best = -1;
    for (int ai : tree_.obs[tree_.root].actions) {
      const auto& an = tree_.act[ai];
      if (an.n == 0) continue;
      if (best < 0 || an.q > tree_.act[best].q ||
          (an.q == tree_.act[best].q && an.n > tree_.act[best].n)) {
        best = ai;
      }
    }
    if (best < 0) best = tree_.obs[tree_.root].actions.front();
    FillRootStats(tree_, best, max_depth_, &d);
    // Action_sam + Reasonability_check (algorithm 1, lines 12-18).
    d.action = SampleExecutable(best, s0, rng);
    const auto& an = tree_.act[best];
    last_sphere_ = {an.action.kind, an.action.x, an.data.range};
    last_entry_ = best;
    return FinishSearch(std::move(d), stop);
  }

  /// Filtering (algorithm 1, line 20): updates the belief with the executed action and the real
  /// observation, and keeps the subtree under the executed sphere and observation.
  BeliefUpdateSummary Advance(const Action& a, const Observation& o, Rng& rng) {
    BeliefUpdateOptions b = options_.search.belief;
    if (b.num_particles == 0) b.num_particles = options_.search.num_particles;
    BeliefUpdateSummary summary = belief_.Update(model_, a, o, rng, b);
    KeepChild(a, o);
    return summary;
  }

  /// Keeps the subtree under (a, o) when tree reuse is on and installs `belief`: for models whose
  /// belief is maintained outside the planner (object search).
  void AdvanceTo(const Action& a, const Observation& o, ParticleBelief<State> belief) {
    belief_ = std::move(belief);
    KeepChild(a, o);
  }

  int64_t TreeSize() const { return tree_.size(); }
  int64_t RootVisits() const { return tree_.root >= 0 ? tree_.obs[tree_.root].n : 0; }

  /// Verifies the statistics of every node below the root: N(node) = sum of N(node, a); N(node, a)
  /// equals the episodes recorded in the sphere; with Monte-Carlo backup Qhat is their mean return;
  /// with exact observation matching every child's visit count matches the recorded episodes; every
  /// continuous sphere's range is at least D_lim. Used by tests after refinements.
  Status CheckInvariants() const {
    if (tree_.root < 0) return OkStatus();
    std::vector<int> stack = {tree_.root};
    while (!stack.empty()) {
      const int node = stack.back();
      stack.pop_back();
      const auto& on = tree_.obs[node];
      int64_t sum = 0;
      for (int ai : on.actions) {
        const auto& an = tree_.act[ai];
        sum += an.n;
        const auto& d = an.data;
        if (an.n != static_cast<int64_t>(d.ids.size())) {
          return InternalError("sphere visit count differs from its recorded episodes");
        }
        if (!std::is_sorted(d.ids.begin(), d.ids.end())) {
          return InternalError("episode ids out of order");
        }
        const bool continuous = model_.KindSpace(an.action.kind).dim() > 0;
        if (continuous && d.range < options_.d_lim * (1 - 1e-12)) {
          return InternalError("sphere range below d_lim");
        }
        if (options_.backup == KctOptions::Backup::kMonteCarlo && an.n > 0) {
          double mean = 0.0;
          for (double r : d.returns) mean += r;
          mean /= static_cast<double>(an.n);
          if (std::abs(mean - an.q) > 1e-6 * std::max(1.0, std::abs(mean))) {
            return InternalError("Qhat differs from the mean recorded return");
          }
        }
        if (!options_.observations.enabled) {
          std::vector<int64_t> per_entry(an.children.size(), 0);
          for (int32_t e : d.entries) {
            if (e >= an.children.size()) return InternalError("record points past the children");
            if (e >= 0) ++per_entry[e];
          }
          for (int k = 0; k < an.children.size(); ++k) {
            if (per_entry[k] != an.generated[k]) {
              return InternalError("child visit count differs from the recorded episodes");
            }
          }
        }
        for (int k = 0; k < an.children.size(); ++k) stack.push_back(an.children.child(k));
      }
      if (sum != on.n) return InternalError("N(node) differs from the sum of N(node, a)");
    }
    return OkStatus();
  }

  /// The root's action list: (sphere, visits, value) per entry.
  std::vector<std::pair<Hypersphere, RootActionStat<Action>>> RootList() const {
    std::vector<std::pair<Hypersphere, RootActionStat<Action>>> out;
    if (tree_.root < 0) return out;
    for (int ai : tree_.obs[tree_.root].actions) {
      const auto& an = tree_.act[ai];
      out.push_back({{an.action.kind, an.action.x, an.data.range}, {an.action, an.n, an.q}});
    }
    return out;
  }

 private:
  // Per action node: the sphere's range (the center is action.x) and the episodes that chose it.
  struct Sphere {
    double range = 0.0;
    std::vector<uint32_t> ids;     // episode ids, increasing
    std::vector<double> returns;   // discounted return from the node
    std::vector<double> rewards;   // immediate reward
    std::vector<int32_t> entries;  // children entry reached, -1 when terminal
    std::vector<float> points;     // executed point, dim floats per record (continuous kinds)
  };
  using Tree = BeliefTree<M, Sphere>;

  void KeepChild(const Action& a, const Observation& o) {
    int next = -1;
    if (options_.search.reuse_tree && tree_.root >= 0) {
      const int ai = EntryContaining(a);
      if (ai >= 0) next = tree_.act[ai].children.Find(o, HashObservation(o));
    }
    last_entry_ = -1;
    if (next < 0) {
      tree_.Clear();
    } else {
      tree_.KeepSubtree(next);
    }
  }

  static Decision<Action> Fail(Decision<Action> d, Status s) {
    d.status = std::move(s);
    d.stats.budget_exhausted = false;
    return d;
  }

  Status EnsureSpheres(int kind, Rng& rng) {
    if (spheres_.count(kind)) return OkStatus();
    const BoxSpace& box = model_.KindSpace(kind);
    std::vector<Hypersphere>& out = spheres_[kind];
    if (box.dim() == 0) return OkStatus();
    // Candidates that fail the reasonability check are dropped; a few rounds top them up.
    std::vector<ActionVec> points;
    const auto t0 = Clock::now();
    for (int round = 0; round < 4 && static_cast<int>(points.size()) < options_.num_candidates;
         ++round) {
      std::vector<ActionVec> batch;
      Status s = sampler_->Sample(belief_, kind, box, options_.num_candidates, rng, &batch,
                                  &candidate_stats_);
      if (!s.ok()) {
        candidate_stats_.elapsed_ms += MillisSince(t0);
        return s;
      }
      for (const ActionVec& p : batch) {
        if (!box.Contains(p)) {
          return InternalError("candidate sampler returned a point outside the action box");
        }
        if (IsFeasibleAction(model_, belief_.Sample(rng), HybridAction{kind, p})) {
          points.push_back(p);
        }
      }
      // A sampler that returns fewer than asked (the neural filter) has nothing more to offer.
      if (static_cast<int>(batch.size()) < options_.num_candidates) break;
    }
    candidate_stats_.elapsed_ms += MillisSince(t0);
    if (points.empty()) {
      // Nothing usable: fall back to one sphere around the whole box.
      out.push_back({kind, box.Clamp((box.lower() + box.upper()) / 2.0),
                     std::max(box.Diameter() / 2.0, options_.d_lim)});
      return OkStatus();
    }
    for (const Cluster& c : ClusterByElbow(box, points, options_.max_initial_clusters, rng)) {
      out.push_back({kind, c.center, std::max(c.radius, options_.d_lim)});
    }
    return OkStatus();
  }

  Status InitList(int node, const State& s, Rng& rng) {
    model_.ActionKinds(s, &scratch_);
    for (int kind : std::vector<int>(scratch_)) {
      if (Status st = EnsureSpheres(kind, rng); !st.ok()) return st;
      if (model_.KindSpace(kind).dim() == 0) {
        HybridAction a;
        a.kind = kind;
        tree_.NewActNode(node, std::move(a));
        continue;
      }
      for (const Hypersphere& h : spheres_[kind]) AddSphere(node, h);
    }
    return OkStatus();
  }

  void AddSphere(int node, const Hypersphere& h) {
    HybridAction a;
    a.kind = h.kind;
    a.x = h.center;
    Sphere data;
    data.range = h.range;
    tree_.NewActNode(node, std::move(a), std::move(data));
  }

  // Update(T, C_a, R_a): the new spheres join every initialised list holding that kind.
  void AddSpheresToTree() {
    const int num_nodes = static_cast<int>(tree_.obs.size());
    for (int node = 0; node < num_nodes; ++node) {
      if (tree_.obs[node].actions.empty()) continue;
      for (const auto& [kind, list] : spheres_) {
        const bool has_kind =
            std::any_of(tree_.obs[node].actions.begin(), tree_.obs[node].actions.end(),
                        [&](int ai) { return tree_.act[ai].action.kind == kind; });
        if (!has_kind) continue;
        for (const Hypersphere& h : list) AddSphere(node, h);
      }
    }
  }

  // A reused root may lack kinds that became legal (e.g. objects detected since): add them.
  Status EnsureRootKinds(const State& s, Rng& rng) {
    const int root = tree_.root;
    if (tree_.obs[root].actions.empty()) return OkStatus();
    model_.ActionKinds(s, &scratch_);
    for (int kind : std::vector<int>(scratch_)) {
      const bool present =
          std::any_of(tree_.obs[root].actions.begin(), tree_.obs[root].actions.end(),
                      [&](int ai) { return tree_.act[ai].action.kind == kind; });
      if (present) continue;
      if (model_.KindSpace(kind).dim() == 0) {
        HybridAction a;
        a.kind = kind;
        tree_.NewActNode(root, std::move(a));
        continue;
      }
      if (Status st = EnsureSpheres(kind, rng); !st.ok()) return st;
      for (const Hypersphere& h : spheres_[kind]) AddSphere(root, h);
    }
    return OkStatus();
  }

  int Select(int node) const {
    const auto& on = tree_.obs[node];
    const double log_n = std::log(static_cast<double>(std::max<int64_t>(on.n, 1)));
    int best = on.actions.front();
    double best_score = -std::numeric_limits<double>::infinity();
    for (int ai : on.actions) {
      const auto& an = tree_.act[ai];
      const double score =
          Ucb1(an.q / scale_, an.n, log_n, options_.w1) + options_.w2 * an.data.range;
      if (score > best_score) {
        best_score = score;
        best = ai;
      }
    }
    return best;
  }

  double VStar(int node) const {
    double best = -std::numeric_limits<double>::infinity();
    for (int ai : tree_.obs[node].actions) {
      if (tree_.act[ai].n > 0) best = std::max(best, tree_.act[ai].q);
    }
    return std::isfinite(best) ? best : tree_.obs[node].leaf_value;
  }

  HybridAction SampleInSphere(int ai, Rng& rng) const {
    const auto& an = tree_.act[ai];
    HybridAction a;
    a.kind = an.action.kind;
    a.x = model_.KindSpace(a.kind).SampleInBall(an.action.x, an.data.range, rng);
    return a;
  }

  // A point of the sphere that passes the reasonability check in state s (a few draws; the last
  // draw when none passes, so that the model's penalty teaches the tree to avoid the sphere).
  HybridAction SampleFeasibleInSphere(int ai, const State& s, Rng& rng) const {
    HybridAction a = SampleInSphere(ai, rng);
    if (model_.KindSpace(a.kind).dim() == 0) return a;
    for (int tries = 1; tries < options_.tree_feasibility_tries && !IsFeasibleAction(model_, s, a);
         ++tries) {
      a = SampleInSphere(ai, rng);
    }
    return a;
  }

  // Episode_simulation (algorithm 2). Returns the discounted return of the episode from `node`.
  double Simulate(const State& s, int node, int depth, uint32_t episode, Rng& rng, Status* status) {
    if (IsTerminalState(model_, s) || depth >= options_.search.max_depth ||
        std::pow(model_.Discount(), depth) < options_.search.discount_horizon) {
      return 0.0;
    }
    max_depth_ = std::max(max_depth_, depth);
    if (tree_.obs[node].actions.empty()) {
      if (Status st = InitList(node, s, rng); !st.ok()) {
        *status = st;
        return 0.0;
      }
      if (tree_.obs[node].actions.empty()) return 0.0;
    }
    const int ai = Select(node);
    Refine(node, ai, rng);
    const HybridAction executed = SampleFeasibleInSphere(ai, s, rng);
    auto t = tree_.Descend(model_, ai, executed, s, options_.observations, episode, rng);
    const double gamma = model_.Discount();
    double total = t.reward;
    if (!t.terminal) {
      if (t.new_node) {
        const double v = LeafEstimate(model_, t.state, depth + 1, options_.search, rng, &scratch_);
        tree_.AddLeafValue(t.child, v);
        total += gamma * v;
      } else {
        total += gamma * Simulate(t.state, t.child, depth + 1, episode, rng, status);
      }
    }
    // Backup (algorithm 6).
    ++tree_.obs[node].n;
    auto& an = tree_.act[ai];
    ++an.n;
    if (options_.backup == KctOptions::Backup::kMonteCarlo) {
      an.q += (total - an.q) / static_cast<double>(an.n);
    } else {
      const double target = t.reward + (t.terminal ? 0.0 : gamma * VStar(t.child));
      tree_.act[ai].q += (target - tree_.act[ai].q) / static_cast<double>(tree_.act[ai].n);
    }
    Sphere& sp = tree_.act[ai].data;
    sp.ids.push_back(episode);
    sp.returns.push_back(total);
    sp.rewards.push_back(t.reward);
    sp.entries.push_back(t.terminal ? -1 : t.entry);
    for (int i = 0; i < executed.x.size(); ++i) {
      sp.points.push_back(static_cast<float>(executed.x[i]));
    }
    return total;
  }

  // Refine (algorithm 3).
  void Refine(int node, int ai, Rng& rng) {
    const BoxSpace& box = model_.KindSpace(tree_.act[ai].action.kind);
    const double range = tree_.act[ai].data.range;
    const int dim = box.dim();
    if (dim == 0 || !(range > options_.d_lim)) return;
    if (static_cast<double>(tree_.act[ai].n) < 1.0 / (options_.c_r * range * range)) return;
    const Sphere& data = tree_.act[ai].data;
    const int n = static_cast<int>(data.ids.size());
    if (n < options_.k) return;
    std::vector<ActionVec> points(n, ActionVec(dim));
    for (int r = 0; r < n; ++r) {
      for (int i = 0; i < dim; ++i) points[r][i] = data.points[static_cast<size_t>(r) * dim + i];
    }
    std::vector<Cluster> clusters = KMeans(box, points, options_.k, rng);
    if (clusters.size() < 2) return;
    std::vector<std::vector<uint32_t>> ids(clusters.size());
    for (size_t j = 0; j < clusters.size(); ++j) {
      for (int m : clusters[j].members) ids[j].push_back(data.ids[m]);
      std::sort(ids[j].begin(), ids[j].end());
    }
    // New spheres 2..k get filtered copies of the subtree; sphere 1 replaces the original.
    for (size_t j = 1; j < clusters.size(); ++j) {
      const int copy = CopyAction(ai, ids[j]);
      tree_.act[copy].action.x = clusters[j].center;
      tree_.act[copy].data.range = FLim(clusters[j].radius, range, options_);
      tree_.obs[node].actions.push_back(copy);
    }
    const int first = CopyAction(ai, ids[0]);
    tree_.act[ai] = std::move(tree_.act[first]);
    tree_.act[first] = {};
    tree_.act[ai].action.x = clusters[0].center;
    tree_.act[ai].data.range = FLim(clusters[0].radius, range, options_);
    ++refinements_;
  }

  static bool Contains(const std::vector<uint32_t>& sorted, uint32_t id) {
    return std::binary_search(sorted.begin(), sorted.end(), id);
  }

  // Copies action node `ai` and its subtree keeping only the episodes in `keep`; returns the new
  // (unattached) action node.
  int CopyAction(int ai, const std::vector<uint32_t>& keep) {
    typename Tree::ActNode out;
    {
      const auto& src = tree_.act[ai];
      out.action = src.action;
      out.data.range = src.data.range;
    }
    const int dim = static_cast<int>(tree_.act[ai].action.x.size());
    std::vector<int> entry_map(tree_.act[ai].children.size(), -1);
    const int records = static_cast<int>(tree_.act[ai].data.ids.size());
    for (int r = 0; r < records; ++r) {
      const auto& src = tree_.act[ai].data;
      if (!Contains(keep, src.ids[r])) continue;
      const int e = src.entries[r];
      int new_entry = -1;
      if (e >= 0) {
        if (entry_map[e] < 0) {
          const int old_child = tree_.act[ai].children.child(e);
          const int new_child = CopyObs(old_child, keep);
          const auto& children = tree_.act[ai].children;
          out.children.Add(children.observation(e), children.hash(e), new_child);
          out.generated.push_back(0);
          entry_map[e] = out.children.size() - 1;
        }
        new_entry = entry_map[e];
        ++out.generated[new_entry];
        ++out.total_generated;
      }
      const auto& src2 = tree_.act[ai].data;
      out.data.ids.push_back(src2.ids[r]);
      out.data.returns.push_back(src2.returns[r]);
      out.data.rewards.push_back(src2.rewards[r]);
      out.data.entries.push_back(new_entry);
      for (int i = 0; i < dim && !src2.points.empty(); ++i) {
        out.data.points.push_back(src2.points[static_cast<size_t>(r) * dim + i]);
      }
    }
    out.n = static_cast<int64_t>(out.data.ids.size());
    out.q = 0.0;
    const double gamma = model_.Discount();
    for (size_t r = 0; r < out.data.ids.size(); ++r) {
      double v = out.data.returns[r];
      if (options_.backup == KctOptions::Backup::kBellman) {
        const int e = out.data.entries[r];
        v = out.data.rewards[r] + (e < 0 ? 0.0 : gamma * VStar(out.children.child(e)));
      }
      out.q += (v - out.q) / static_cast<double>(r + 1);
    }
    tree_.act.push_back(std::move(out));
    return static_cast<int>(tree_.act.size()) - 1;
  }

  // Copies observation node `node` and its subtree keeping only the episodes in `keep`.
  int CopyObs(int node, const std::vector<uint32_t>& keep) {
    typename Tree::ObsNode out;
    {
      const auto& src = tree_.obs[node];
      out.leaf_value = src.leaf_value;
      out.leaf_count = src.leaf_count;
      double previous = 0.0;
      for (size_t i = 0; i < src.states.size(); ++i) {
        const double w = src.cumulative[i] - previous;
        previous = src.cumulative[i];
        if (!Contains(keep, src.episodes[i])) continue;
        out.states.push_back(src.states[i]);
        out.rewards.push_back(src.rewards[i]);
        out.episodes.push_back(src.episodes[i]);
        out.cumulative.push_back((out.cumulative.empty() ? 0.0 : out.cumulative.back()) + w);
      }
    }
    const std::vector<int> actions = tree_.obs[node].actions;
    for (int ai : actions) {
      const int copy = CopyAction(ai, keep);
      out.actions.push_back(copy);
      out.n += tree_.act[copy].n;
    }
    tree_.obs.push_back(std::move(out));
    return static_cast<int>(tree_.obs.size()) - 1;
  }

  HybridAction SampleExecutable(int ai, const State& s, Rng& rng) const {
    const auto& an = tree_.act[ai];
    if (model_.KindSpace(an.action.kind).dim() == 0) return an.action;
    if (options_.final_action == KctOptions::FinalAction::kUniformInSphere) {
      for (int i = 0; i < options_.max_feasibility_tries; ++i) {
        HybridAction a = SampleInSphere(ai, rng);
        if (IsFeasibleAction(model_, s, a)) return a;
      }
    }
    if (IsFeasibleAction(model_, s, an.action)) return an.action;
    // Fall back to the best tried point of the sphere.
    const auto& data = an.data;
    const int dim = static_cast<int>(an.action.x.size());
    int best = -1;
    for (size_t r = 0; r < data.ids.size(); ++r) {
      if (best < 0 || data.returns[r] > data.returns[best]) best = static_cast<int>(r);
    }
    HybridAction a = an.action;
    if (best >= 0 && !data.points.empty()) {
      for (int i = 0; i < dim; ++i) a.x[i] = data.points[static_cast<size_t>(best) * dim + i];
    }
    return a;
  }

  // The root entry an executed action came from: the last decision's sphere when it contains the
  // action, else the closest containing sphere of the same kind.
  int EntryContaining(const HybridAction& a) const {
    auto contains = [&](int ai) {
      const auto& an = tree_.act[ai];
      if (an.action.kind != a.kind) return false;
      const BoxSpace& box = model_.KindSpace(a.kind);
      if (box.dim() == 0) return true;
      return box.Distance(a.x, an.action.x) <= an.data.range * (1.0 + 1e-9) + 1e-12;
    };
    if (last_entry_ >= 0 && last_entry_ < static_cast<int>(tree_.act.size()) &&
        contains(last_entry_)) {
      return last_entry_;
    }
    int best = -1;
    double best_ratio = std::numeric_limits<double>::infinity();
    for (int ai : tree_.obs[tree_.root].actions) {
      if (!contains(ai)) continue;
      const auto& an = tree_.act[ai];
      const double range = std::max(an.data.range, 1e-12);
      const double ratio = model_.KindSpace(a.kind).dim() == 0
                               ? 0.0
                               : model_.KindSpace(a.kind).Distance(a.x, an.action.x) / range;
      if (ratio < best_ratio) {
        best_ratio = ratio;
        best = ai;
      }
    }
    return best;
  }

  const M& model_;
  KctOptions options_;
  std::shared_ptr<CandidateSampler<State>> sampler_;
  double scale_ = 1.0;
  ParticleBelief<State> belief_;
  Tree tree_;
  std::map<int, std::vector<Hypersphere>> spheres_;
  CandidateStats candidate_stats_;
  Hypersphere last_sphere_;
  int last_entry_ = -1;
  uint32_t next_episode_ = 1;
  int max_depth_ = 0;
  int64_t refinements_ = 0;
  std::vector<int> scratch_;
};

}  // namespace npfkct
