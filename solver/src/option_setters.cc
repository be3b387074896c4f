#include "npfkct/solver/option_setters.h"

#include <cmath>
#include <functional>
#include <map>

#include "npfkct/solver/option_table.h"

namespace npfkct {
namespace {

using option_table::AddNested;
using option_table::Apply;
using option_table::Bool;
using option_table::Enum;
using option_table::Int;
using option_table::Keys;
using option_table::Nested;
using option_table::Real;
using option_table::Table;
using option_table::Values;

const Table<SearchOptions>& SearchTable() {
  static const auto* table = new Table<SearchOptions>{
      {"max_depth", Int(&SearchOptions::max_depth)},
      {"discount_horizon", Real(&SearchOptions::discount_horizon)},
      {"reuse_tree", Bool(&SearchOptions::reuse_tree)},
      {"num_particles", Int(&SearchOptions::num_particles)},
      {"leaf_value",
       Enum(&SearchOptions::leaf_value,
            {SearchOptions::LeafValue::kRollout, SearchOptions::LeafValue::kHeuristic},
            "0 (rollout) or 1 (heuristic)")},
      {"threads", Int(&SearchOptions::threads)},
      {"rollout_first", Bool(&SearchOptions::rollout_first)},
      {"belief.resample_threshold",
       Nested(&SearchOptions::belief, Real(&BeliefUpdateOptions::resample_threshold))},
      {"belief.reinvigoration_fraction",
       Nested(&SearchOptions::belief, Real(&BeliefUpdateOptions::reinvigoration_fraction))},
      {"belief.max_attempts_per_particle",
       Nested(&SearchOptions::belief, Int(&BeliefUpdateOptions::max_attempts_per_particle))},
  };
  return *table;
}

template <class O>
void AddSearch(Table<O>* table) {
  AddNested(table, "search", &O::search, SearchTable());
}

const Table<ObservationWidening>& WideningTable() {
  static const auto* table = new Table<ObservationWidening>{
      {"enabled", Bool(&ObservationWidening::enabled)},
      {"k", Real(&ObservationWidening::k)},
      {"alpha", Real(&ObservationWidening::alpha)},
      {"check_repeat", Bool(&ObservationWidening::check_repeat)},
  };
  return *table;
}

template <class O>
void AddWidening(Table<O>* table) {
  AddNested(table, "observations", &O::observations, WideningTable());
}

const Table<PomcpOptions>& PomcpTable() {
  static const auto* table = [] {
    auto* t = new Table<PomcpOptions>{
        {"exploration_c", Real(&PomcpOptions::exploration_c)},
        {"use_preferred_actions", Bool(&PomcpOptions::use_preferred_actions)},
        {"prior_count", Int(&PomcpOptions::prior_count)},
        {"prior_value", Real(&PomcpOptions::prior_value)},
    };
    AddSearch(t);
    return t;
  }();
  return *table;
}

const Table<DespotOptions>& DespotTable() {
  static const auto* table = [] {
    auto* t = new Table<DespotOptions>{
        {"num_scenarios", Int(&DespotOptions::num_scenarios)},
        {"xi", Real(&DespotOptions::xi)},
        {"pruning_constant", Real(&DespotOptions::pruning_constant)},
        {"max_policy_sim_len", Int(&DespotOptions::max_policy_sim_len)},
    };
    AddSearch(t);
    return t;
  }();
  return *table;
}

const Table<PomcpowOptions>& PomcpowTable() {
  static const auto* table = [] {
    auto* t = new Table<PomcpowOptions>{
        {"exploration_c", Real(&PomcpowOptions::exploration_c)},
        {"enable_action_pw", Bool(&PomcpowOptions::enable_action_pw)},
        {"k_action", Real(&PomcpowOptions::k_action)},
        {"alpha_action", Real(&PomcpowOptions::alpha_action)},
        {"use_voo", Bool(&PomcpowOptions::use_voo)},
        {"voo.uniform_probability",
         Nested(&PomcpowOptions::voo, Real(&VooOptions::uniform_probability))},
        {"voo.proposal_stddev", Nested(&PomcpowOptions::voo, Real(&VooOptions::proposal_stddev))},
        {"voo.accept_radius", Nested(&PomcpowOptions::voo, Real(&VooOptions::accept_radius))},
        {"voo.max_tries", Nested(&PomcpowOptions::voo, Int(&VooOptions::max_tries))},
        {"feasibility_tries", Int(&PomcpowOptions::feasibility_tries)},
    };
    AddSearch(t);
    AddWidening(t);
    return t;
  }();
  return *table;
}

const Table<AdvtOptions>& AdvtTable() {
  static const auto* table = [] {
    auto* t = new Table<AdvtOptions>{
        {"exploration_c", Real(&AdvtOptions::exploration_c)},
        {"diameter_coefficient", Real(&AdvtOptions::diameter_coefficient)},
        {"split_coefficient", Real(&AdvtOptions::split_coefficient)},
        {"diameter_samples", Int(&AdvtOptions::diameter_samples)},
        {"walk_steps", Int(&AdvtOptions::walk_steps)},
        {"feasibility_tries", Int(&AdvtOptions::feasibility_tries)},
        {"backup",
         Enum(&AdvtOptions::backup, {AdvtOptions::Backup::kMonteCarlo, AdvtOptions::Backup::kMax},
              "0 (Monte Carlo) or 1 (max)")},
    };
    AddSearch(t);
    AddWidening(t);
    return t;
  }();
  return *table;
}

const Table<KctOptions>& KctTable() {
  static const auto* table = [] {
    auto* t = new Table<KctOptions>{
        {"k", Int(&KctOptions::k)},
        {"w1", Real(&KctOptions::w1)},
        {"w2", Real(&KctOptions::w2)},
        {"value_scale", Real(&KctOptions::value_scale)},
        {"c_r", Real(&KctOptions::c_r)},
        {"d_lim", Real(&KctOptions::d_lim)},
        {"w1_bar", Real(&KctOptions::w1_bar)},
        {"w2_bar", Real(&KctOptions::w2_bar)},
        {"final_lcb", Real(&KctOptions::final_lcb)},
        {"num_candidates", Int(&KctOptions::num_candidates)},
        {"max_initial_clusters", Int(&KctOptions::max_initial_clusters)},
        {"max_feasibility_tries", Int(&KctOptions::max_feasibility_tries)},
        {"tree_feasibility_tries", Int(&KctOptions::tree_feasibility_tries)},
        {"backup",
         Enum(&KctOptions::backup, {KctOptions::Backup::kMonteCarlo, KctOptions::Backup::kBellman},
              "0 (Monte Carlo) or 1 (Bellman)")},
        {"final_action",
         Enum(&KctOptions::final_action,
              {KctOptions::FinalAction::kUniformInSphere, KctOptions::FinalAction::kCenter,
               KctOptions::FinalAction::kRegression},
              "0 (uniform), 1 (center) or 2 (regression)")},
        {"regression_reach", Real(&KctOptions::regression_reach)},
        {"regression_trust", Real(&KctOptions::regression_trust)},
        {"regression_min_r2", Real(&KctOptions::regression_min_r2)},
        {"final_choice",
         Enum(&KctOptions::final_choice,
              {KctOptions::FinalChoice::kMaxValue, KctOptions::FinalChoice::kMostVisited,
               KctOptions::FinalChoice::kLowerBound},
              "0 (highest value), 1 (most visited) or 2 (lower confidence bound)")},
        {"normalization",
         Enum(&KctOptions::normalization,
              {KctOptions::Normalization::kObservedRange, KctOptions::Normalization::kValueScale,
               KctOptions::Normalization::kSiblingRange},
              "0 (observed range), 1 (value scale) or 2 (sibling range)")},
        {"w2_ratio", Real(&KctOptions::w2_ratio)},
        {"sample_candidates", Bool(&KctOptions::sample_candidates)},
        {"refine_share", Real(&KctOptions::refine_share)},
        {"point_children", Bool(&KctOptions::point_children)},
        {"point_k", Real(&KctOptions::point_k)},
        {"point_alpha", Real(&KctOptions::point_alpha)},
    };
    AddSearch(t);
    AddWidening(t);
    return t;
  }();
  return *table;
}

}  // namespace

Status SetOption(SearchOptions* o, std::string_view key, double value) {
  return Apply(SearchTable(), o, key, value);
}
Status SetOption(PomcpOptions* o, std::string_view key, double value) {
  return Apply(PomcpTable(), o, key, value);
}
Status SetOption(DespotOptions* o, std::string_view key, double value) {
  return Apply(DespotTable(), o, key, value);
}
Status SetOption(PomcpowOptions* o, std::string_view key, double value) {
  return Apply(PomcpowTable(), o, key, value);
}
Status SetOption(AdvtOptions* o, std::string_view key, double value) {
  return Apply(AdvtTable(), o, key, value);
}
Status SetOption(KctOptions* o, std::string_view key, double value) {
  return Apply(KctTable(), o, key, value);
}

std::vector<std::string> OptionNames(const SearchOptions*) { return Keys(SearchTable()); }
std::vector<std::string> OptionNames(const PomcpOptions*) { return Keys(PomcpTable()); }
std::vector<std::string> OptionNames(const DespotOptions*) { return Keys(DespotTable()); }
std::vector<std::string> OptionNames(const PomcpowOptions*) { return Keys(PomcpowTable()); }
std::vector<std::string> OptionNames(const AdvtOptions*) { return Keys(AdvtTable()); }
std::vector<std::string> OptionNames(const KctOptions*) { return Keys(KctTable()); }

OptionValueList OptionValues(const SearchOptions& o) { return Values(SearchTable(), o); }
OptionValueList OptionValues(const PomcpOptions& o) { return Values(PomcpTable(), o); }
OptionValueList OptionValues(const DespotOptions& o) { return Values(DespotTable(), o); }
OptionValueList OptionValues(const PomcpowOptions& o) { return Values(PomcpowTable(), o); }
OptionValueList OptionValues(const AdvtOptions& o) { return Values(AdvtTable(), o); }
OptionValueList OptionValues(const KctOptions& o) { return Values(KctTable(), o); }

}  // namespace npfkct
