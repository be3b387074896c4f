// Every planner on the object-search model behind one interface, as the server's sessions and the
// benchmark use them: NPF-kCT, POMCP and GPOMCP on the manual discrete set, POMCPOW, VOMCPOW and
// the ADVT-style planner.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/solver/belief.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/object_search/discrete.h"
#include "npfkct/solver/object_search/model.h"
#include "npfkct/solver/planner.h"

namespace npfkct::object_search {

/// A planner of hybrid object-search actions whose belief is maintained outside it.
class SearchPlanner {
 public:
  virtual ~SearchPlanner() = default;
  /// "npfkct", "kct", "pomcp", "gpomcp", "pomcpow", "vomcpow" or "advt".
  virtual const std::string& name() const = 0;
  /// Replaces the belief and drops the tree.
  virtual void SetBelief(ParticleBelief<State> belief) = 0;
  /// Plans within the budget.
  virtual Decision<HybridAction> Plan(const Budget& budget, Rng& rng) = 0;
  /// Keeps the subtree under (a, o) when the planner reuses trees, and installs `belief`.
  virtual void AdvanceTo(const HybridAction& a, const Observation& o,
                         ParticleBelief<State> belief) = 0;
  /// Tells the planner that the model's World changed (manual configurations depend on it).
  virtual void OnWorldChanged() {}
  /// Nodes in the tree.
  virtual int64_t TreeSize() const = 0;
  /// Whether the planner keeps its tree across real steps.
  virtual bool ReusesTree() const = 0;
  /// What the candidate sampler did in the last Plan() (NPF-kCT only).
  virtual CandidateStats candidate_stats() const { return {}; }
};

/// The planner names MakeSearchPlanner accepts.
const std::vector<std::string>& SearchPlannerNames();

/// Creates planner `name` over `model` (which must outlive it), with option overrides
/// (SetOption keys of the planner's options struct) applied to the object-search defaults, and
/// `sampler` as NPF-kCT's candidate source (uniform when null). Unknown names and bad options
/// are INVALID_ARGUMENT naming them.
StatusOr<std::unique_ptr<SearchPlanner>> MakeSearchPlanner(
    const std::string& name, const ObjectSearchModel& model,
    const std::vector<std::pair<std::string, double>>& options,
    std::shared_ptr<CandidateSampler<State>> sampler = nullptr);

}  // namespace npfkct::object_search
