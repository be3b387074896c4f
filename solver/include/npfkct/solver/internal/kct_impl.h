// The k-center clustering tree's search, out of the public header (Ceres style): the definitions
// of KCenterTree's members (kct.h declares them and includes this file at its end). Nothing here
// is part of the solver's interface; include npfkct/solver/kct.h instead.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <numbers>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "npfkct/solver/kct.h"

namespace npfkct {

template <HybridActionModel M>
auto KCenterTree<M>::Plan(const TerminationCondition& stop, Rng& rng) -> Decision<Action> {
  Decision<Action> d;
  if (Status s = this->Begin(stop, &d); !s.ok()) return Base::Fail(std::move(d), std::move(s));
  if (Status s = PrepareWorkers(stop, rng, &d); !s.ok()) {
    return Base::Fail(std::move(d), std::move(s));
  }
  Search(stop);
  for (Worker& w : workers_) {
    if (!w.status.ok()) return Base::Fail(std::move(d), w.status);
    d.stats.simulations += w.simulations;
    d.stats.refinements += w.refinements;
    d.stats.max_depth = std::max(d.stats.max_depth, w.max_depth);
  }

  if (Status s = Decide(stop, rng, &d); !s.ok()) return Base::Fail(std::move(d), std::move(s));
  d = FinishSearch(std::move(d), stop);
  if (workers_.size() > 1) {
    for (const Worker& w : workers_) d.stats.cpu_ms += w.cpu_ms;  // every search thread's
  }
  return d;
}

template <HybridActionModel M>
Status KCenterTree<M>::CheckInvariants() const {
  for (const Worker& w : workers_) {
    if (Status s = CheckTree(w.tree); !s.ok()) return s;
  }
  return OkStatus();
}

template <HybridActionModel M>
auto KCenterTree<M>::RootList() const
    -> std::vector<std::pair<Hypersphere, RootActionStat<Action>>> {
  std::vector<std::pair<Hypersphere, RootActionStat<Action>>> out;
  const Tree& tree = workers_[0].tree;
  if (tree.root < 0) return out;
  for (int ai : tree.obs[tree.root].actions) {
    const auto& an = tree.act[ai];
    if (an.data.point_of != 0) continue;
    out.push_back(
        {{an.action.kind, an.action.x, an.data.range, an.data.members}, {an.action, an.n, an.q}});
  }
  return out;
}

template <HybridActionModel M>
void KCenterTree<M>::ClearTree() {
  for (Worker& w : workers_) {
    w.tree.Clear();
    w.last_entry = -1;
    w.vmin = std::numeric_limits<double>::infinity();
    w.vmax = -std::numeric_limits<double>::infinity();
  }
}

template <HybridActionModel M>
Status KCenterTree<M>::PrepareWorkers(const TerminationCondition& stop, Rng& rng,
                                      Decision<Action>* d) {
  candidate_stats_ = {};
  spheres_.clear();
  // Net_sam + k-clustering for the kinds legal at the root, then Update(T, C_a, R_a).
  std::vector<int> kinds;
  model_.ActionKinds(belief_.Sample(rng), &kinds);
  for (int kind : kinds) {
    if (Status s = EnsureSpheres(kind, rng, stop); !s.ok()) {
      return s;
    }
  }
  ResolveParameters();
  for (int t = 0; t < static_cast<int>(workers_.size()); ++t) {
    Worker& w = workers_[t];
    w.rng = rng.Split();
    w.max_depth = 0;
    w.refinements = 0;
    w.simulations = 0;
    w.status = OkStatus();
    w.stop = &stop;
    if (w.tree.root < 0) {
      w.tree.root = w.tree.NewObsNode();
    } else {
      ForgetRootOrigins(w, t);
      AddSpheresToTree(w);
      if (Status s = EnsureRootKinds(w, belief_.Sample(rng), rng); !s.ok()) {
        return s;
      }
    }
    d->stats.reused_visits += w.tree.obs[w.tree.root].n;
    if (w.tree.obs[w.tree.root].actions.empty()) {
      if (Status s = InitList(w, w.tree.root, belief_.Sample(rng), rng); !s.ok()) {
        return s;
      }
    }
    if (options_.search.rollout_first) AddRolloutFirst(w, rng);
  }

  return OkStatus();
}

template <HybridActionModel M>
void KCenterTree<M>::Search(const TerminationCondition& stop) {
  // The search: with one thread on the calling thread under the caller's condition. With
  // several, every worker (worker 0 on the calling thread) gets a condition of its own with
  // what is left of the caller's wall and CPU budget (each on its own thread's CPU clock), its
  // share of the simulations, and the caller's cancellation and resource limit (polled by the
  // workers: the caller's condition is not read while they run).
  const int threads = static_cast<int>(workers_.size());
  if (threads == 1) {
    RunEpisodes(workers_[0], stop);
  } else {
    Budget left = stop.budget();
    if (left.time_ms > 0.0) left.time_ms = std::max(left.time_ms - stop.ElapsedMs(), 1e-3);
    if (left.cpu_ms > 0.0) left.cpu_ms = std::max(left.cpu_ms - stop.CpuMs(), 1e-3);
    if (left.max_simulations > 0) {
      left.max_simulations = (left.max_simulations + threads - 1) / threads;
    }
    auto run = [this, left, &stop](int t) {
      TerminationCondition local(
          left, [&stop] { return stop.Interrupted(); }, 1.0);
      RunEpisodes(workers_[t], local);
      workers_[t].cpu_ms = t == 0 ? 0.0 : local.CpuMs();  // the caller's own clock counts 0
    };
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(run, t);
    run(0);
    for (std::thread& th : pool) th.join();
  }
}

template <HybridActionModel M>
Status KCenterTree<M>::Decide(const TerminationCondition& stop, Rng& rng, Decision<Action>* d) {
  // The decision: merge the root statistics of the workers and pick a sphere (algorithm 1,
  // line 12), then Action_sam + Reasonability_check (lines 13-18).
  // A sphere none of whose points passes the check is passed over for the next best, up to
  // kMaxFinalEntries of them: in a world where hardly any configuration is feasible, a root of
  // thousands of spheres cost thousands of times one sphere's draws after the budget (a 200 ms
  // plan ran 35 s with max_feasibility_tries 10,000). A cancelled plan stops passing over.
  const State& s0 = belief_.Sample(rng);
  int chosen_worker = 0, best = -1, point = -1;
  std::set<std::pair<int, int>> excluded;
  bool executable = false;
  if (options_.point_children) {
    // The most visited point or discrete action of the root (first worker's tree); a point's
    // sphere is the entry. Without points (discrete actions only) final_choice decides.
    const Worker& w = workers_[0];
    const auto& root = w.tree.obs[w.tree.root].actions;
    const bool points = std::any_of(root.begin(), root.end(), [&](int bi) {
      return w.tree.act[bi].data.point_of != 0 && w.tree.act[bi].n > 0;
    });
    const int top = !points ? -1 : MostVisitedAtRoot(w, s0, [&](const auto& bn) {
      return bn.data.point_of != 0 || model_.KindSpace(bn.action.kind).dim() == 0;
    });
    if (top >= 0 && w.tree.act[top].data.point_of == 0) {
      best = top;
      d->action = w.tree.act[top].action;
      executable = true;
    } else if (top >= 0) {
      point = top;
      best = SphereOf(w.tree, w.tree.root, point);
      d->action = w.tree.act[point].action;
      executable = best >= 0;
      if (!executable) point = -1;
      // A quadratic fitted to the records around the point's sphere, where it explains them,
      // finds the optimum between the points (the linear-quadratic benchmark's first action).
      HybridAction regressed;
      if (executable && options_.final_action == KctOptions::FinalAction::kRegression &&
          RegressedPoint(w, best, s0, &regressed)) {
        d->action = std::move(regressed);
      }
    }
  }
  for (int tried = 0;
       !executable && tried < kMaxFinalEntries && ChooseRootEntry(excluded, &chosen_worker, &best);
       ++tried) {
    if (options_.point_children) {
      const int64_t sid = workers_[chosen_worker].tree.act[best].data.sid;
      point = MostVisitedAtRoot(workers_[chosen_worker], s0,
                                [sid](const auto& bn) { return bn.data.point_of == sid; });
      if (point >= 0) {
        d->action = workers_[chosen_worker].tree.act[point].action;
        executable = true;
        break;
      }
    }
    if (SampleExecutable(workers_[chosen_worker], best, s0, rng, &d->action)) {
      executable = true;
      break;
    }
    excluded.insert({chosen_worker, best});
    if (stop.Interrupted()) break;
  }
  // Past them, the visited root sphere of the highest Qhat whose center is executable (one
  // check per sphere, in one pass): a root where only a sliver of the space is feasible still
  // gets an executable action.
  if (!executable && !stop.Interrupted()) {
    double best_q = -std::numeric_limits<double>::infinity();
    for (int t = 0; t < static_cast<int>(workers_.size()); ++t) {
      const Tree& tree = workers_[t].tree;
      if (tree.root < 0) continue;
      for (int ai : tree.obs[tree.root].actions) {
        const auto& entry = tree.act[ai];
        if (entry.n == 0 || entry.q <= best_q || excluded.count({t, ai}) ||
            entry.data.point_of != 0 || !IsFeasibleAction(model_, s0, entry.action)) {
          continue;
        }
        best_q = entry.q;
        chosen_worker = t;
        best = ai;
        d->action = entry.action;
        executable = true;
      }
    }
  }
  if (!executable && !ChooseRootEntry({}, &chosen_worker, &best)) {
    return FailedPreconditionError("no legal action at the root");
  }
  Worker& cw = workers_[chosen_worker];
  const auto& an = cw.tree.act[best];
  if (!executable) d->action = an.action;
  d->value = point >= 0 ? cw.tree.act[point].q : an.q;
  for (int ai : cw.tree.obs[cw.tree.root].actions) {
    const auto& e = cw.tree.act[ai];
    if (e.data.point_of == 0) d->root.push_back({e.action, e.n, e.q});
  }
  for (const Worker& w : workers_) {
    d->stats.tree_nodes += w.tree.size();
    d->stats.root_visits += w.tree.obs[w.tree.root].n;
  }
  d->stats.root_actions = static_cast<int>(cw.tree.obs[cw.tree.root].actions.size());
  last_sphere_ = {an.action.kind, an.action.x, an.data.range, an.data.members};
  for (Worker& w : workers_) w.last_entry = -1;
  cw.last_entry = point >= 0 ? point : best;
  return OkStatus();
}

template <HybridActionModel M>
void KCenterTree<M>::RunEpisodes(Worker& w, const TerminationCondition& stop) {
  w.stop = &stop;
  int64_t sims = 0;
  while (!stop.ShouldStop(sims)) {
    const State& s = belief_.Sample(w.rng);
    if (!IsTerminalState(model_, s)) {
      Simulate(w, s, w.tree.root, 0, w.next_episode++);
      if (!w.status.ok()) break;
    }
    ++sims;
  }
  w.simulations = sims;
  w.stop = nullptr;
}

template <HybridActionModel M>
void KCenterTree<M>::ResolveParameters() {
  double sum = 0.0;
  int count = 0;
  for (const auto& [kind, list] : spheres_) {
    for (const Hypersphere& h : list) {
      sum += h.range;
      ++count;
    }
  }
  used_.mean_initial_range = count > 0 ? sum / count : options_.d_lim;
  const double mean = std::max(used_.mean_initial_range, options_.d_lim);
  used_.w2 = std::isnan(options_.w2) ? options_.w2_ratio / mean : options_.w2;
  used_.c_r = std::isnan(options_.c_r)
                  ? 1.0 / (options_.refine_share * std::max(1, belief_.size()) * mean * mean)
                  : options_.c_r;
  used_.value_scale =
      std::isnan(options_.value_scale) ? RewardRange(model_, 1.0) : options_.value_scale;
  used_.threads = static_cast<int>(workers_.size());
}

template <HybridActionModel M>
void KCenterTree<M>::KeepChild(Worker& w, const Action& a, const Observation& o) {
  int next = -1;
  if (options_.search.reuse_tree && w.tree.root >= 0) {
    const int ai = EntryContaining(w, a);
    if (ai >= 0) next = w.tree.act[ai].children.Find(o, HashObservation(o));
  }
  w.last_entry = -1;
  if (next < 0) {
    w.tree.Clear();
    w.vmin = std::numeric_limits<double>::infinity();
    w.vmax = -std::numeric_limits<double>::infinity();
  } else {
    w.tree.KeepSubtree(next);
  }
}

template <HybridActionModel M>
Status KCenterTree<M>::EnsureSpheres(int kind, Rng& rng, const TerminationCondition& stop) {
  std::lock_guard<std::mutex> lock(spheres_mutex_);
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
    Status s = sampler_->Sample(belief_, kind, box, options_.num_candidates, stop, rng, &batch,
                                &candidate_stats_);
    if (!s.ok()) {
      candidate_stats_.elapsed_ms += MillisSince(t0);
      return s;
    }
    for (size_t i = 0; i < batch.size(); ++i) {
      const ActionVec& p = batch[i];
      if (!box.Contains(p)) {
        return InternalError("candidate sampler returned a point outside the action box");
      }
      if (i % 64 == 63 && stop.ShouldStop(0)) break;
      if (IsFeasibleAction(model_, belief_.Sample(rng), HybridAction{kind, p})) {
        points.push_back(p);
      }
    }
    // A sampler that returns fewer than asked (the neural filter) has nothing more to offer.
    if (static_cast<int>(batch.size()) < options_.num_candidates || stop.ShouldStop(0)) break;
  }
  candidate_stats_.elapsed_ms += MillisSince(t0);
  if (stop.cancelled()) return CancelledError("planning was cancelled");
  if (points.empty()) {
    // Nothing usable: fall back to one sphere around the whole box.
    out.push_back({kind, box.Clamp((box.lower() + box.upper()) / 2.0),
                   std::max(box.Diameter() / 2.0, options_.d_lim), nullptr});
    return OkStatus();
  }
  const std::vector<Cluster> clusters = ClusterByElbow(box, points, options_.max_initial_clusters,
                                                       rng, [&stop] { return stop.ShouldStop(0); });
  if (stop.cancelled()) return CancelledError("planning was cancelled");
  for (const Cluster& c : clusters) {
    auto members = std::make_shared<std::vector<ActionVec>>();
    for (int m : c.members) members->push_back(points[m]);
    out.push_back({kind, c.center, std::max(c.radius, options_.d_lim), std::move(members)});
  }
  return OkStatus();
}

