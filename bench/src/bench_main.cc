// npfkct-bench: runs episodes of a benchmark problem with a planner and a per-step budget and
// prints one JSON object per run.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <concepts>
#include <cstdio>
#include <functional>
#include <iostream>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "episode_runner.h"
#include "npfkct/common/version.h"
#include "npfkct/solver/advt.h"
#include "npfkct/solver/despot.h"
#include "npfkct/solver/discrete_as_hybrid.h"
#include "npfkct/solver/kct.h"
#include "npfkct/solver/models/light_dark.h"
#include "npfkct/solver/models/linear_quadratic.h"
#include "npfkct/solver/models/rock_sample.h"
#include "npfkct/solver/models/tag.h"
#include "npfkct/solver/models/tiger.h"
#include "npfkct/solver/models/vdp_tag.h"
#include "npfkct/solver/models/vpw_lqg.h"
#include "npfkct/solver/option_setters.h"
#include "npfkct/solver/pomcp.h"
#include "npfkct/solver/pomcpow.h"
#include "object_search_bench.h"

namespace npfkct::bench {
namespace {

struct Config {
  std::string problem;
  std::string planner;
  int episodes = 100;
  double time_ms = 0.0;
  double cpu_ms = 0.0;
  int64_t sims = 0;
  uint64_t seed = 1;
  int threads = 1;
  int max_steps = 0;
  std::string rollout;
  std::vector<std::string> options;
  bool trace = false;
};

// A value of an episode's trace: a number, or a hybrid action's kind (the discrete index of a
// discrete model run as a hybrid one, as kCT runs SimpleLightDark).
template <class T>
concept TraceNumber = std::is_arithmetic_v<T>;
template <class T>
concept Traceable = TraceNumber<T> || std::same_as<T, HybridAction>;

template <Traceable T>
double TraceValue(const T& v) {
  if constexpr (std::same_as<T, HybridAction>) {
    return v.kind;
  } else {
    return static_cast<double>(v);
  }
}

/// Whether an episode of M can be traced (its states, actions and observations are numbers).
template <class M>
constexpr bool kTraceable = Traceable<typename M::State> && Traceable<typename M::Action> &&
                            Traceable<typename M::Observation>;

/// One episode's trace as a JSON line: the states from the initial one, and each step's action,
/// observation and reward.
struct EpisodeTrace {
  std::vector<double> states, actions, observations, rewards;

