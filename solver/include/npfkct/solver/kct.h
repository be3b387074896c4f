// The k-center clustering tree of NPF-kCT (paper section 4.2, algorithms 1-3 and 6).
//
// Every observation node keeps a dynamic action list L(node) of hyperspheres (center, range) of the
// continuous action space, plus the discrete actions (range 0). The list starts from candidate
// actions (uniform, aimed, or filtered by the neural process network) clustered into hyperspheres
// by k-means with the elbow method. An episode picks the entry maximising
//   U = norm(Qhat) + w1 sqrt(log N / N_a) + w2 range,
// refines it once N_a >= 1 / (C_r range^2) and range > D_lim by k-means of the actions tried in it
// (radii clamped by f_lim; the subtree is copied for every new sphere and each copy keeps only the
// episodes of its cluster), executes a point of the sphere (one of the candidates it covers, or
// uniform in it), and backs up by Monte Carlo or Bellman (algorithm 6). norm() maps Qhat onto
// [0, 1] by the range of its siblings' values (or of the returns seen in this search, or divides
// by the model's reward range); w2 follows appendix J's rule from the radii of this step's initial
// spheres unless set. The executed action comes from the root sphere of highest Qhat (the paper's
// rule; or the most visited one). With search.threads > 1, that many
// independent trees search the same belief from the same initial spheres (root parallelism) and
// the root statistics of spheres descending from the same initial sphere are merged.
//
// That is the paper's tree (KctOptions::point_children = false). By default every point drawn is
// an action node of its own (point children): the tree picks among a node's points by U, widens
// the node progressively, and asks the spheres where the next point goes; a sphere's refinement
// regroups its points by k-means and copies nothing. The spheres keep the paper's role (where to
// look, how finely), the points keep what each action earned.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/belief_tree.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/clustering.h"
#include "npfkct/solver/hybrid.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/planner_base.h"