template <HybridActionModel M>
Status KCenterTree<M>::InitList(Worker& w, int node, const State& s, Rng& rng) {
  model_.ActionKinds(s, &w.scratch);
  const std::vector<int> kinds = w.scratch;
  for (int kind : kinds) {
    Status st;
    const std::vector<Hypersphere> list = SpheresOf(w, kind, rng, &st);
    if (!st.ok()) return st;
    if (model_.KindSpace(kind).dim() == 0) {
      HybridAction a;
      a.kind = kind;
      Sphere data;
      data.origin = Origin(kind, -1);
      w.tree.NewActNode(node, std::move(a), std::move(data));
      continue;
    }
    for (size_t i = 0; i < list.size(); ++i) {
      AddSphere(w, node, list[i], Origin(kind, static_cast<int>(i)));
    }
  }
  return OkStatus();
}

template <HybridActionModel M>
void KCenterTree<M>::AddSphere(Worker& w, int node, const Hypersphere& h, int64_t origin) {
  HybridAction a;
  a.kind = h.kind;
  a.x = h.center;
  Sphere data;
  data.range = h.range;
  data.origin = origin;
  data.sid = w.next_sid++;
  data.members = h.members;
  w.tree.NewActNode(node, std::move(a), std::move(data));
}

template <HybridActionModel M>
void KCenterTree<M>::AddSpheresToTree(Worker& w) {
  const int num_nodes = static_cast<int>(w.tree.obs.size());
  for (int node = 0; node < num_nodes; ++node) {
    if (w.tree.obs[node].actions.empty()) continue;
    for (const auto& [kind, list] : spheres_) {
      const bool has_kind =
          std::any_of(w.tree.obs[node].actions.begin(), w.tree.obs[node].actions.end(),
                      [&](int ai) { return w.tree.act[ai].action.kind == kind; });
      if (!has_kind) continue;
      for (size_t i = 0; i < list.size(); ++i) {
        AddSphere(w, node, list[i], Origin(kind, static_cast<int>(i)));
      }
    }
  }
}

