// The planner registry: every planner the server, the benchmark and the API schema know, each as
// one entry that names it, lists its options with their object-search defaults, says what it
// takes (the neural filter's candidates, the true world) and makes it. Adding a planner is one
// header (the planner) and one entry:
//
//   PlannerRegistry planners = PlannerRegistry::BuiltIn();
//   Status added = planners.Add({
//       .name = "greedy",
//       .summary = "one-step lookahead over aimed views",
//       .defaults = [](const SearchParams&) { return OptionList{{"views", 64}}; },
//       .make = [](const PlannerArgs& args) -> StatusOr<std::unique_ptr<SearchPlanner>> {
//         GreedyOptions o;  // with a SetOption(GreedyOptions*, key, value) overload
//         if (Status s = ApplyOptions(&o, args.options); !s.ok()) return s;
//         return std::unique_ptr<SearchPlanner>(new GreedyPlanner(*args.model, o));
//       }});
//   auto planner = planners.Make("greedy", {.model = &model, .options = {{"views", 128}}});
//
// The server takes a registry in its options and the benchmark in its configuration; both, the
// create-session schema's list of planner names and GET /v1/planners read it.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/object_search/model.h"
#include "npfkct/object_search/search_planner.h"
#include "npfkct/solver/candidates.h"

namespace npfkct::object_search {

/// The true world of a benchmark scene, for the planners that are told it (the oracles). Opaque
/// here: the layer that owns the truth (the simulator) derives from it, and its planners'
/// factories cast it back.
class Truth {
 public:
  virtual ~Truth() = default;
};

/// What a factory makes a planner from.
struct PlannerArgs {
  /// The model it plans on (must outlive the planner).
  const ObjectSearchModel* model = nullptr;
  /// Overrides of its options (SetOption keys), in the order given.
  OptionList options;
  /// The neural filter's candidate sampler, for a planner that takes one (null: none loaded).
  std::shared_ptr<CandidateSampler<State>> sampler;
  /// The true world, for a planner that needs it (only benchmarks have one).
  const Truth* truth = nullptr;
};

/// One planner of the registry.
struct PlannerEntry {
  /// The name the API, the benchmark and the registry's Make() accept.
  std::string name;
  /// What it is, for help texts, GET /v1/planners and the docs.
  std::string summary;
  /// Whether it plans with the neural filter's candidates when a model is loaded (the server
  /// gives it its default model unless the request names one).
  bool takes_sampler = false;
  /// Whether it must be told the true world (benchmarks only; the server refuses it).
  bool needs_truth = false;
  /// Every option it takes with the value it runs with when not overridden, for a world with the
  /// reward table `params` (some defaults follow the reward range).
  std::function<OptionList(const SearchParams& params)> defaults;
  /// Makes it; INVALID_ARGUMENT naming the option for a bad override.
  std::function<StatusOr<std::unique_ptr<SearchPlanner>>(const PlannerArgs&)> make;
};

/// Whether `name` is a well-formed planner name: 1-64 lower-case letters, digits and '-'.
bool IsPlannerName(std::string_view name);

/// A set of planners by name, in the order tables list them. Copyable; a server or a benchmark
/// holds its own, so that a registry is never changed while another thread reads it.
class PlannerRegistry {
 public:
  /// The planners npfkct ships, in table order: npfkct, kct, pomcp, gpomcp, pomcp-joint,
  /// pomcpow, vomcpow, advt, and the oracles (told the true world: their factory is the
  /// simulator's, sim::AddOracleFactories; without it they are listed and refused).
  static const PlannerRegistry& BuiltIn();

  /// Adds `entry`; INVALID_ARGUMENT for an empty or taken name, a name of other characters than
  /// lower-case letters, digits and '-', or a missing factory or defaults.
  Status Add(PlannerEntry entry);
  /// Replaces the factory of the entry named `name` (e.g. the oracles', by the simulator);
  /// NOT_FOUND when there is none.
  Status SetFactory(
      std::string_view name,
      std::function<StatusOr<std::unique_ptr<SearchPlanner>>(const PlannerArgs&)> make);

  /// The entry named `name`, or null.
  const PlannerEntry* Find(std::string_view name) const;
  const std::vector<PlannerEntry>& entries() const { return entries_; }
  /// Every name; with `servable_only`, those a server may run (not needing the truth).
  std::vector<std::string> Names(bool servable_only = false) const;

  /// Makes planner `name` over `args.model` with the overrides of `args.options`. Unknown names,
  /// a planner that needs the truth without it, and bad options are INVALID_ARGUMENT naming them.
  StatusOr<std::unique_ptr<SearchPlanner>> Make(std::string_view name,
                                                const PlannerArgs& args) const;

 private:
  std::vector<PlannerEntry> entries_;
};

/// Applies `overrides` to `options` with SetOption, then checks them with Validate(): the first
/// error, naming the option.
template <class Options>
Status ApplyOptions(Options* options, const OptionList& overrides) {
  for (const auto& [key, value] : overrides) {
    if (Status s = SetOption(options, key, value); !s.ok()) return s;
  }
  return options->Validate();
}

}  // namespace npfkct::object_search