namespace npfkct {

/// Options of the k-center clustering tree. Defaults follow the paper's appendix J where it gives
/// a value or a rule; the rest are marked.
struct KctOptions {
  /// Depth, horizon, reuse, particles, threads and belief update settings.
  SearchOptions search;
  /// Clusters per refinement (k).
  int k = 3;
  /// UCB coefficient w1 (on normalised values).
  double w1 = std::numbers::sqrt2;
  /// Range coefficient w2; NaN: appendix J's rule, w2 = w2_ratio / (mean radius of this step's
  /// initial spheres), so that the range term of a typical initial sphere is w2_ratio, comparable
  /// to the other two terms.
  double w2 = std::numeric_limits<double>::quiet_NaN();
  /// The range term of a sphere of the mean initial radius under the appendix J rule.
  double w2_ratio = 0.5;
  /// How Qhat is mapped for U.
  enum class Normalization {
    kObservedRange,  ///< (Qhat - min) / (max - min) over the returns seen in this search.
    kValueScale,     ///< Qhat / value_scale (NaN scale: the model's reward range).
    kSiblingRange,   ///< (Qhat - min) / (max - min) over the visited entries of the node.
  };
  Normalization normalization = Normalization::kSiblingRange;
  /// Scale dividing Qhat in U with kValueScale; NaN means the model's reward range.
  double value_scale = std::numeric_limits<double>::quiet_NaN();
  /// Refinement exploration constant C_r: refine once N_a >= 1 / (C_r range^2). NaN: appendix J's
  /// rule, C_r = 1 / (refine_share N_p mean(range)^2) with N_p the root belief's particles and the
  /// mean radius of this step's initial spheres, so that a sphere of that radius is refined after
  /// refine_share N_p visits. That rule was made for 60 s of planning per step; at budgets of a
  /// second it refines too slowly (object search, VDP Tag and the linear-quadratic test all do
  /// better at 0.05; docs/experiments.md, "Are kCT's defaults right?"), hence the fixed default.
  double c_r = 0.05;
  /// The share of N_p in appendix J's C_r rule (30% to 50% there).
  double refine_share = 0.4;
  /// Minimum radius D_lim: spheres of this range or less are never refined. The paper's 0.2 (its
  /// appendix J, for a Fetch's configuration) stops the spheres at a fifth of a radian, wider than
  /// the headings VDP Tag needs; with point children (below) a small sphere costs no subtree, so
  /// the default is a tenth of it. Object search keeps the paper's 0.2.
  double d_lim = 0.02;
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
  /// Which root sphere the executed action comes from.
  enum class FinalChoice {
    kMaxValue,     ///< The highest Qhat among visited spheres (paper, algorithm 1 line 12).
    kMostVisited,  ///< The most visited sphere (robust to spheres visited a handful of times).
    kLowerBound,   ///< The highest Qhat - final_lcb * sd / sqrt(N) (sd of the sphere's returns).
  };
  FinalChoice final_choice = FinalChoice::kMaxValue;
  /// Standard errors subtracted from Qhat by the kLowerBound final choice.
  double final_lcb = 1.0;
  /// How the executed action is drawn from the chosen root sphere.
  enum class FinalAction {
    kUniformInSphere,  ///< Uniform in the sphere, rejecting infeasible points (paper).
    kCenter,           ///< The sphere's center (when feasible).
    /// The maximiser of a quadratic fitted by least squares to the root's recorded (point,
    /// return) pairs near the chosen sphere (within regression_reach of its radii), kept within
    /// regression_trust radii of its center; kUniformInSphere's rule when fewer than three
    /// records per coefficient are near, the fit explains less than regression_min_r2 of the
    /// returns' variance, is not concave, or its point is not feasible. The sphere's points are
    /// few and its mean is noisy; the fit pools every record around it (docs/experiments.md,
    /// "Do the solver's planners match...").
    kRegression,
  };
  FinalAction final_action = FinalAction::kRegression;
  /// With kRegression: records within this many sphere radii of its center enter the fit.
  double regression_reach = 20.0;
  /// With kRegression: the fitted maximiser is kept within this many sphere radii of its center.
  double regression_trust = 10.0;
  /// With kRegression: the fit is used only when it explains this share of the returns' variance.
  double regression_min_r2 = 0.9;
  /// Where Action_sam draws the point of a sphere: uniformly in the sphere (the paper), or among
  /// the candidates (Net_sam's filtered samples) the sphere covers, uniformly in it when it
  /// covers none. The candidates are where the filter found efficient actions; a uniform draw
  /// also lands on the parts of the sphere between them.
  bool sample_candidates = true;
  /// Draws tried by Action_sam before it falls back to the center.
  int max_feasibility_tries = 100;
  /// Draws tried inside the tree to find a point of a sphere that passes the model's
  /// reasonability check (1: no check in the tree, the paper's behaviour).
  int tree_feasibility_tries = 1;
  /// Point children: every point the search draws is an action node with its own subtree, and
  /// the tree picks among all of a node's points by U (one bandit per node), widening the node
  /// progressively (a new point while it has fewer than point_k N^point_alpha); the spheres decide
  /// where a new point is drawn (U over the spheres with the range term, then Action_sam in the
  /// chosen one), and a refinement splits a sphere by k-means of its points and reassigns them,
  /// copying no subtree. The executed action is the root's most visited point or discrete action
  /// (a point moved, with kRegression, to the fitted maximiser around its sphere where the fit
  /// holds); final_choice decides only at a root without points. False: the paper's tree, where
  /// every point drawn in a sphere shares the sphere's subtree (docs/experiments.md, "kCT's
  /// defaults: point children").
  bool point_children = true;
  /// With point_children: the progressive widening's coefficient (default: POMCPOW's VDP Tag
  /// action widening, 30 N^(1/30)).
  double point_k = 30.0;
  /// With point_children: the progressive widening's exponent.
  double point_alpha = 1.0 / 30.0;
  /// Observation branching.
  ObservationWidening observations;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (Status s = search.Validate(); !s.ok()) return Prefixed("search", s);
    if (k < 2) return InvalidArgumentError("k must be >= 2");
    if (!(w1 >= 0.0) || !std::isfinite(w1)) return InvalidArgumentError("w1 must be >= 0");
    if (!std::isnan(w2) && !(w2 >= 0.0 && std::isfinite(w2))) {
      return InvalidArgumentError("w2 must be >= 0 (or NaN for appendix J's rule)");
    }
    if (!(w2_ratio >= 0.0) || !std::isfinite(w2_ratio)) {
      return InvalidArgumentError("w2_ratio must be >= 0");
    }
    if (!std::isnan(value_scale) && !(value_scale > 0.0 && std::isfinite(value_scale))) {
      return InvalidArgumentError("value_scale must be > 0 (or NaN for the reward range)");
    }
    if (!std::isnan(c_r) && !(c_r > 0.0 && std::isfinite(c_r))) {
      return InvalidArgumentError("c_r must be > 0 (or NaN for appendix J's rule)");
    }
    if (!(refine_share > 0.0 && refine_share <= 10.0)) {
      return InvalidArgumentError("refine_share must be in (0, 10]");
    }
    if (!(d_lim > 0.0) || !std::isfinite(d_lim)) return InvalidArgumentError("d_lim must be > 0");
    if (!(w2_bar >= 0.0 && w2_bar < w1_bar && w1_bar <= 1.0)) {
      return InvalidArgumentError("w1_bar and w2_bar must satisfy 0 <= w2_bar < w1_bar <= 1");
    }
    if (!(final_lcb >= 0.0 && final_lcb <= 100.0)) {
      return InvalidArgumentError("final_lcb must be in [0, 100]");
    }
    if (!(regression_reach > 0.0 && regression_reach <= 1000.0)) {
      return InvalidArgumentError("regression_reach must be in (0, 1000]");
    }
    if (!(regression_trust >= 0.0 && regression_trust <= 1000.0)) {
      return InvalidArgumentError("regression_trust must be in [0, 1000]");
    }
    if (!(regression_min_r2 >= 0.0 && regression_min_r2 <= 1.0)) {
      return InvalidArgumentError("regression_min_r2 must be in [0, 1]");
    }
    if (num_candidates < 1 || num_candidates > 100000) {
      return InvalidArgumentError("num_candidates must be in [1, 100000]");
    }
    if (max_initial_clusters < 1 || max_initial_clusters > 64) {
      return InvalidArgumentError("max_initial_clusters must be in [1, 64]");
    }
    if (max_feasibility_tries < 1 || max_feasibility_tries > 100000) {
      return InvalidArgumentError("max_feasibility_tries must be in [1, 100000]");
    }
    if (tree_feasibility_tries < 1 || tree_feasibility_tries > 1000) {
      return InvalidArgumentError("tree_feasibility_tries must be in [1, 1000]");
    }
    if (!(point_k > 0.0 && point_k <= 1000.0)) {
      return InvalidArgumentError("point_k must be in (0, 1000]");
    }
    if (!(point_alpha >= 0.0 && point_alpha <= 1.0)) {
      return InvalidArgumentError("point_alpha must be in [0, 1]");
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
  /// The candidates the sphere was built from (points of its kind's box).
  std::shared_ptr<const std::vector<ActionVec>> members;
};

/// The parameters a kCT search actually used (appendix J's rules resolved), Ceres style.
struct KctUsed {
  double w2 = 0.0;
  double c_r = 0.0;
  double value_scale = 0.0;  ///< With kValueScale.
  double mean_initial_range = 0.0;
  int threads = 1;
  /// Every value as (name, value), for reports.
  std::vector<std::pair<std::string, double>> Values() const {
    return {{"w2", w2},
            {"c_r", c_r},
            {"value_scale", value_scale},
            {"mean_initial_range", mean_initial_range},
            {"threads", static_cast<double>(threads)}};
  }
};

/// The k-center clustering tree planner over a hybrid-action model. The model must outlive it.
template <HybridActionModel M>
class KCenterTree : public PlannerBase<KCenterTree<M>, M, KctOptions> {
  using Base = PlannerBase<KCenterTree<M>, M, KctOptions>;
  NPFKCT_PLANNER_INTERFACE(Base);