template <HybridActionModel M>
Status KCenterTree<M>::EnsureRootKinds(Worker& w, const State& s, Rng& rng) {
  const int root = w.tree.root;
  if (w.tree.obs[root].actions.empty()) return OkStatus();
  std::vector<int> kinds;
  model_.ActionKinds(s, &kinds);
  for (int kind : kinds) {
    const bool present =
        std::any_of(w.tree.obs[root].actions.begin(), w.tree.obs[root].actions.end(),
                    [&](int ai) { return w.tree.act[ai].action.kind == kind; });
    if (present) continue;
    if (model_.KindSpace(kind).dim() == 0) {
      HybridAction a;
      a.kind = kind;
      Sphere data;
      data.origin = Origin(kind, -1);
      w.tree.NewActNode(root, std::move(a), std::move(data));
      continue;
    }
    Status st;
    const std::vector<Hypersphere> list = SpheresOf(w, kind, rng, &st);
    if (!st.ok()) return st;
    for (size_t i = 0; i < list.size(); ++i) {
      AddSphere(w, root, list[i], Origin(kind, static_cast<int>(i)));
    }
  }
  return OkStatus();
}

template <HybridActionModel M>
void KCenterTree<M>::AddRolloutFirst(Worker& w, Rng& rng) {
  if constexpr (requires(const State& s) {
                  { model_.RolloutAction(s, rng) } -> std::same_as<HybridAction>;
                }) {
    const HybridAction a = RolloutFirstAction(model_, belief_, belief_.Sample(rng), rng);
    if (model_.KindSpace(a.kind).dim() == 0) return;
    AddSphere(w, w.tree.root, {a.kind, a.x, options_.d_lim, nullptr}, Origin(a.kind, 999999));
    // Move it to the front so that it is the first untried entry U picks.
    auto& list = w.tree.obs[w.tree.root].actions;
    std::rotate(list.rbegin(), list.rbegin() + 1, list.rend());
  }
}

