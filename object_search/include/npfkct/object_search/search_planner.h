// Every planner on the object-search model behind one interface, as the server's sessions and the
// benchmark use them, and the adapter that puts a solver Planner behind it. The planners are
// named and made by the registry (planner_registry.h).
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/object_search/model.h"
#include "npfkct/solver/belief.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/planner_base.h"

namespace npfkct::object_search {

/// Option values as (key, value): SetOption's keys (snake_case, nested as "search.max_depth").
using OptionList = std::vector<std::pair<std::string, double>>;

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
  /// Every option as the planner runs with it (the registry's defaults with the overrides it was
  /// made with), in key order.
  virtual OptionList OptionsUsed() const = 0;
  /// What the last Plan() resolved itself from the options and the belief (kCT's w2, c_r, value
  /// scale, ...), as (name, value); empty for planners that resolve nothing.
  virtual OptionList ResolvedByLastPlan() const { return {}; }
};

/// A solver Planner `P` over the hybrid object-search model behind the SearchPlanner interface.
/// A new continuous planner needs nothing more than this adapter and a registry entry:
///
///   return std::unique_ptr<SearchPlanner>(new HybridSearchPlanner<MyPlanner<ObjectSearchModel>>(
///       "mine", *args.model, options, option_values));
template <Planner P>
class HybridSearchPlanner final : public SearchPlanner {
 public:
  /// Makes `P(model, options, extra...)`; `used` is every option as it runs (OptionsUsed()).
  template <class Options, class... Extra>
  HybridSearchPlanner(std::string name, const ObjectSearchModel& model, Options options,
                      OptionList used, Extra&&... extra)
      : name_(std::move(name)),
        planner_(model, options, std::forward<Extra>(extra)...),
        used_(std::move(used)),
        reuse_(options.search.reuse_tree),
        threads_(options.search.threads) {}

  const std::string& name() const override { return name_; }
  void SetBelief(ParticleBelief<State> belief) override { planner_.SetBelief(std::move(belief)); }
  using SearchPlanner::Plan;
  Decision<HybridAction> Plan(const TerminationCondition& stop, Rng& rng) override {
    return planner_.Plan(stop, rng);
  }
  void AdvanceTo(const HybridAction& a, const Observation& o,
                 ParticleBelief<State> belief) override {
    planner_.AdvanceTo(a, o, std::move(belief));
  }
  void DropTree() override { planner_.DropTree(); }
  int64_t TreeSize() const override { return planner_.TreeSize(); }
  bool ReusesTree() const override { return reuse_; }
  int SearchThreads() const override { return threads_; }
  CandidateStats candidate_stats() const override {
    if constexpr (requires { planner_.candidate_stats(); }) {
      return planner_.candidate_stats();
    } else {
      return {};
    }
  }
  OptionList OptionsUsed() const override { return used_; }
  OptionList ResolvedByLastPlan() const override {
    if constexpr (requires { planner_.used().Values(); }) {
      return planner_.used().Values();
    } else {
      return {};
    }
  }

 private:
  std::string name_;
  P planner_;
  OptionList used_;
  bool reuse_;
  int threads_;
};

}  // namespace npfkct::object_search