  std::string Json(const std::string& label, int episode) const {
    std::string out = "{\"trace\": \"" + JsonEscape(label) + "\", \"episode\": " +
                      std::to_string(episode);
    auto list = [&out](const char* name, const std::vector<double>& v) {
      out += std::string(", \"") + name + "\": [";
      char buf[32];
      for (size_t i = 0; i < v.size(); ++i) {
        if (std::isfinite(v[i])) {
          std::snprintf(buf, sizeof buf, "%s%.9g", i ? ", " : "", v[i]);
        } else {
          std::snprintf(buf, sizeof buf, "%snull", i ? ", " : "");
        }
        out += buf;
      }
      out += "]";
    };
    list("states", states);
    list("actions", actions);
    list("observations", observations);
    list("rewards", rewards);
    return out + "}\n";
  }
};

/// Runs one closed-loop episode: the planner plans on its belief, the true model executes.
template <class M, class P, class SuccessFn>
EpisodeResult RunEpisode(const M& model, P& planner, const Budget& budget, int max_steps,
                         uint64_t seed, SuccessFn success, EpisodeTrace* trace = nullptr) {
  EpisodeResult result;
  Rng rng(seed);
  Rng world(seed ^ 0x5bd1e995u);
  planner.Reset(rng);
  auto state = model.SampleInitialState(world);
  if constexpr (kTraceable<M>) {
    if (trace != nullptr) trace->states.push_back(TraceValue(state));
  }
  double discount = 1.0;
  for (int t = 0; t < max_steps; ++t) {
    auto d = planner.Plan(budget, rng);
    if (!d.status.ok()) {
      result.error = d.status.ToString();
      break;
    }
    result.sims_per_step.push_back(d.stats.simulations);
    result.ms_per_step.push_back(d.stats.elapsed_ms);
    result.cpu_ms_per_step.push_back(d.stats.cpu_ms);
    auto step = model.Step(state, d.action, world);
    if constexpr (kTraceable<M>) {
      if (trace != nullptr) {
        trace->actions.push_back(TraceValue(d.action));
        trace->observations.push_back(TraceValue(step.observation));
        trace->rewards.push_back(step.reward);
        trace->states.push_back(TraceValue(step.state));
      }
    }
    result.discounted_return += discount * step.reward;
    result.undiscounted_return += step.reward;
    discount *= model.Discount();
    ++result.steps;
    if (step.terminal) {
      result.success = success(step);
      break;
    }
    planner.Advance(d.action, step.observation, rng);
    state = std::move(step.state);
  }
  return result;
}

template <class Options>
bool ApplyOptions(Options* o, const std::vector<std::string>& assignments) {
  for (const auto& a : assignments) {
    Status s = SetOptionFromString(o, a);
    if (!s.ok()) {
      std::cerr << "npfkct-bench: " << s.message() << "\nknown options:";
      for (const auto& name : OptionNames(o)) std::cerr << " " << name;
      std::cerr << "\n";
      return false;
    }
  }
  if (Status s = o->Validate(); !s.ok()) {
    std::cerr << "npfkct-bench: invalid options: " << s.message() << "\n";
    return false;
  }
  return true;
}

// kCT's tree in a run's record: "points" (point children, the default since they were measured on
// VDP Tag) or "spheres" (the paper's tree); a record without the field predates the choice
// (spheres).
template <class Options>
const char* KctTree(const Options& o) {
  if constexpr (requires { o.point_children; }) return o.point_children ? "points" : "spheres";
  return nullptr;
}

void PrintJson(const Config& c, const RunSummary& s, int max_steps, const char* kct_tree) {
  std::printf(
      "{\"problem\": \"%s\", \"planner\": \"%s\", \"episodes\": %d, \"time_ms\": %g, "
      "\"cpu_ms\": %g, \"sims\": %lld, \"max_steps\": %d, \"seed\": %llu, \"threads\": %d, "
      "\"rollout\": \"%s\", \"options\": [",
      JsonEscape(c.problem).c_str(), JsonEscape(c.planner).c_str(), c.episodes, c.time_ms, c.cpu_ms,
      static_cast<long long>(c.sims), max_steps, static_cast<unsigned long long>(c.seed), c.threads,
      JsonEscape(c.rollout).c_str());
  for (size_t i = 0; i < c.options.size(); ++i) {
    std::printf("%s\"%s\"", i ? ", " : "", JsonEscape(c.options[i]).c_str());
  }
  std::printf("]");
  if (kct_tree != nullptr) std::printf(", \"kct_tree\": \"%s\"", kct_tree);
  std::printf(
      ", \"mean_discounted_return\": %.4f, \"stderr\": %.4f, \"ci95\": %.4f, "
      "\"success_rate\": ",
      s.mean_return, s.stderr_return, s.ci95_return);
  if (s.success_rate) {
    std::printf("%.4f", *s.success_rate);
  } else {
    std::printf("null");
  }
  std::printf(
      ", \"mean_steps\": %.3f, \"ci95_steps\": %.3f, \"median_sims_per_step\": %.1f, "
      "\"median_sims_per_second\": %.1f, \"median_sims_per_cpu_second\": %.1f, "
      "\"median_first_step_sims_per_second\": %.1f, \"wall_seconds\": %.2f, "
      "\"failed_episodes\": %d",
      s.mean_steps, s.ci95_steps, s.median_sims_per_step, s.median_sims_per_second,
      s.median_sims_per_cpu_second, s.median_first_step_sims_per_second, s.wall_seconds,
      s.failed_episodes);
  if (!s.first_error.empty()) std::printf(", \"error\": \"%s\"", JsonEscape(s.first_error).c_str());
  std::printf(", \"episode_returns\": [");
  for (size_t i = 0; i < s.returns.size(); ++i) std::printf("%s%.4f", i ? ", " : "", s.returns[i]);
  std::printf("], \"episode_steps\": [");
  for (size_t i = 0; i < s.steps.size(); ++i) std::printf("%s%g", i ? ", " : "", s.steps[i]);
  std::printf("]}\n");
  std::fflush(stdout);
}

template <class M, class P, class Options, class SuccessFn>
int Run(const Config& c, const M& model, Options options, int default_max_steps,
        bool success_defined, SuccessFn success) {
  if (!ApplyOptions(&options, c.options)) return 2;
  const Budget budget{c.time_ms, c.sims, c.cpu_ms};
  if (Status s = budget.Validate(); !s.ok()) {
    std::cerr << "npfkct-bench: " << s.message() << "\n";
    return 2;
  }
  const int max_steps = c.max_steps > 0 ? c.max_steps : default_max_steps;
  if (c.trace && !kTraceable<M>) {
    std::cerr << "npfkct-bench: --trace needs a problem whose states, actions and observations "
                 "are numbers (lightdark, tiger); '"
              << c.problem << "' has others\n";
    return 2;
  }
  const std::string label = c.problem + "/" + c.planner;
  auto summary = RunEpisodes(
      c.episodes, c.threads, success_defined,
      [&](int i) {
        P planner(model, options);
        EpisodeTrace trace;
        EpisodeResult r = RunEpisode(model, planner, budget, max_steps,
                                     c.seed * 1000003ULL + i, success, c.trace ? &trace : nullptr);
        if (c.trace) std::fputs(trace.Json(label, i).c_str(), stderr);  // one line, one call
        return r;
      },
      label);
  PrintJson(c, summary, max_steps, KctTree(options));
  return summary.failed_episodes == 0 ? 0 : 1;
}

int Unsupported(const Config& c) {
  std::cerr << "npfkct-bench: planner '" << c.planner << "' does not apply to problem '"
            << c.problem << "'\n";
  return 2;
}

int RunTiger(const Config& c) {
  // Default rollout: always listen (random rollouts bury every value under -600).
  models::Tiger::Rollout rollout = models::Tiger::Rollout::kListen;
  if (c.rollout == "random") {
    rollout = models::Tiger::Rollout::kRandom;
  } else if (!c.rollout.empty() && c.rollout != "listen") {
    std::cerr << "npfkct-bench: tiger rollouts are 'random' or 'listen'\n";
    return 2;
  }
  const models::Tiger model(0.85, 0.95, rollout);
  auto never = [](const auto&) { return false; };
  if (c.planner == "pomcp") {
    PomcpOptions o;  // c = reward range 110
    o.search.num_particles = 2000;
    return Run<models::Tiger, Pomcp<models::Tiger>>(c, model, o, 100, false, never);
  }
  if (c.planner == "pomcpow") {
    PomcpowOptions o;
    o.search.num_particles = 2000;
    o.enable_action_pw = false;
    return Run<models::Tiger, Pomcpow<models::Tiger>>(c, model, o, 100, false, never);
  }
  return Unsupported(c);
}

int RunRockSample(const Config& c) {
  const auto model = models::RockSample::Standard78();
  auto exited = [](const auto& step) { return step.reward == 10.0; };
  if (c.planner == "pomcp") {
    PomcpOptions o;  // c = reward range 20, preferred-action prior (10, 1.0), as POMCP 1.0
    o.prior_value = 1.0;
    o.search.num_particles = 4096;
    o.search.discount_horizon = 0.01;
    o.search.max_depth = 90;
    o.search.belief.reinvigoration_fraction = 1.0 / 16.0;
    return Run<models::RockSample, Pomcp<models::RockSample>>(c, model, o, 100, true, exited);
  }
  if (c.planner == "despot") {
    // The authors' defaults (K 500, depth 90, xi 0.95, no pruning) and RockSample bounds (MDP
    // upper bound, "go east" lower bound); the belief keeps 4096 particles as POMCP's does.
    DespotOptions o;
    o.search.num_particles = 4096;
    o.search.belief.reinvigoration_fraction = 1.0 / 16.0;
    return Run<models::RockSample, Despot<models::RockSample>>(c, model, o, 100, true, exited);
  }
  return Unsupported(c);
}

// Tag as DESPOT's papers run it (Somani et al. 2013; the authors' examples/cpp_models/tag): 90
// steps at most, the opponent tagged is the success.
int RunTag(const Config& c) {
  const models::Tag model;
  auto tagged = [](const auto& step) { return step.state.tagged; };
  if (c.planner == "pomcp") {
    PomcpOptions o;  // c = reward range 20, rollouts of the model's policy
    o.search.num_particles = 4096;
    o.search.max_depth = 90;
    o.search.discount_horizon = 0.01;
    return Run<models::Tag, Pomcp<models::Tag>>(c, model, o, 90, true, tagged);
  }
  if (c.planner == "despot") {
    // The authors' Tag settings (K 500, depth 90, xi 0.95, pruning constant 0.01), their
    // default upper bound (shortest path) and a lower bound in the spirit of their default
    // (the model's DefaultPolicyActions: chase the scenarios' most common opponent cell).
    DespotOptions o;
    o.search.num_particles = 4096;
    o.pruning_constant = 0.01;
    return Run<models::Tag, Despot<models::Tag>>(c, model, o, 90, true, tagged);
  }
  return Unsupported(c);
}

int RunLightDark(const Config& c) {
  // Leaves valued by the fully observable MDP (default, as published) or, labelled, by the detour
  // to the light (models::SimpleLightDark::Leaf::kLocalize).
  using Leaf = models::SimpleLightDark::Leaf;
  Leaf leaf = Leaf::kFullyObservable;
  if (c.rollout == "localize") {
    leaf = Leaf::kLocalize;
  } else if (!c.rollout.empty() && c.rollout != "fo") {
    std::cerr << "npfkct-bench: lightdark leaf values (--rollout) are 'fo' or 'localize'\n";
    return 2;
  }
  const models::SimpleLightDark model(0.0, leaf);
  auto declared_at_zero = [](const auto& step) { return step.reward == 100.0; };
  if (c.planner == "pomcp") {
    PomcpOptions o;  // the POMCPOW paper's POMCP with continuous observations
    o.exploration_c = 100.0;
    o.search.max_depth = 20;
    o.search.num_particles = 10000;
    o.search.leaf_value = SearchOptions::LeafValue::kHeuristic;
    return Run<models::SimpleLightDark, Pomcp<models::SimpleLightDark>>(c, model, o, 100, true,
                                                                        declared_at_zero);
  }
  if (c.planner == "d-pomcp") {
    // The authors' discretised POMCP (icaps_2018/ld_discretization.jl, "d_pomcp"): observations
    // in bins of 10^-1.5, their best width (60.99 +- 0.41 at 1 s in their raw data), c = 100,
    // depth 20; leaves valued by the fully observable MDP (theirs: rollouts of its policy).
    const models::SimpleLightDark discretised(std::pow(10.0, -1.5), leaf);
    PomcpOptions o;
    o.exploration_c = 100.0;
    o.search.max_depth = 20;
    o.search.num_particles = 10000;
    o.search.leaf_value = SearchOptions::LeafValue::kHeuristic;
    return Run<models::SimpleLightDark, Pomcp<models::SimpleLightDark>>(c, discretised, o, 100,
                                                                        true, declared_at_zero);
  }
  if (c.planner == "pomcpow") {
    PomcpowOptions o;  // the POMCPOW paper's settings
    o.exploration_c = 90.0;
    o.enable_action_pw = false;
    o.observations.k = 5.0;
    o.observations.alpha = 1.0 / 15.0;
    o.observations.check_repeat = false;
    o.search.max_depth = 20;
    o.search.num_particles = 10000;
    o.search.leaf_value = SearchOptions::LeafValue::kHeuristic;
    return Run<models::SimpleLightDark, Pomcpow<models::SimpleLightDark>>(c, model, o, 100, true,
                                                                          declared_at_zero);
  }
  if (c.planner == "kct") {
    // The actions are discrete: kCT's list holds them as points (no spheres to refine), with the
    // POMCPOW paper's observation widening, depth, particles and leaf values.
    const DiscreteAsHybrid<models::SimpleLightDark> hybrid(model);
    KctOptions o;
    o.observations.k = 5.0;
    o.observations.alpha = 1.0 / 15.0;
    o.observations.check_repeat = false;
    o.search.max_depth = 20;
    o.search.num_particles = 10000;
    o.search.leaf_value = SearchOptions::LeafValue::kHeuristic;
    return Run<DiscreteAsHybrid<models::SimpleLightDark>,
               KCenterTree<DiscreteAsHybrid<models::SimpleLightDark>>>(c, hybrid, o, 100, true,
                                                                       declared_at_zero);
  }
  return Unsupported(c);
}

int RunVdpTag(const Config& c) {
  models::VdpTag::Rollout rollout = models::VdpTag::Rollout::kRandom;
  if (c.rollout == "tonextml") {
    rollout = models::VdpTag::Rollout::kToNextMl;
  } else if (!c.rollout.empty() && c.rollout != "random") {
    std::cerr << "npfkct-bench: vdptag rollouts are 'random' or 'tonextml'\n";
    return 2;
  }
  const models::VdpTag model(rollout);
  auto tagged = [](const auto& step) { return step.state.tagged; };
  using Model = models::VdpTag;
  if (c.planner == "pomcpow" || c.planner == "vomcpow") {
    PomcpowOptions o;  // the POMCPOW paper's VDP Tag settings
    o.exploration_c = 110.0;
    o.k_action = 30.0;
    o.alpha_action = 1.0 / 30.0;
    o.observations.k = 5.0;
    o.observations.alpha = 1.0 / 100.0;
    o.observations.check_repeat = false;
    o.search.max_depth = 10;
    o.search.num_particles = 10000;
    if (c.planner == "vomcpow") {  // the VPW paper's tuned settings
      o.use_voo = true;
      o.exploration_c = 85.0;
      o.observations.k = 2.5;
      o.voo.uniform_probability = 0.7;
      o.voo.proposal_stddev = std::sqrt(0.1);
      o.voo.accept_radius = 0.01;
      o.voo.max_tries = 20;
    }
    return Run<Model, Pomcpow<Model>>(c, model, o, 100, true, tagged);
  }
  if (c.planner == "advt") {
    AdvtOptions o;  // the ADVT authors' VDP Tag configuration
    o.exploration_c = 156.6;
    o.diameter_coefficient = 5.0;
    o.split_coefficient = 5.0;
    o.observations.k = 5.0;
    o.observations.alpha = 1.0 / 100.0;
    o.observations.check_repeat = false;
    o.search.max_depth = 10;
    o.search.num_particles = 10000;
    return Run<Model, Advt<Model>>(c, model, o, 100, true, tagged);
  }
  if (c.planner == "kct") {
    KctOptions o;  // the library's defaults, with VOMCPOW's observation widening, depth, particles
    o.observations.k = 2.5;
    o.observations.alpha = 1.0 / 100.0;
    o.observations.check_repeat = false;
    o.search.max_depth = 10;
    o.search.num_particles = 10000;
    return Run<Model, KCenterTree<Model>>(c, model, o, 100, true, tagged);
  }
  return Unsupported(c);
}

// The VPW paper's first-action benchmark on its 2-D LQG (Lim, Tomlin & Sunberg 2021,
// VOOTreeSearch.jl scripts/LQG/action_compare.jl): each "episode" is one plan from the initial
// belief, scored by the Euclidean distance of its action to the LQR optimum (6, -6). POMCPOW and
// VOMCPOW take the script's tuned constants and RolloutFirst; kCT takes its defaults.
int RunLqg(const Config& c) {
  models::LinearQuadratic::Params params = models::LinearQuadratic::Params::VpwLqg();
  if (c.rollout == "uniform") {
    params.rollout = models::LinearQuadratic::Rollout::kUniform;
  } else if (!c.rollout.empty() && c.rollout != "lqr") {
    std::cerr << "npfkct-bench: lqg rollouts are 'lqr' (default) or 'uniform'\n";
    return 2;
  }
  const models::LinearQuadratic model(params);
  using Model = models::LinearQuadratic;
  const Budget budget{c.time_ms, c.sims, c.cpu_ms};
  if (Status s = budget.Validate(); !s.ok()) {
    std::cerr << "npfkct-bench: " << s.message() << "\n";
    return 2;
  }
  std::vector<double> distance(c.episodes, 0.0);
  std::vector<ActionVec> chosen(c.episodes);
  auto score = [&](auto& planner, int i) {
    EpisodeResult r;
    Rng rng(c.seed * 1000003ULL + i);
    planner.Reset(rng);
    auto d = planner.Plan(budget, rng);
    if (!d.status.ok()) {
      r.error = d.status.ToString();
      return r;
    }
    r.sims_per_step.push_back(d.stats.simulations);
    r.ms_per_step.push_back(d.stats.elapsed_ms);
    r.cpu_ms_per_step.push_back(d.stats.cpu_ms);
    r.steps = 1;
    chosen[i] = d.action.x;
    distance[i] = (d.action.x - model.OptimalFirstAction()).norm();
    return r;
  };
  std::function<EpisodeResult(int)> run;
  const char* kct_tree = nullptr;
  if (c.planner == "pomcpow" || c.planner == "vomcpow") {
    PomcpowOptions o = models::VpwLqgPomcpowOptions(c.planner == "vomcpow");
    if (!ApplyOptions(&o, c.options)) return 2;
    run = [&, o](int i) {
      Pomcpow<Model> planner(model, o);
      return score(planner, i);
    };
  } else if (c.planner == "kct") {
    KctOptions o;
    o.search.max_depth = 3;
    o.search.num_particles = 1000;
    if (!ApplyOptions(&o, c.options)) return 2;
    kct_tree = KctTree(o);
    run = [&, o](int i) {
      KCenterTree<Model> planner(model, o);
      return score(planner, i);
    };
  } else {
    return Unsupported(c);
  }
  const RunSummary s =
      Summarize(RunJobs(c.episodes, c.threads, run, c.problem + "/" + c.planner), false, 0.0);
  const MeanInterval d = MeanWithInterval(distance);
  ActionVec mean_action = MakeActionVec({0.0, 0.0});
  for (const ActionVec& a : chosen) mean_action += a / static_cast<double>(c.episodes);
  std::printf(
      "{\"problem\": \"lqg\", \"planner\": \"%s\", \"plans\": %d, \"time_ms\": %g, \"cpu_ms\": %g, "
      "\"sims\": %lld, \"seed\": %llu, \"rollout\": \"%s\", \"options\": [",
      JsonEscape(c.planner).c_str(), c.episodes, c.time_ms, c.cpu_ms,
      static_cast<long long>(c.sims), static_cast<unsigned long long>(c.seed),
      params.rollout == Model::Rollout::kLqr ? "lqr" : "uniform");
  for (size_t i = 0; i < c.options.size(); ++i) {
    std::printf("%s\"%s\"", i ? ", " : "", JsonEscape(c.options[i]).c_str());
  }
  std::printf("]");
  if (kct_tree != nullptr) std::printf(", \"kct_tree\": \"%s\"", kct_tree);
  std::printf(
      ", \"optimum\": [%.4f, %.4f], \"mean_action\": [%.4f, %.4f], \"mean_distance\": %.4f, "
      "\"stderr\": %.4f, \"median_distance\": %.4f, \"median_sims_per_step\": %.1f, "
      "\"failed_plans\": %d}\n",
      model.OptimalFirstAction()[0], model.OptimalFirstAction()[1], mean_action[0], mean_action[1],
      d.mean, d.StandardError(), Median(distance), s.median_sims_per_step, s.failed_episodes);
  return s.failed_episodes == 0 ? 0 : 1;
}

}  // namespace
}  // namespace npfkct::bench