template <HybridActionModel M>
double KCenterTree<M>::Normalized(const Worker& w, double q) const {
  if (options_.normalization == KctOptions::Normalization::kValueScale) {
    return q / used_.value_scale;
  }
  if (!(w.vmax > w.vmin)) return 0.0;
  return (q - w.vmin) / (w.vmax - w.vmin);
}

template <HybridActionModel M>
int KCenterTree<M>::Select(const Worker& w, int node, bool points) const {
  const auto& on = w.tree.obs[node];
  const auto take = [&](const auto& an) {
    return points ? an.data.point_of != 0 || model_.KindSpace(an.action.kind).dim() == 0
                  : an.data.point_of == 0;
  };
  const double log_n = std::log(static_cast<double>(std::max<int64_t>(on.n, 1)));
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  if (options_.normalization == KctOptions::Normalization::kSiblingRange) {
    for (int ai : on.actions) {
      if (w.tree.act[ai].n == 0 || !take(w.tree.act[ai])) continue;
      lo = std::min(lo, w.tree.act[ai].q);
      hi = std::max(hi, w.tree.act[ai].q);
    }
  }
  int best = -1;
  double best_score = -std::numeric_limits<double>::infinity();
  for (int ai : on.actions) {
    const auto& an = w.tree.act[ai];
    if (!take(an)) continue;
    const double q = options_.normalization == KctOptions::Normalization::kSiblingRange
                         ? (hi > lo ? (an.q - lo) / (hi - lo) : 0.0)
                         : Normalized(w, an.q);
    const double score = Ucb1(q, an.n, log_n, options_.w1) + used_.w2 * an.data.range;
    if (best < 0 || score > best_score) {
      best_score = score;
      best = ai;
    }
  }
  return best;
}

template <HybridActionModel M>
int KCenterTree<M>::SelectFlat(Worker& w, int node, const State& s, int* sphere) {
  Tree& tree = w.tree;
  int points = 0;
  for (int bi : tree.obs[node].actions) {
    const auto& bn = tree.act[bi];
    if (bn.data.point_of != 0 || model_.KindSpace(bn.action.kind).dim() == 0) ++points;
  }
  const int64_t n = tree.obs[node].n;
  if (points < options_.point_k * std::pow(static_cast<double>(n + 1), options_.point_alpha)) {
    // Widen: a new point where U over the spheres says, after refining the sphere when due.
    int ai = Select(w, node);
    if (RefinePoints(w, node, ai)) ai = Select(w, node);
    *sphere = ai;
    if (model_.KindSpace(tree.act[ai].action.kind).dim() == 0) return ai;
    HybridAction a = SampleFeasibleInSphere(tree, ai, s, w.rng);
    Sphere data;
    data.origin = tree.act[ai].data.origin;
    data.point_of = tree.act[ai].data.sid;
    return tree.NewActNode(node, std::move(a), std::move(data));
  }
  const int best = Select(w, node, /*points=*/true);
  *sphere = tree.act[best].data.point_of != 0 ? SphereOf(tree, node, best) : best;
  return best;
}

template <HybridActionModel M>
int KCenterTree<M>::SphereOf(const Tree& tree, int node, int pi) const {
  int sphere = -1;
  for (int ai : tree.obs[node].actions) {
    const auto& an = tree.act[ai];
    if (an.data.point_of == 0 && an.data.sid == tree.act[pi].data.point_of) sphere = ai;
  }
  return sphere;
}

template <HybridActionModel M>
bool KCenterTree<M>::RefinePoints(Worker& w, int node, int ai) {
  Tree& tree = w.tree;
  const int kind = tree.act[ai].action.kind;
  const BoxSpace& box = model_.KindSpace(kind);
  const double range = tree.act[ai].data.range;
  if (box.dim() == 0 || !(range > options_.d_lim)) return false;
  if (static_cast<double>(tree.act[ai].n) < 1.0 / (used_.c_r * range * range)) return false;
  const int64_t sid = tree.act[ai].data.sid;
  std::vector<int> kids;
  std::vector<ActionVec> points;
  for (int bi : tree.obs[node].actions) {
    if (tree.act[bi].data.point_of != sid) continue;
    kids.push_back(bi);
    points.push_back(tree.act[bi].action.x);
  }
  if (static_cast<int>(points.size()) < options_.k) return false;
  const std::vector<Cluster> clusters =
      KMeans(box, points, options_.k, w.rng, [&w] { return w.stop->ShouldStop(0); });
  if (clusters.size() < 2) return false;
  const auto members = SplitMembers(box, tree.act[ai].data.members, clusters);
  const int64_t origin = tree.act[ai].data.origin;
  std::vector<int> entry(clusters.size(), ai);
  for (size_t j = 0; j < clusters.size(); ++j) {
    Sphere data;
    data.origin = origin;
    data.range = FLim(clusters[j].radius, range, options_);
    data.members = members[j];
    data.sid = w.next_sid++;
    if (j == 0) {
      tree.act[ai].action.x = clusters[0].center;
      tree.act[ai].data = std::move(data);
    } else {
      entry[j] = tree.NewActNode(node, HybridAction{kind, clusters[j].center}, std::move(data));
    }
  }
  // Each new sphere's statistics are its points' records, in episode order.
  const int dim = box.dim();
  const double gamma = model_.Discount();
  for (size_t j = 0; j < clusters.size(); ++j) {
    auto& sphere = tree.act[entry[j]];
    std::vector<std::pair<uint32_t, std::pair<int, int>>> order;  // (id, (kid, record))
    for (int m : clusters[j].members) {
      auto& point = tree.act[kids[m]];
      point.data.point_of = sphere.data.sid;
      for (size_t r = 0; r < point.data.ids.size(); ++r) {
        order.push_back({point.data.ids[r], {kids[m], static_cast<int>(r)}});
      }
    }
    std::sort(order.begin(), order.end());
    Sphere& sp = sphere.data;
    sphere.n = static_cast<int64_t>(order.size());
    sphere.q = 0.0;
    for (size_t i = 0; i < order.size(); ++i) {
      const auto& [kid, r] = order[i].second;
      const auto& src = tree.act[kid];
      sp.ids.push_back(order[i].first);
      sp.returns.push_back(src.data.returns[r]);
      sp.rewards.push_back(src.data.rewards[r]);
      sp.entries.push_back(-1);
      for (int d = 0; d < dim; ++d) sp.points.push_back(src.action.x[d]);
      double v = src.data.returns[r];
      if (options_.backup == KctOptions::Backup::kBellman) {
        const int e = src.data.entries[r];
        v = src.data.rewards[r] + (e < 0 ? 0.0 : gamma * VStar(tree, src.children.child(e)));
      }
      sphere.q += (v - sphere.q) / static_cast<double>(i + 1);
    }
  }
  ++w.refinements;
  return true;
}

