// Every planner on the object-search model behind one interface, as the server's sessions and the
// benchmark use them, and the one registry of planner names.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/object_search/discrete.h"
#include "npfkct/object_search/model.h"
#include "npfkct/solver/belief.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/planner.h"

namespace npfkct::object_search {

/// A planner of hybrid object-search actions whose belief is maintained outside it.
class SearchPlanner {
 public:
  virtual ~SearchPlanner() = default;
  /// The registry name it was made with.
  virtual const std::string& name() const = 0;
  /// Replaces the belief and drops the tree.
  virtual void SetBelief(ParticleBelief<State> belief) = 0;
  /// Plans until `stop` says so (its budget, or a cancellation by the caller).
  virtual Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) = 0;
  /// Plans within `budget` (a condition nobody else can cancel).
  Decision<HybridAction> Plan(const Budget& budget, Rng& rng) {
    TerminationCondition stop(budget);
    return Plan(stop, rng);
  }
  /// Keeps the subtree under (a, o) when the planner reuses trees, and installs `belief`.
  virtual void AdvanceTo(const HybridAction& a, const Observation& o,
                         ParticleBelief<State> belief) = 0;
  /// Tells the planner that the model's World changed (manual poses depend on it).
  virtual void OnWorldChanged() {}
  /// Drops the search tree (and its memory), keeping the belief: the next Plan() starts afresh.
  virtual void DropTree() = 0;
  /// Nodes in the tree.
  virtual int64_t TreeSize() const = 0;
  /// Whether the planner keeps its tree across real steps.
  virtual bool ReusesTree() const = 0;
  /// Threads a Plan() searches on (search.threads; 1 but for kCT).
  virtual int SearchThreads() const { return 1; }
  /// What the candidate sampler did in the last Plan() (NPF-kCT only).
  virtual CandidateStats candidate_stats() const { return {}; }
};

/// One entry of the planner registry.
struct PlannerInfo {
  std::string name;     ///< The name MakeSearchPlanner, the API and npfkct-bench accept.
  std::string summary;  ///< What it is, for help texts and the README.
  /// Whether it plans with NPF-kCT's candidate sampler (the neural filter) when one is given.
  bool uses_sampler = false;
  /// Whether it must be told the true world (only the benchmark can make it).
  bool needs_truth = false;
};

/// The planner registry: every planner name, in the order tables list them.
const std::vector<PlannerInfo>& SearchPlanners();
/// The registry's names.
std::vector<std::string> SearchPlannerNames();
/// The registry entry of `name`, or null.
const PlannerInfo* FindSearchPlanner(const std::string& name);

/// Creates planner `name` over `model` (which must outlive it), with option overrides
/// (SetOption keys of the planner's options struct) applied to the object-search defaults, and
/// `sampler` as NPF-kCT's candidate source (uniform when null; ignored by other planners).
/// Unknown names, planners that need the true world, and bad options are INVALID_ARGUMENT
/// naming them.
StatusOr<std::unique_ptr<SearchPlanner>> MakeSearchPlanner(
    const std::string& name, const ObjectSearchModel& model,
    const std::vector<std::pair<std::string, double>>& options,
    std::shared_ptr<CandidateSampler<State>> sampler = nullptr);

}  // namespace npfkct::object_search