int main(int argc, char** argv) {
  npfkct::bench::Config c;
  npfkct::bench::SearchBenchConfig search;
  CLI::App app{
      "npfkct-bench: closed-loop benchmark runs of the npfkct planners, on the classic POMDP "
      "benchmarks (--problem) or on object-search scenarios (--scenario)"};
  app.set_version_flag("--version", std::string("npfkct-bench ") + npfkct::kVersion);
  app.add_option("--problem", c.problem,
                 "tiger | rocksample | tag | lightdark | vdptag | lqg (the VPW paper's LQG: each "
                 "episode is one plan, scored by its first action's distance to the optimum)");
  app.add_option("--scenario", search.scenarios,
                 "object-search scenario file(s) (repeatable or comma-separated)")
      ->delimiter(',');
  std::string scenario_planners;
  for (const std::string& name : npfkct::object_search::PlannerRegistry::BuiltIn().Names()) {
    scenario_planners += name + ", ";
  }
  app.add_option("--planner", search.planners,
                 "problems: pomcp | d-pomcp | despot | pomcpow | vomcpow | advt | kct; scenarios: "
                 "a comma-separated "
                 "list of " +
                     scenario_planners + "or all")
      ->delimiter(',')
      ->required();
  app.add_option("--episodes,--trials", c.episodes, "episodes (trials) per run")
      ->check(CLI::PositiveNumber);
  app.add_option("--time-ms", c.time_ms, "wall-clock planning time per step in ms (0: no limit)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--cpu-ms", c.cpu_ms,
                 "CPU time of the planning thread per step in ms (0: no limit); benchmarks of "
                 "record use it, since it does not shrink when other work shares the core")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--sims", c.sims, "simulations per step (0: no limit)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--seed", c.seed, "base seed; episode i uses seed * 1000003 + i");
  app.add_option("--threads", c.threads, "episodes run in parallel")->check(CLI::PositiveNumber);
  app.add_option("--max-steps", c.max_steps, "episode length limit (default per problem)");
  app.add_option("--rollout", c.rollout,
                 "tiger: listen (default) | random; vdptag: random (default) | tonextml; lqg: "
                 "lqr (default) | uniform; lightdark (the leaf value): fo (default) | localize; "
                 "scenarios: aimed (default) | clear | greedy | random");
  double plan_r_co = std::nan("");
  app.add_option("--plan-r-co", plan_r_co,
                 "scenarios: R_co of the planners' model (the simulator pays the scenario's)");
  app.add_option("--obstacle-reward", search.obstacle_reward,
                 "scenarios: what the planners' model pays for an obstacle declaration: every "
                 "(default, the paper's) | covers (only one hiding the target)");
  app.add_option("--grid-sampling", search.grid_sampling,
                 "scenarios: how the grid world weighs a cell: probability (default, sigmoid of "
                 "its log-odds) | odds (the paper's)");
  app.add_option(
      "--opt", c.options,
      "planner option key=value (repeatable); scenarios: filter.* set Net_sam's options");
  app.add_option("--model", search.filter_model,
                 "scenarios: the neural filter model of the npfkct planner (default: the shipped "
                 "one; none: uniform candidates)");
  app.add_option("--label", search.label,
                 "scenarios: the name the records give the one planner run (a preset of a planner "
                 "and its options, e.g. npfkct-paper); records keep the planner in base_planner");
  app.add_option("--robot", search.robot, "scenarios: override the robot (fetch | stretch)");
  app.add_option("--table", search.table_path, "scenarios: write a Markdown table (Table 1)");
  app.add_option(
         "--observe", search.observe,
         "scenarios: how the robot observes, geometric (the simulator's shortcut) and/or "
         "perception (rendered RGB-D frames through the perception pipeline) and/or boxes (their "
         "depth with a simulated detector's 2D boxes of the target)")
      ->delimiter(',');
  app.add_flag("--trace", search.trace,
               "scenarios: print each step of every trial on stderr (each line names its trial); "
               "lightdark, tiger: each episode's states, actions, observations and rewards as a "
               "JSON line on stderr");
  app.add_option("--render", search.render_dir,
                 "scenarios: write per-step PNGs of the first trial into this directory");
  CLI11_PARSE(app, argc, argv);
  if (!search.scenarios.empty()) {
    search.trials = c.episodes;
    search.time_ms = c.time_ms;
    search.cpu_ms = c.cpu_ms;
    search.sims = c.sims;
    search.seed = c.seed;
    search.threads = c.threads;
    search.max_steps = c.max_steps;
    search.options = c.options;
    if (!c.rollout.empty()) search.rollout = c.rollout;
    if (!std::isnan(plan_r_co)) search.plan_r_co = plan_r_co;
    return npfkct::bench::RunObjectSearchBench(search);
  }
  if (search.planners.size() != 1) {
    std::cerr << "npfkct-bench: one --planner per --problem run\n";
    return 2;
  }
  c.planner = search.planners[0];
  c.trace = search.trace;
  if (c.problem == "tiger") return npfkct::bench::RunTiger(c);
  if (c.problem == "rocksample") return npfkct::bench::RunRockSample(c);
  if (c.problem == "lightdark") return npfkct::bench::RunLightDark(c);
  if (c.problem == "vdptag") return npfkct::bench::RunVdpTag(c);
  if (c.problem == "lqg") return npfkct::bench::RunLqg(c);
  if (c.problem == "tag") return npfkct::bench::RunTag(c);
  std::cerr << "npfkct-bench: set --problem or --scenario (unknown problem '" << c.problem
            << "')\n";
  return 2;
}