template <HybridActionModel M>
template <class Take>
int KCenterTree<M>::MostVisitedAtRoot(const Worker& w, const State& s, Take take) const {
  int best = -1;
  for (int bi : w.tree.obs[w.tree.root].actions) {
    const auto& bn = w.tree.act[bi];
    if (!take(bn) || bn.n == 0) continue;
    if (best >= 0 &&
        (bn.n < w.tree.act[best].n || (bn.n == w.tree.act[best].n && bn.q <= w.tree.act[best].q))) {
      continue;
    }
    if (IsFeasibleAction(model_, s, bn.action)) best = bi;
  }
  return best;
}

template <HybridActionModel M>
double KCenterTree<M>::VStar(const Tree& tree, int node) const {
  double best = -std::numeric_limits<double>::infinity();
  for (int ai : tree.obs[node].actions) {
    if (tree.act[ai].n > 0 && tree.act[ai].data.point_of == 0) {
      best = std::max(best, tree.act[ai].q);
    }
  }
  return std::isfinite(best) ? best : tree.obs[node].leaf_value;
}

template <HybridActionModel M>
HybridAction KCenterTree<M>::SampleInSphere(const Tree& tree, int ai, Rng& rng) const {
  const auto& an = tree.act[ai];
  HybridAction a;
  a.kind = an.action.kind;
  const auto& members = an.data.members;
  if (options_.sample_candidates && members && !members->empty()) {
    a.x = (*members)[rng.UniformInt(static_cast<int64_t>(members->size()))];
  } else {
    a.x = model_.KindSpace(a.kind).SampleInBall(an.action.x, an.data.range, rng);
  }
  return a;
}

template <HybridActionModel M>
HybridAction KCenterTree<M>::SampleFeasibleInSphere(const Tree& tree, int ai, const State& s,
                                                    Rng& rng) const {
  HybridAction a = SampleInSphere(tree, ai, rng);
  if (model_.KindSpace(a.kind).dim() == 0) return a;
  for (int tries = 1; tries < options_.tree_feasibility_tries && !IsFeasibleAction(model_, s, a);
       ++tries) {
    a = SampleInSphere(tree, ai, rng);
  }
  return a;
}

template <HybridActionModel M>
double KCenterTree<M>::Simulate(Worker& w, const State& s, int node, int depth, uint32_t episode) {
  if (IsTerminalState(model_, s) || depth >= options_.search.max_depth ||
      std::pow(model_.Discount(), depth) < options_.search.discount_horizon) {
    return 0.0;
  }
  w.max_depth = std::max(w.max_depth, depth);
  if (w.tree.obs[node].actions.empty()) {
    if (Status st = InitList(w, node, s, w.rng); !st.ok()) {
      w.status = st;
      return 0.0;
    }
    if (w.tree.obs[node].actions.empty()) return 0.0;
  }
  int ai = -1;
  int pi = -1;  // the action node descended: the sphere, or its point child
  HybridAction executed;
  if (options_.point_children) {
    pi = SelectFlat(w, node, s, &ai);
    executed = w.tree.act[pi].action;
  } else {
    ai = Select(w, node);
    Refine(w, node, ai);
    pi = ai;
    executed = SampleFeasibleInSphere(w.tree, ai, s, w.rng);
  }
  auto t = w.tree.Descend(model_, pi, executed, s, options_.observations, episode, w.rng);
  const double gamma = model_.Discount();
  double total = t.reward;
  if (!t.terminal) {
    if (t.new_node) {
      const double v = LeafEstimate(model_, t.state, depth + 1, options_.search, w.rng, &w.scratch);
      w.tree.AddLeafValue(t.child, v);
      total += gamma * v;
    } else {
      total += gamma * Simulate(w, t.state, t.child, depth + 1, episode);
    }
  }
  // Backup (algorithm 6), of the sphere and of its point child; a sphere with point children
  // records no child entries (the subtree is the point's).
  ++w.tree.obs[node].n;
  const double target = options_.backup == KctOptions::Backup::kMonteCarlo
                            ? total
                            : t.reward + (t.terminal ? 0.0 : gamma * VStar(w.tree, t.child));
  for (int bi : {ai, pi}) {
    auto& an = w.tree.act[bi];
    ++an.n;
    an.q += (target - an.q) / static_cast<double>(an.n);
    w.vmin = std::min({w.vmin, total, an.q});
    w.vmax = std::max({w.vmax, total, an.q});
    Sphere& sp = an.data;
    sp.ids.push_back(episode);
    sp.returns.push_back(total);
    sp.rewards.push_back(t.reward);
    sp.entries.push_back(t.terminal || bi != pi ? -1 : t.entry);
    for (int i = 0; i < executed.x.size(); ++i) {
      sp.points.push_back(static_cast<float>(executed.x[i]));
    }
    if (pi == ai) break;
  }
  return total;
}