 public:
  /// A planner whose candidates come from `sampler` (uniform when null).
  KCenterTree(const M& model, KctOptions options,
              std::shared_ptr<CandidateSampler<State>> sampler = nullptr)
      : Base(model, std::move(options)), sampler_(std::move(sampler)) {
    if (!sampler_) sampler_ = std::make_shared<UniformCandidateSampler<State>>();
    workers_.resize(std::clamp(options_.search.threads, 1, 64));
  }

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
  /// The parameters the last Plan() used.
  const KctUsed& used() const { return used_; }

  /// Plans until `stop` says so (algorithm 1, lines 3-18) and recommends an executable action.
  /// Advance (filtering, algorithm 1, line 20) keeps every worker's subtree under the executed
  /// sphere and the real observation.
  Decision<Action> Plan(const TerminationCondition& stop, Rng& rng);

  /// Nodes in the trees (all workers).
  int64_t TreeSize() const {
    int64_t n = 0;
    for (const Worker& w : workers_) n += w.tree.size();
    return n;
  }
  /// Root visits (all workers).
  int64_t RootVisits() const {
    int64_t n = 0;
    for (const Worker& w : workers_) n += w.tree.root >= 0 ? w.tree.obs[w.tree.root].n : 0;
    return n;
  }

  /// Verifies the statistics of every node below every root: N(node) = sum of N(node, a);
  /// N(node, a) equals the episodes recorded in the sphere; with Monte-Carlo backup Qhat is their
  /// mean return; with exact observation matching every child's visit count matches the recorded
  /// episodes; every continuous sphere's range is at least D_lim. Used by tests after refinements.
  Status CheckInvariants() const;

