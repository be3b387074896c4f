// Helpers for planners over hybrid (discrete kind + continuous part) action spaces.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "npfkct/solver/model.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/spaces.h"

namespace npfkct {

/// Metric distance between two hybrid actions: the kind's box metric for equal kinds, +infinity
/// for different kinds.
template <HybridActionModel M>
double ActionDistance(const M& model, const HybridAction& a, const HybridAction& b) {
  if (a.kind != b.kind) return std::numeric_limits<double>::infinity();
  return model.KindSpace(a.kind).Distance(a.x, b.x);
}

/// Options of Voronoi optimistic sampling of new actions (Lim, Tomlin & Sunberg 2021).
struct VooOptions {
  /// Probability of sampling a new action uniformly instead of in the best action's Voronoi cell
  /// (VOOTreeSearch.jl's exploration_prob; 0.7 in its VDP Tag experiments).
  double uniform_probability = 0.7;
  /// Standard deviation, in metric units, of the Gaussian proposal around the best action.
  double proposal_stddev = 0.316;
  /// Proposals closer than this to the best action are accepted at once.
  double accept_radius = 0.01;
  /// After this many proposals the closest one to the best action is returned.
  int max_tries = 20;

  /// Checks every option; the message names the offending one.
  Status Validate() const {
    if (!(uniform_probability >= 0.0 && uniform_probability <= 1.0)) {
      return InvalidArgumentError("uniform_probability must be in [0, 1]");
    }
    if (!(proposal_stddev > 0.0) || !std::isfinite(proposal_stddev)) {
      return InvalidArgumentError("proposal_stddev must be > 0");
    }
    if (!(accept_radius >= 0.0) || !std::isfinite(accept_radius)) {
      return InvalidArgumentError("accept_radius must be >= 0");
    }
    if (max_tries < 1) return InvalidArgumentError("max_tries must be >= 1");
    return OkStatus();
  }
};

/// A uniform point of `kind`'s box that passes the model's reasonability check in state s: up to
/// `tries` draws, the last one kept when none passes (1: no check).
template <HybridActionModel M>
ActionVec SampleFeasiblePoint(const M& model, const typename M::State& s, int kind, int tries,
                              Rng& rng) {
  HybridAction a;
  a.kind = kind;
  const BoxSpace& box = model.KindSpace(kind);
  a.x = box.SampleUniform(rng);
  for (int t = 1; t < tries && box.dim() > 0 && !IsFeasibleAction(model, s, a); ++t) {
    a.x = box.SampleUniform(rng);
  }
  return a.x;
}

/// Draws a new hybrid action for a node that already holds `existing`: a legal kind chosen
/// uniformly among those still open (a kind without continuous part is open until it is present),
/// and a uniform point of its box that passes the reasonability check in s (up to
/// `feasibility_tries` draws). Returns false when no kind is open.
template <HybridActionModel M>
bool SampleUniformNewAction(const M& model, const typename M::State& s,
                            const std::vector<const HybridAction*>& existing, Rng& rng,
                            std::vector<int>* scratch, HybridAction* out,
                            int feasibility_tries = 1) {
  model.ActionKinds(s, scratch);
  auto is_closed = [&](int kind) {
    if (model.KindSpace(kind).dim() > 0) return false;
    return std::any_of(existing.begin(), existing.end(),
                       [kind](const HybridAction* a) { return a->kind == kind; });
  };
  scratch->erase(std::remove_if(scratch->begin(), scratch->end(), is_closed), scratch->end());
  if (scratch->empty()) return false;
  out->kind = (*scratch)[rng.UniformInt(static_cast<int64_t>(scratch->size()))];
  out->x = SampleFeasiblePoint(model, s, out->kind, feasibility_tries, rng);
  return true;
}

/// Voronoi optimistic sampling around `best` (an element of `existing`): Gaussian proposals of the
/// same kind, accepted when inside best's Voronoi cell among `existing` or within accept_radius of
/// best; after max_tries the proposal closest to best is returned. With `check_feasible`, only
/// proposals that pass the model's reasonability check in state s count as inside.
template <HybridActionModel M>
HybridAction SampleVoronoiAround(const M& model, const typename M::State& s,
                                 const HybridAction& best,
                                 const std::vector<const HybridAction*>& existing,
                                 const VooOptions& options, Rng& rng, bool check_feasible = false) {
  const BoxSpace& box = model.KindSpace(best.kind);
  HybridAction closest = best;
  double closest_dist = std::numeric_limits<double>::infinity();
  for (int tries = 1;; ++tries) {
    HybridAction proposal;
    proposal.kind = best.kind;
    proposal.x = best.x;
    for (int i = 0; i < box.dim(); ++i) {
      if (!box.fixed(i)) proposal.x[i] += options.proposal_stddev * box.scale()[i] * rng.Normal();
    }
    proposal.x = box.WrapPeriodic(proposal.x);
    const bool inside =
        box.Contains(proposal.x) && (!check_feasible || IsFeasibleAction(model, s, proposal));
    const double d = box.Distance(proposal.x, best.x);
    if (inside && d < closest_dist) {
      closest = proposal;
      closest_dist = d;
    }
    if (tries >= options.max_tries) return closest_dist < INFINITY ? closest : best;
    if (!inside) continue;
    if (d < options.accept_radius) return proposal;
    const bool in_cell = std::none_of(existing.begin(), existing.end(), [&](const HybridAction* a) {
      return a->kind == best.kind && box.Distance(proposal.x, a->x) < d;
    });
    if (in_cell) return proposal;
  }
}

}  // namespace npfkct