template <HybridActionModel M>
void KCenterTree<M>::Refine(Worker& w, int node, int ai) {
  Tree& tree = w.tree;
  const BoxSpace& box = model_.KindSpace(tree.act[ai].action.kind);
  const double range = tree.act[ai].data.range;
  const int dim = box.dim();
  if (dim == 0 || !(range > options_.d_lim)) return;
  if (static_cast<double>(tree.act[ai].n) < 1.0 / (used_.c_r * range * range)) return;
  const Sphere& data = tree.act[ai].data;
  const int n = static_cast<int>(data.ids.size());
  if (n < options_.k) return;
  std::vector<ActionVec> points(n, ActionVec(dim));
  for (int r = 0; r < n; ++r) {
    for (int i = 0; i < dim; ++i) points[r][i] = data.points[static_cast<size_t>(r) * dim + i];
  }
  // Cut short (a coarser split) when the search must stop.
  std::vector<Cluster> clusters =
      KMeans(box, points, options_.k, w.rng, [&w] { return w.stop->ShouldStop(0); });
  if (clusters.size() < 2) return;
  std::vector<std::vector<uint32_t>> ids(clusters.size());
  for (size_t j = 0; j < clusters.size(); ++j) {
    for (int m : clusters[j].members) ids[j].push_back(data.ids[m]);
    std::sort(ids[j].begin(), ids[j].end());
  }
  const auto members = SplitMembers(box, tree.act[ai].data.members, clusters);
  // New spheres 2..k get filtered copies of the subtree; sphere 1 replaces the original.
  for (size_t j = 1; j < clusters.size(); ++j) {
    const int copy = CopyAction(w, ai, ids[j]);
    tree.act[copy].action.x = clusters[j].center;
    tree.act[copy].data.range = FLim(clusters[j].radius, range, options_);
    tree.act[copy].data.members = members[j];
    tree.act[copy].data.sid = w.next_sid++;
    tree.obs[node].actions.push_back(copy);
  }
  const int first = CopyAction(w, ai, ids[0]);
  tree.act[ai] = std::move(tree.act[first]);
  tree.act[first] = {};
  tree.act[ai].action.x = clusters[0].center;
  tree.act[ai].data.range = FLim(clusters[0].radius, range, options_);
  tree.act[ai].data.members = members[0];
  tree.act[ai].data.sid = w.next_sid++;
  ++w.refinements;
}

template <HybridActionModel M>
auto KCenterTree<M>::SplitMembers(const BoxSpace& box,
                                  const std::shared_ptr<const std::vector<ActionVec>>& parent,
                                  const std::vector<Cluster>& clusters)
    -> std::vector<std::shared_ptr<const std::vector<ActionVec>>> {
  std::vector<std::shared_ptr<const std::vector<ActionVec>>> members(clusters.size());
  if (!parent || parent->empty()) return members;
  std::vector<std::vector<ActionVec>> split(clusters.size());
  for (const ActionVec& m : *parent) {
    size_t nearest = 0;
    double best = std::numeric_limits<double>::infinity();
    for (size_t j = 0; j < clusters.size(); ++j) {
      const double d = box.SquaredDistance(m, clusters[j].center);
      if (d < best) {
        best = d;
        nearest = j;
      }
    }
    split[nearest].push_back(m);
  }
  for (size_t j = 0; j < clusters.size(); ++j) {
    if (!split[j].empty()) {
      members[j] = std::make_shared<const std::vector<ActionVec>>(std::move(split[j]));
    }
  }
  return members;
}

template <HybridActionModel M>
int KCenterTree<M>::CopyAction(Worker& w, int ai, const std::vector<uint32_t>& keep) {
  Tree& tree = w.tree;
  typename Tree::ActNode out;
  {
    const auto& src = tree.act[ai];
    out.action = src.action;
    out.data.range = src.data.range;
    out.data.origin = src.data.origin;
    out.data.members = src.data.members;
  }
  const int dim = static_cast<int>(tree.act[ai].action.x.size());
  std::vector<int> entry_map(tree.act[ai].children.size(), -1);
  const int records = static_cast<int>(tree.act[ai].data.ids.size());
  for (int r = 0; r < records; ++r) {
    const auto& src = tree.act[ai].data;
    if (!Contains(keep, src.ids[r])) continue;
    const int e = src.entries[r];
    int new_entry = -1;
    if (e >= 0) {
      if (entry_map[e] < 0) {
        const int old_child = tree.act[ai].children.child(e);
        const int new_child = CopyObs(w, old_child, keep);
        const auto& children = tree.act[ai].children;
        out.children.Add(children.observation(e), children.hash(e), new_child);
        out.generated.push_back(0);
        entry_map[e] = out.children.size() - 1;
      }
      new_entry = entry_map[e];
      ++out.generated[new_entry];
      ++out.total_generated;
    }
    const auto& src2 = tree.act[ai].data;
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
      v = out.data.rewards[r] + (e < 0 ? 0.0 : gamma * VStar(tree, out.children.child(e)));
    }
    out.q += (v - out.q) / static_cast<double>(r + 1);
  }
  tree.act.push_back(std::move(out));
  return static_cast<int>(tree.act.size()) - 1;
}

template <HybridActionModel M>
int KCenterTree<M>::CopyObs(Worker& w, int node, const std::vector<uint32_t>& keep) {
  Tree& tree = w.tree;
  typename Tree::ObsNode out;
  {
    const auto& src = tree.obs[node];
    out.leaf_value = src.leaf_value;
    out.leaf_count = src.leaf_count;
    double previous = 0.0;
    for (size_t i = 0; i < src.states.size(); ++i) {
      const double wgt = src.cumulative[i] - previous;
      previous = src.cumulative[i];
      if (!Contains(keep, src.episodes[i])) continue;
      out.states.push_back(src.states[i]);
      out.rewards.push_back(src.rewards[i]);
      out.episodes.push_back(src.episodes[i]);
      out.cumulative.push_back((out.cumulative.empty() ? 0.0 : out.cumulative.back()) + wgt);
    }
  }
  const std::vector<int> actions = tree.obs[node].actions;
  for (int ai : actions) {
    const int copy = CopyAction(w, ai, keep);
    out.actions.push_back(copy);
    out.n += tree.act[copy].n;
  }
  tree.obs.push_back(std::move(out));
  return static_cast<int>(tree.obs.size()) - 1;
}