  /// The first search tree's root list: (sphere, visits, value) per entry.
  std::vector<std::pair<Hypersphere, RootActionStat<Action>>> RootList() const;

 private:
  // Root entries the decision passes over at most when none of their points is executable.
  static constexpr int kMaxFinalEntries = 8;

  // Per action node: the sphere's range (the center is action.x), where it came from, and the
  // episodes that chose it.
  struct Sphere {
    double range = 0.0;
    // At the root: which of this step's initial entries it descends from (merging the workers'
    // statistics), or a negative worker-unique code for entries kept from earlier steps.
    int64_t origin = -1;
    // A worker-unique id of a sphere (> 0), and for a point child the id of its sphere (0: not a
    // point). Ids, unlike node indices, survive the compaction of a kept subtree.
    int64_t sid = 0;
    int64_t point_of = 0;
    // The candidates it covers (shared by the copies of an initial sphere); null: none.
    std::shared_ptr<const std::vector<ActionVec>> members;
    std::vector<uint32_t> ids;     // episode ids, increasing
    std::vector<double> returns;   // discounted return from the node
    std::vector<double> rewards;   // immediate reward
    std::vector<int32_t> entries;  // children entry reached, -1 when terminal
    std::vector<float> points;     // executed point, dim floats per record (continuous kinds)
  };
  using Tree = BeliefTree<M, Sphere>;

  // One search: a tree and what a thread needs to grow it.
  struct Worker {
    Tree tree;
    Rng rng;
    uint32_t next_episode = 1;
    int max_depth = 0;
    int64_t refinements = 0;
    int64_t simulations = 0;
    double cpu_ms = 0.0;  // CPU time of this worker's thread in the last call (threads > 1)
    double vmin = std::numeric_limits<double>::infinity();
    double vmax = -std::numeric_limits<double>::infinity();
    int last_entry = -1;
    int64_t next_sid = 1;
    Status status;
    std::vector<int> scratch;
    const TerminationCondition* stop = nullptr;  // this worker's, while Plan() runs
  };

  // Every worker keeps its subtree under (a, o), or clears its tree.
  void KeepChild(const Action& a, const Observation& o) {
    for (Worker& w : workers_) KeepChild(w, a, o);
  }

  bool HasTree() const { return workers_[0].tree.root >= 0; }
  void ClearTree();

  // Plan's first stage (after Begin dropped a tree that is not reused): builds the spheres of the
  // kinds legal at the root (Net_sam + k-clustering), resolves the parameters and readies every
  // worker's root.
  Status PrepareWorkers(const TerminationCondition& stop, Rng& rng, Decision<Action>* d);

  // Plan's second stage: the episodes, on the calling thread or on one thread per worker.
  void Search(const TerminationCondition& stop);

  // Plan's last stage: the decision from the workers' root statistics, and its statistics.
  Status Decide(const TerminationCondition& stop, Rng& rng, Decision<Action>* d);

  void RunEpisodes(Worker& w, const TerminationCondition& stop);

  // w2 and C_r by appendix J's rules from this step's initial spheres, unless set.
  void ResolveParameters();

  void KeepChild(Worker& w, const Action& a, const Observation& o);

  // The origin code of this step's entry `index` of kind `kind` (index -1: a discrete kind).
  static int64_t Origin(int kind, int index) { return int64_t{kind} * 1000003 + index + 1; }

  // Entries kept from earlier steps become worker-unique groups.
  void ForgetRootOrigins(Worker& w, int worker) {
    for (int ai : w.tree.obs[w.tree.root].actions) {
      w.tree.act[ai].data.origin = -1 - (int64_t{worker} << 32) - ai;
    }
  }

  // The candidates and initial spheres of a kind, once per Plan(). Sampling ends early, with the
  // points found so far, when `stop` says the search must stop; a cancellation ends the plan.
  Status EnsureSpheres(int kind, Rng& rng, const TerminationCondition& stop);

  // The spheres of a kind, under the lock (a deep node may ask for a kind first seen there).
  std::vector<Hypersphere> SpheresOf(const Worker& w, int kind, Rng& rng, Status* status) {
    *status = EnsureSpheres(kind, rng, *w.stop);
    std::lock_guard<std::mutex> lock(spheres_mutex_);
    return spheres_[kind];
  }

  Status InitList(Worker& w, int node, const State& s, Rng& rng);

  void AddSphere(Worker& w, int node, const Hypersphere& h, int64_t origin);