template <HybridActionModel M>
bool KCenterTree<M>::ChooseRootEntry(const std::set<std::pair<int, int>>& excluded, int* worker,
                                     int* entry) const {
  // Sum and sum of squares of recorded returns, for the lower bound's standard error.
  struct Moments {
    int64_t n = 0;
    double sum = 0.0;
    double sq = 0.0;
    void Add(const std::vector<double>& returns) {
      for (double r : returns) {
        sum += r;
        sq += r * r;
      }
      n += static_cast<int64_t>(returns.size());
    }
  };
  struct Group {
    int64_t n = 0;
    double q_sum = 0.0;
    Moments returns;  // filled for kLowerBound only
  };
  const auto final_choice = options_.final_choice;
  const bool by_bound = final_choice == KctOptions::FinalChoice::kLowerBound;
  // Qhat less final_lcb standard errors of the recorded returns (no spread known: Qhat).
  const auto lower_bound = [this](double q, const Moments& m) {
    if (m.n < 2) return q;
    const double mean = m.sum / static_cast<double>(m.n);
    const double var = std::max(0.0, (m.sq - mean * m.sum) / static_cast<double>(m.n - 1));
    return q - options_.final_lcb * std::sqrt(var / static_cast<double>(m.n));
  };
  std::map<int64_t, Group> groups;
  for (int t = 0; t < static_cast<int>(workers_.size()); ++t) {
    const Worker& w = workers_[t];
    if (w.tree.root < 0) continue;
    for (int ai : w.tree.obs[w.tree.root].actions) {
      if (excluded.count({t, ai})) continue;
      const auto& an = w.tree.act[ai];
      if (an.data.point_of != 0) continue;
      Group& g = groups[an.data.origin];
      g.n += an.n;
      g.q_sum += an.q * static_cast<double>(an.n);
      if (by_bound) g.returns.Add(an.data.returns);
    }
  }
  if (groups.empty()) return false;
  int64_t best_origin = groups.begin()->first;
  double best_key = -std::numeric_limits<double>::infinity();
  int64_t best_n = -1;
  for (const auto& [origin, g] : groups) {
    if (g.n == 0) continue;
    const double q = g.q_sum / static_cast<double>(g.n);
    const double key = final_choice == KctOptions::FinalChoice::kMostVisited
                           ? static_cast<double>(g.n)
                       : by_bound ? lower_bound(q, g.returns)
                                  : q;
    if (key > best_key || (key == best_key && g.n > best_n)) {
      best_key = key;
      best_n = g.n;
      best_origin = origin;
    }
  }
  *worker = -1;
  *entry = -1;
  int64_t most = -1;
  double most_q = -std::numeric_limits<double>::infinity();
  for (int t = 0; t < static_cast<int>(workers_.size()); ++t) {
    const Worker& w = workers_[t];
    if (w.tree.root < 0) continue;
    for (int ai : w.tree.obs[w.tree.root].actions) {
      const auto& an = w.tree.act[ai];
      if (an.data.origin != best_origin || an.data.point_of != 0 || excluded.count({t, ai})) {
        continue;
      }
      double key = an.q;
      if (by_bound) {
        Moments m;
        m.Add(an.data.returns);
        key = lower_bound(an.q, m);
      }
      const bool better = final_choice == KctOptions::FinalChoice::kMostVisited
                              ? (an.n > most || (an.n == most && an.q > most_q))
                              : (an.n > 0 && (key > most_q || *entry < 0));
      if (*entry < 0 || better) {
        most = an.n;
        most_q = final_choice == KctOptions::FinalChoice::kMostVisited ? an.q : key;
        *worker = t;
        *entry = ai;
      }
    }
  }
  return *entry >= 0;
}

template <HybridActionModel M>
bool KCenterTree<M>::SampleExecutable(const Worker& w, int ai, const State& s, Rng& rng,
                                      HybridAction* out) const {
  const auto& an = w.tree.act[ai];
  *out = an.action;
  if (model_.KindSpace(an.action.kind).dim() == 0) return true;
  if (options_.final_action == KctOptions::FinalAction::kCenter &&
      IsFeasibleAction(model_, s, an.action)) {
    return true;
  }
  if (options_.final_action == KctOptions::FinalAction::kRegression &&
      RegressedPoint(w, ai, s, out)) {
    return true;
  }
  if (options_.sample_candidates && an.data.members && !an.data.members->empty()) {
    // The sphere's tried candidate with the best mean return (a candidate is a point, so it
    // gathers returns over the episodes that drew it), else any feasible candidate.
    if (BestTriedPoint(an, s, out)) return true;
    std::vector<int> order(an.data.members->size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    for (size_t i = order.size(); i > 1; --i) {
      std::swap(order[i - 1], order[rng.UniformInt(static_cast<int64_t>(i))]);
    }
    for (int i : order) {
      HybridAction a{an.action.kind, (*an.data.members)[i]};
      if (IsFeasibleAction(model_, s, a)) {
        *out = std::move(a);
        return true;
      }
    }
  }
  // The sphere rule, also where the regression found no point.
  if (options_.final_action != KctOptions::FinalAction::kCenter) {
    for (int i = 0; i < options_.max_feasibility_tries; ++i) {
      HybridAction a = SampleInSphere(w.tree, ai, rng);
      if (IsFeasibleAction(model_, s, a)) {
        *out = std::move(a);
        return true;
      }
    }
  }
  if (IsFeasibleAction(model_, s, an.action)) return true;
  const auto& data = an.data;
  const int dim = static_cast<int>(an.action.x.size());
  int best = -1;
  HybridAction a = an.action;
  for (size_t r = 0; r < data.ids.size() && !data.points.empty(); ++r) {
    for (int i = 0; i < dim; ++i) a.x[i] = data.points[r * dim + i];
    if (!IsFeasibleAction(model_, s, a)) continue;
    if (best < 0 || data.returns[r] > data.returns[best]) best = static_cast<int>(r);
  }
  if (best < 0) return false;
  for (int i = 0; i < dim; ++i) out->x[i] = data.points[static_cast<size_t>(best) * dim + i];
  return true;
}

template <HybridActionModel M>
bool KCenterTree<M>::RegressedPoint(const Worker& w, int ai, const State& s,
                                    HybridAction* out) const {
  const auto& an = w.tree.act[ai];
  const int dim = static_cast<int>(an.action.x.size());
  const double radius = an.data.range;
  if (dim == 0 || !(radius > 0.0)) return false;
  // Metric coordinates z = (x - center) / (scale radius), the shorter way round periodic
  // dimensions; features 1, z_i, z_i z_j (i <= j).
  const BoxSpace& box = model_.KindSpace(an.action.kind);
  ActionVec point(dim);
  const int features = (dim + 1) * (dim + 2) / 2;
  const double reach = options_.regression_reach;
  std::vector<double> rows;
  std::vector<double> targets;
  Eigen::VectorXd z(dim);
  for (const Worker& other : workers_) {
    if (other.tree.root < 0) continue;
    for (int bi : other.tree.obs[other.tree.root].actions) {
      const auto& bn = other.tree.act[bi];
      if (bn.action.kind != an.action.kind || bn.data.points.empty() || bn.data.point_of != 0) {
        continue;
      }
      for (size_t r = 0; r < bn.data.ids.size(); ++r) {
        for (int i = 0; i < dim; ++i) point[i] = bn.data.points[r * dim + i];
        const ActionVec delta = box.Difference(point, an.action.x);
        for (int i = 0; i < dim; ++i) z[i] = delta[i] / (box.scale()[i] * radius);
        if (z.norm() > reach) continue;
        rows.push_back(1.0);
        for (int i = 0; i < dim; ++i) rows.push_back(z[i]);
        for (int i = 0; i < dim; ++i) {
          for (int j = i; j < dim; ++j) rows.push_back(z[i] * z[j]);
        }
        targets.push_back(bn.data.returns[r]);
      }
    }
  }
  const int n = static_cast<int>(targets.size());
  if (n < 3 * features) return false;
  const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> x(
      rows.data(), n, features);
  const Eigen::Map<const Eigen::VectorXd> y(targets.data(), n);
  const Eigen::VectorXd beta = x.colPivHouseholderQr().solve(y);
  if (!beta.allFinite()) return false;
  // The share of the returns' variance the quadratic explains.
  const double total = (y.array() - y.mean()).square().sum();
  const double residual = (x * beta - y).squaredNorm();
  if (!(total > 0.0) || 1.0 - residual / total < options_.regression_min_r2) return false;
  // Q(z) ~ beta0 + g.z + z' H z / 2 with H symmetric.
  Eigen::VectorXd g = beta.segment(1, dim);
  Eigen::MatrixXd h(dim, dim);
  int k = 1 + dim;
  for (int i = 0; i < dim; ++i) {
    for (int j = i; j < dim; ++j, ++k) {
      h(i, j) = h(j, i) = (i == j) ? 2.0 * beta[k] : beta[k];
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(h);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues().maxCoeff() < 0.0)) return false;
  Eigen::VectorXd best = -h.ldlt().solve(g);
  if (!best.allFinite()) return false;
  // Stay where the fit has data.
  if (best.norm() > options_.regression_trust) best *= options_.regression_trust / best.norm();
  HybridAction a = an.action;
  a.x = box.Clamp(an.action.x + radius * box.scale().cwiseProduct(best));
  if (!IsFeasibleAction(model_, s, a)) return false;
  *out = std::move(a);
  return true;
}

template <HybridActionModel M>
bool KCenterTree<M>::BestTriedPoint(const typename Tree::ActNode& an, const State& s,
                                    HybridAction* out) const {
  const auto& data = an.data;
  const int dim = static_cast<int>(an.action.x.size());
  if (data.points.empty() || dim == 0) return false;
  std::map<std::vector<float>, std::pair<int, double>> stats;  // point -> (count, sum)
  for (size_t r = 0; r < data.ids.size(); ++r) {
    std::vector<float> key(data.points.begin() + r * dim, data.points.begin() + (r + 1) * dim);
    auto& [count, sum] = stats[key];
    ++count;
    sum += data.returns[r];
  }
  int min_count = 1;
  for (const auto& [key, cs] : stats) min_count = std::max(min_count, std::min(cs.first, 2));
  double best = -std::numeric_limits<double>::infinity();
  bool found = false;
  for (const auto& [key, cs] : stats) {
    if (cs.first < min_count) continue;
    const double mean = cs.second / cs.first;
    if (mean <= best) continue;
    HybridAction a = an.action;
    for (int i = 0; i < dim; ++i) a.x[i] = key[i];
    if (!IsFeasibleAction(model_, s, a)) continue;
    best = mean;
    *out = std::move(a);
    found = true;
  }
  return found;
}

template <HybridActionModel M>
int KCenterTree<M>::EntryContaining(const Worker& w, const HybridAction& a) const {
  const Tree& tree = w.tree;
  auto contains = [&](int ai) {
    const auto& an = tree.act[ai];
    if (an.action.kind != a.kind) return false;
    const BoxSpace& box = model_.KindSpace(a.kind);
    if (box.dim() == 0) return true;
    return box.Distance(a.x, an.action.x) <= an.data.range * (1.0 + 1e-9) + 1e-12;
  };
  if (w.last_entry >= 0 && w.last_entry < static_cast<int>(tree.act.size()) &&
      contains(w.last_entry)) {
    return w.last_entry;
  }
  int best = -1;
  double best_ratio = std::numeric_limits<double>::infinity();
  for (int ai : tree.obs[tree.root].actions) {
    if (!contains(ai)) continue;
    const auto& an = tree.act[ai];
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

template <HybridActionModel M>
Status KCenterTree<M>::CheckTree(const Tree& tree) const {
  if (tree.root < 0) return OkStatus();
  std::vector<int> stack = {tree.root};
  while (!stack.empty()) {
    const int node = stack.back();
    stack.pop_back();
    const auto& on = tree.obs[node];
    int64_t sum = 0;
    std::map<int64_t, int64_t> point_visits;  // sphere id -> visits of its point children
    for (int ai : on.actions) {
      const auto& an = tree.act[ai];
      const auto& d = an.data;
      if (d.point_of != 0) {
        point_visits[d.point_of] += an.n;
      } else {
        sum += an.n;
      }
      if (an.n != static_cast<int64_t>(d.ids.size())) {
        return InternalError("sphere visit count differs from its recorded episodes");
      }
      if (!std::is_sorted(d.ids.begin(), d.ids.end())) {
        return InternalError("episode ids out of order");
      }
      const bool continuous = model_.KindSpace(an.action.kind).dim() > 0;
      if (continuous && d.point_of == 0 && d.range < options_.d_lim * (1 - 1e-12)) {
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
    if (options_.point_children) {
      for (int ai : on.actions) {
        const auto& an = tree.act[ai];
        if (an.data.point_of != 0 || model_.KindSpace(an.action.kind).dim() == 0) continue;
        const auto it = point_visits.find(an.data.sid);
        if (an.n != (it == point_visits.end() ? 0 : it->second)) {
          return InternalError("a sphere's visits differ from its point children's");
        }
        if (it != point_visits.end()) point_visits.erase(it);
      }
      if (!point_visits.empty()) return InternalError("a point child without its sphere");
    }
  }
  return OkStatus();
}
}  // namespace npfkct