  // Update(T, C_a, R_a): the new spheres join every initialised list holding that kind.
  void AddSpheresToTree(Worker& w);

  // A reused root may lack kinds that became legal (e.g. objects detected since): add them.
  Status EnsureRootKinds(Worker& w, const State& s, Rng& rng);

  // The rollout policy's action as a root sphere of radius D_lim, tried first.
  void AddRolloutFirst(Worker& w, Rng& rng);

  double Normalized(const Worker& w, double q) const;

  // The entry of `node` of highest U: among its spheres and discrete actions, or with `points`
  // among its points and discrete actions (a point's range, 0, adds no range term).
  int Select(const Worker& w, int node, bool points = false) const;

  // The sphere of point `pi` of `node` (-1: none).
  int SphereOf(const Tree& tree, int node, int pi) const;

  // With point_children: the action node to descend (a point, or a discrete entry) and in *sphere
  // the entry whose statistics it also updates (itself for a discrete entry).
  int SelectFlat(Worker& w, int node, const State& s, int* sphere);

  // With point_children: Refine by k-means of the sphere's points; returns false when not due.
  bool RefinePoints(Worker& w, int node, int ai);

  // The most visited root entry for which take(entry) holds and which is feasible in `s`, ties
  // to the higher Qhat (-1: none visited).
  template <class Take>
  int MostVisitedAtRoot(const Worker& w, const State& s, Take take) const;

  double VStar(const Tree& tree, int node) const;

  HybridAction SampleInSphere(const Tree& tree, int ai, Rng& rng) const;

  // A point of the sphere; with tree_feasibility_tries > 1 one that passes the reasonability
  // check in state s (the last draw when none passes, so that the model's penalty teaches the tree
  // to avoid the sphere).
  HybridAction SampleFeasibleInSphere(const Tree& tree, int ai, const State& s, Rng& rng) const;

  // Episode_simulation (algorithm 2). Returns the discounted return of the episode from `node`.
  double Simulate(Worker& w, const State& s, int node, int depth, uint32_t episode);

  // Refine (algorithm 3).
  void Refine(Worker& w, int node, int ai);

  static bool Contains(const std::vector<uint32_t>& sorted, uint32_t id) {
    return std::binary_search(sorted.begin(), sorted.end(), id);
  }

  // The candidates a refined sphere covered, each to the nearest new center (null: none).
  static std::vector<std::shared_ptr<const std::vector<ActionVec>>> SplitMembers(
      const BoxSpace& box, const std::shared_ptr<const std::vector<ActionVec>>& parent,
      const std::vector<Cluster>& clusters);

  // Copies action node `ai` and its subtree keeping only the episodes in `keep`; returns the new
  // (unattached) action node.
  int CopyAction(Worker& w, int ai, const std::vector<uint32_t>& keep);

  // Copies observation node `node` and its subtree keeping only the episodes in `keep`.
  int CopyObs(Worker& w, int node, const std::vector<uint32_t>& keep);

  // Merges the workers' root statistics by origin and picks the entry to execute: the group
  // chosen by the final-choice rule, then its most visited entry.
  bool ChooseRootEntry(const std::set<std::pair<int, int>>& excluded, int* worker,
                       int* entry) const;

  // Action_sam with the reasonability check: a feasible point drawn uniformly in the sphere (or
  // its center), else the best-returning feasible point tried in it; false when there is none.
  bool SampleExecutable(const Worker& w, int ai, const State& s, Rng& rng, HybridAction* out) const;
  bool RegressedPoint(const Worker& w, int ai, const State& s, HybridAction* out) const;

  // Among the points executed in a sphere, the feasible one with the best mean return over the
  // episodes that executed it, counting only points executed at least twice when any was.
  bool BestTriedPoint(const typename Tree::ActNode& an, const State& s, HybridAction* out) const;

  // The root entry an executed action came from: the last decision's sphere when it contains the
  // action, else the closest containing sphere of the same kind.
  int EntryContaining(const Worker& w, const HybridAction& a) const;

  Status CheckTree(const Tree& tree) const;

  std::shared_ptr<CandidateSampler<State>> sampler_;
  std::vector<Worker> workers_;
  std::map<int, std::vector<Hypersphere>> spheres_;
  std::mutex spheres_mutex_;
  CandidateStats candidate_stats_;
  KctUsed used_;
  Hypersphere last_sphere_;
};

}  // namespace npfkct

// The definitions of KCenterTree's members (the search itself).
#include "npfkct/solver/internal/kct_impl.h"  // IWYU pragma: export
