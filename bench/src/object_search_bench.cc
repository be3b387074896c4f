#include "object_search_bench.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include "episode_runner.h"
#include "npfkct/filter/filter.h"
#include "npfkct/object_search/planner_registry.h"
#include "npfkct/perception/perception.h"
#include "npfkct/sim/api_robot.h"
#include "npfkct/sim/frame_io.h"
#include "npfkct/sim/oracle.h"
#include "npfkct/sim/scenario.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::bench {
namespace {

using object_search::ObjectSearchModel;
using object_search::World;

struct TrialContext {
  const sim::Scenario* scenario;
  const object_search::PlannerRegistry* planners;
  std::string planner;
  std::vector<std::pair<std::string, double>> options;  // planner options
  filter::FilterOptions filter_options;
  Budget budget;
  int max_steps;
  uint64_t seed;
  std::string render_prefix;  // empty: no pictures
  bool trace = false;         // each step on stderr
  bool perception = false;    // observe through rendered frames and the perception pipeline
  bool boxes = false;         // with the robot's detector's boxes in place of the image
  std::shared_ptr<const filter::NeuralFilter> filter;  // Net_sam of the npfkct planner
  object_search::SearchRollout rollout = object_search::SearchRollout::kAimed;
  std::optional<double> plan_r_co;  // R_co of the planning model (the simulator pays the real one)
  object_search::ObstacleReward obstacle_reward = object_search::ObstacleReward::kEvery;
  object_search::GridSampling grid_sampling = object_search::GridSampling::kProbability;
};

// The world the planners plan on: the robot's knowledge, with the planning model's R_co when the
// run gives one.
std::shared_ptr<World> PlanningWorld(const World& world, const std::optional<double>& plan_r_co) {
  auto planning = std::make_shared<World>(world);
  if (plan_r_co) planning->params.r_co = *plan_r_co;
  return planning;
}

// A registry planner; one that takes the filter's candidates gets Net_sam over the loaded filter;
// one that needs the truth is told `truth`.
StatusOr<std::unique_ptr<object_search::SearchPlanner>> MakePlanner(
    const object_search::PlannerRegistry& planners, const std::string& name,
    const ObjectSearchModel& model, const std::vector<std::pair<std::string, double>>& options,
    const filter::FilterOptions& filter_options,
    const std::shared_ptr<const filter::NeuralFilter>& net,
    const object_search::Truth* truth = nullptr) {
  object_search::PlannerArgs args{&model, options, nullptr, truth};
  const object_search::PlannerEntry* entry = planners.Find(name);
  if (entry != nullptr && entry->takes_sampler && net != nullptr) {
    auto made = filter::MakeNetSam(net, model, filter_options);
    if (!made.ok()) return made.status();
    args.sampler = *made;
  }
  return planners.Make(name, args);
}

// The robot's eyes in perception mode: renders the view, reports a noisy pose, and turns the
// frame into detections with the perception pipeline, as the server does for raw :observe data.
// With `boxes`, the robot's own detector instead: the depth and a simulated YOLO-style
// detector's boxes of the target (no photos, no image).
class PerceivingRobot {
 public:
  PerceivingRobot(const sim::Simulator& simulator, const World& world, bool boxes)
      : simulator_(simulator),
        boxes_(boxes),
        perception_(world,
                    boxes ? perception::TargetModel{}
                          : perception::TargetModel{{sim::ObjectPhotos(
                                simulator.objects()[simulator.target_index()])}},
                    {}) {}

  StatusOr<object_search::RealObservation> Observe(Rng& rng) {
    const sim::Frame f = simulator_.Render(640, 480);
    object_search::RobotConfig reported = simulator_.robot();
    const sim::SimNoise& noise = simulator_.scenario().noise;
    reported.x += noise.localization_xy * rng.Normal();
    reported.y += noise.localization_xy * rng.Normal();
    reported.yaw = object_search::WrapAngle(reported.yaw + noise.localization_yaw * rng.Normal());
    perception::SensorFrame frame;
    frame.cloud = sim::FrameCloud(f, /*world_frame=*/false);
    if (frame.cloud->empty()) {  // nothing in range: the pose alone
      object_search::RealObservation obs;
      obs.achieved = reported;
      return obs;
    }
    if (boxes_) {
      frame.image_boxes = sim::DetectorBoxes(simulator_, f, rng);
    } else {
      frame.image = sim::FrameBgr(f);
    }
    frame.intrinsics = {f.width, f.height, f.fx, f.fy, f.cx, f.cy};
    frame.reported = reported;
    auto result = perception_.Process(frame);
    if (!result.ok()) return result.status();
    frame_ms_.push_back(result->timings.total);
    return result->observation;
  }
  /// The robot took the object away: its track goes.
  void Removed(const std::string& key) { perception_.DropTrack(key); }
  const std::vector<double>& frame_ms() const { return frame_ms_; }

 private:
  const sim::Simulator& simulator_;
  bool boxes_;
  perception::Perception perception_;
  std::vector<double> frame_ms_;
};

std::string Describe(const HybridAction& a, const World& w) {
  if (a.kind == object_search::kMoveKind) {
    const auto c = ObjectSearchModel::ConfigOf(a.x);
    char buf[160];
    std::snprintf(buf, sizeof buf, "move x=%.2f y=%.2f yaw=%.2f lift=%.2f pan=%.2f tilt=%.2f", c.x,
                  c.y, c.yaw, c.lift, c.pan, c.tilt);
    return buf;
  }
  const int i = object_search::KindObject(a.kind);
  const std::string key = i < static_cast<int>(w.objects.size()) ? w.objects[i].key : "?";
  static const char* kVerbs[] = {"declare target", "declare obstacle", "remove"};
  return std::string(kVerbs[object_search::KindOffset(a.kind)]) + " " + key;
}

// The root entries the search weighed most: the 3 most visited, then the 3 most visited discrete
// ones among the rest, each as its action's verb (and object), visits and Qhat.
std::string RootSummary(const std::vector<RootActionStat<HybridAction>>& root, const World& w) {
  std::vector<int> order(root.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::stable_sort(order.begin(), order.end(),
                   [&](int a, int b) { return root[a].visits > root[b].visits; });
  std::string out;
  int shown = 0, discrete = 0;
  for (int i : order) {
    const auto& e = root[i];
    if (e.visits == 0) break;
    const bool move = e.action.kind == object_search::kMoveKind;
    if (shown >= 3 && (move || discrete >= 3)) continue;
    if (shown >= 3) ++discrete;
    ++shown;
    char buf[64];
    std::snprintf(buf, sizeof buf, " n=%lld q=%.0f", static_cast<long long>(e.visits), e.value);
    if (!out.empty()) out.push_back(',');
    out.push_back(' ');
    out.append(move ? std::string("move") : Describe(e.action, w));
    out.append(buf);
  }
  return out;
}

// One line on stderr for a step: the action, its outcome, the search statistics, the root entries
// the search weighed most and, per known object, the face grids confirmed as the target's (+)
// and as an obstacle's (-) after the step, marked * while the object can be declared.
void TraceStep(const TrialContext& ctx, const ObjectSearchModel& model, const World& world, int t,
               const Decision<HybridAction>& d, const std::string& detail) {
  std::string known;
  for (size_t i = 1; i < world.objects.size(); ++i) {
    const auto& o = world.objects[i];
    if (o.status == object_search::kRemoved) continue;
    const int plus = model.CountPast(o.odds, true);
    const int minus = model.CountPast(o.odds, false);
    const bool declarable =
        o.status == object_search::kUpdating && std::max(plus, minus) >= world.params.n_odds;
    known += " " + o.key + ":" + std::to_string(plus) + "/" + std::to_string(minus) +
             (declarable ? "*" : "");
  }
  const std::string root = RootSummary(d.root, world);
  std::fprintf(stderr, "%s %s trial %llu step %2d: %-62s %-30s sims %7lld value %9.1f%s%s |%s\n",
               ctx.scenario->name.c_str(), ctx.planner.c_str(),
               static_cast<unsigned long long>(ctx.seed % 1000003ULL), t + 1,
               Describe(d.action, world).c_str(), detail.c_str(),
               static_cast<long long>(d.stats.simulations), d.value,
               root.empty() ? "" : " root:", root.c_str(), known.c_str());
}

// Takes an observation after step `action`, gives it to the world, the model and the planner:
// a fresh belief of `particles` (drawn from `rng`), the tree kept unless new objects appeared.
Status TakeObservation(const object_search::RealObservation& obs, const HybridAction& action,
                       int particles, const std::optional<double>& plan_r_co, World* world,
                       ObjectSearchModel* model, object_search::SearchPlanner* planner, Rng& rng) {
  std::vector<int> detected;
  bool new_objects = false;
  for (const auto& det : obs.objects) {
    const int index = world->FindObject(det.key);
    if (index < 0) new_objects = true;
    detected.push_back(index);
  }
  const object_search::Observation key = model->RealObservationKey(detected);
  if (Status s = object_search::ApplyRealObservation(world, obs); !s.ok()) return s;
  model->SetWorld(PlanningWorld(*world, plan_r_co));
  planner->OnWorldChanged();
  auto belief = ParticleBelief<object_search::State>::FromInitial(*model, particles, rng);
  if (new_objects) {
    planner->SetBelief(std::move(belief));
  } else {
    planner->AdvanceTo(action, key, std::move(belief));
  }
  return OkStatus();
}

// Writes the picture of step t (the belief beside the camera's view) under ctx.render_prefix.
void RenderStepPicture(const TrialContext& ctx, const World& world, const sim::Simulator& simulator,
                       int t, const HybridAction& action, const std::string& detail) {
  char name[32];
  std::snprintf(name, sizeof name, "-step%02d.png", t + 1);
  const std::string caption =
      "step " + std::to_string(t + 1) + ": " + Describe(action, world) + " (" + detail + ")";
  (void)sim::WritePng(ctx.render_prefix + name,
                      sim::RenderStep(world, simulator.Render(), caption));
}

// One trial: the robot looks once, then plans, acts and observes until the target is removed,
// an error, or ctx.max_steps.
EpisodeResult RunTrial(const TrialContext& ctx) {
  EpisodeResult result;
  sim::Simulator simulator(*ctx.scenario, ctx.seed);
  auto initial = simulator.InitialWorld();
  if (!initial.ok()) {
    result.error = initial.status().ToString();
    return result;
  }
  World world = *initial;
  world.grid.SetSampling(ctx.grid_sampling);
  Rng rng(ctx.seed * 7919 + 1), world_rng(ctx.seed * 104729 + 3), sensor_rng(ctx.seed * 31 + 5);
  std::unique_ptr<PerceivingRobot> eyes;
  if (ctx.perception) eyes = std::make_unique<PerceivingRobot>(simulator, world, ctx.boxes);
  auto observe = [&]() -> StatusOr<object_search::RealObservation> {
    if (eyes) return eyes->Observe(sensor_rng);
    return simulator.Observe(world_rng);
  };
  // The robot looks once from its start before planning.
  auto first = observe();
  Status first_status =
      first.ok() ? object_search::ApplyRealObservation(&world, *first) : first.status();
  if (!first_status.ok()) {
    result.error = first_status.ToString();
    return result;
  }
  ObjectSearchModel model(PlanningWorld(world, ctx.plan_r_co), ctx.rollout);
  model.SetObstacleReward(ctx.obstacle_reward);
  // The oracles are told the true scene; every other planner plans on the robot's belief.
  const sim::SceneTruth truth(simulator);
  auto made = MakePlanner(*ctx.planners, ctx.planner, model, ctx.options, ctx.filter_options,
                          ctx.filter, &truth);
  if (!made.ok()) {
    result.error = made.status().ToString();
    return result;
  }
  std::unique_ptr<object_search::SearchPlanner> planner = std::move(made).value();
  const int particles = 300;
  planner->SetBelief(ParticleBelief<object_search::State>::FromInitial(model, particles, rng));
  double discount = 1.0;
  for (int t = 0; t < ctx.max_steps; ++t) {
    TerminationCondition stop(ctx.budget);
    Decision<HybridAction> d = planner->Plan(stop, rng);
    if (!d.status.ok()) {
      result.error = d.status.ToString();
      break;
    }
    result.sims_per_step.push_back(d.stats.simulations);
    result.ms_per_step.push_back(d.stats.elapsed_ms);
    result.cpu_ms_per_step.push_back(d.stats.cpu_ms);
    const sim::ExecutionOutcome outcome = simulator.Execute(d.action, world, world_rng);
    result.discounted_return += discount * outcome.reward;
    result.undiscounted_return += outcome.reward;
    const bool obstacle_declared =
        d.action.kind != object_search::kMoveKind && outcome.success &&
        object_search::KindOffset(d.action.kind) == object_search::kDeclareObstacleOffset;
    result.target_return += discount * (obstacle_declared ? world.params.r_min : outcome.reward);
    discount *= world.params.discount;
    ++result.steps;
    if (d.action.kind != object_search::kMoveKind) {
      const int object = object_search::KindObject(d.action.kind);
      const int offset = object_search::KindOffset(d.action.kind);
      if (eyes && outcome.success && offset == object_search::kRemoveOffset) {
        eyes->Removed(world.objects[object].key);
      }
      (void)object_search::ApplyDiscreteOutcome(&world, object, offset, outcome.success);
    }
    if (outcome.terminal) {
      if (ctx.trace) TraceStep(ctx, model, world, t, d, outcome.detail);
      result.success = true;
      break;
    }
    auto observed = observe();
    Status s = observed.ok() ? TakeObservation(*observed, d.action, particles, ctx.plan_r_co,
                                               &world, &model, planner.get(), rng)
                             : observed.status();
    if (!s.ok()) {
      result.error = s.ToString();
      break;
    }
    if (ctx.trace) TraceStep(ctx, model, world, t, d, outcome.detail);
    if (!ctx.render_prefix.empty()) {
      RenderStepPicture(ctx, world, simulator, t, d.action, outcome.detail);
    }
  }
  if (eyes) result.extra_ms = eyes->frame_ms();
  return result;
}

std::string Cell(const RunSummary& s) {
  char buf[160];
  std::snprintf(buf, sizeof buf, "%.1f ± %.1f \\| %.1f ± %.1f \\| %.0f%%", s.mean_return,
                s.ci95_return, s.mean_steps, s.ci95_steps, 100.0 * s.success_rate.value_or(0.0));
  return buf;
}

// What the checks before any trial give every trial.
struct BenchSetup {
  std::vector<std::pair<std::string, double>> options;  // planner options
  filter::FilterOptions filter_options;
  Budget budget;
  object_search::PlannerRegistry registry;
  std::vector<std::string> planners;                // compared, "all" expanded
  std::shared_ptr<const filter::NeuralFilter> net;  // null: no planner takes it, or "none"
  object_search::SearchRollout rollout = object_search::SearchRollout::kAimed;
  object_search::ObstacleReward obstacle_reward = object_search::ObstacleReward::kEvery;
  object_search::GridSampling grid_sampling = object_search::GridSampling::kProbability;
};

// The stages before any trial each take the config and fill their part of `setup`; on an
// error they print it and give false (the bench then exits with 2).

// Parse options: --opt key=number into the planner options and filter.* into the filter's;
// the budget.
bool ParseOptions(const SearchBenchConfig& config, BenchSetup* setup) {
  for (const std::string& a : config.options) {
    const size_t eq = a.find('=');
    char* end = nullptr;
    const std::string value = eq == std::string::npos ? "" : a.substr(eq + 1);
    const double v = std::strtod(value.c_str(), &end);
    if (eq == std::string::npos || value.empty() || end != value.c_str() + value.size()) {
      std::cerr << "npfkct-bench: option '" << a << "' is not key=number\n";
      return false;
    }
    const std::string key = a.substr(0, eq);
    if (key.rfind("filter.", 0) == 0) {
      if (Status s = filter::SetOption(&setup->filter_options, key.substr(7), v); !s.ok()) {
        std::cerr << "npfkct-bench: " << s.message() << "\n";
        return false;
      }
      continue;
    }
    setup->options.emplace_back(key, v);
  }
  if (Status s = setup->filter_options.Validate(); !s.ok()) {
    std::cerr << "npfkct-bench: filter." << s.message() << "\n";
    return false;
  }
  setup->budget = Budget{config.time_ms, config.sims, config.cpu_ms};
  if (Status s = setup->budget.Validate(); !s.ok()) {
    std::cerr << "npfkct-bench: " << s.message() << " (--time-ms, --cpu-ms, --sims)\n";
    return false;
  }
  return true;
}

// Check planners: the registry with the oracles, and every planner named known to it.
bool CheckPlanners(const SearchBenchConfig& config, BenchSetup* setup) {
  setup->registry = config.registry ? *config.registry : object_search::PlannerRegistry::BuiltIn();
  if (Status s = sim::AddOracleFactories(&setup->registry); !s.ok()) {
    std::cerr << "npfkct-bench: " << s.message() << "\n";
    return false;
  }
  setup->planners = config.planners;
  if (setup->planners.size() == 1 && setup->planners[0] == "all") {
    setup->planners = setup->registry.Names();
  }
  for (const std::string& p : setup->planners) {
    if (setup->registry.Find(p) == nullptr) {
      std::string known;
      for (const auto& n : setup->registry.Names()) known += " " + n;
      std::cerr << "npfkct-bench: unknown planner '" << p << "' (known:" << known << ")\n";
      return false;
    }
  }
  if (!config.label.empty() &&
      (setup->planners.size() != 1 || !object_search::IsPlannerName(config.label))) {
    std::cerr << "npfkct-bench: --label names the one planner of a run: 1-64 lower-case letters, "
                 "digits and '-'\n";
    return false;
  }
  return true;
}

// Load the filter: the neural filter, when a planner takes its candidates and it is not "none".
bool LoadFilter(const SearchBenchConfig& config, BenchSetup* setup) {
  const object_search::PlannerRegistry& registry = setup->registry;
  if (std::any_of(setup->planners.begin(), setup->planners.end(),
                  [&](const std::string& p) { return registry.Find(p)->takes_sampler; }) &&
      config.filter_model != "none") {
    const std::string path =
        config.filter_model.empty() ? std::string(NPFKCT_FILTER_MODEL) : config.filter_model;
    auto loaded = filter::NeuralFilter::Load(path);
    if (!loaded.ok()) {
      std::cerr << "npfkct-bench: --model: " << loaded.status().message() << "\n";
      return false;
    }
    setup->net = *loaded;
  }
  return true;
}

// Check the observation modes (the oracles observe geometrically only) and parse the rollout.
bool CheckModesAndRollout(const SearchBenchConfig& config, BenchSetup* setup) {
  const object_search::PlannerRegistry& registry = setup->registry;
  for (const std::string& mode : config.observe) {
    if (mode != "geometric" && mode != "perception" && mode != "boxes") {
      std::cerr << "npfkct-bench: --observe: expected geometric, perception or boxes, got '" << mode
                << "'\n";
      return false;
    }
    if (mode != "geometric" &&
        std::any_of(setup->planners.begin(), setup->planners.end(),
                    [&](const std::string& p) { return registry.Find(p)->needs_truth; })) {
      std::cerr << "npfkct-bench: the oracle observes geometrically only\n";
      return false;
    }
  }
  if (config.rollout == "clear") {
    setup->rollout = object_search::SearchRollout::kClear;
  } else if (config.rollout == "greedy") {
    setup->rollout = object_search::SearchRollout::kGreedy;
  } else if (config.rollout == "random") {
    setup->rollout = object_search::SearchRollout::kRandom;
  } else if (config.rollout != "aimed") {
    std::cerr << "npfkct-bench: scenario rollouts are aimed (default), clear, greedy or random\n";
    return false;
  }
  if (config.obstacle_reward == "covers") {
    setup->obstacle_reward = object_search::ObstacleReward::kCovers;
  } else if (config.obstacle_reward != "every") {
    std::cerr << "npfkct-bench: --obstacle-reward is every (default) or covers\n";
    return false;
  }
  if (config.grid_sampling == "odds") {
    setup->grid_sampling = object_search::GridSampling::kOdds;
  } else if (config.grid_sampling != "probability") {
    std::cerr << "npfkct-bench: --grid-sampling is probability (default) or odds\n";
    return false;
  }
  return true;
}

// Load and validate the scenarios: each file (with --robot applied), its map, and every planner
// made once on it with the options, before spending time on trials.
bool LoadScenarios(const SearchBenchConfig& config, const BenchSetup& setup,
                   std::vector<sim::Scenario>* scenarios) {
  for (const std::string& path : config.scenarios) {
    auto loaded = sim::LoadScenario(path);
    if (!loaded.ok()) {
      std::cerr << "npfkct-bench: " << loaded.status().message() << "\n";
      return false;
    }
    sim::Scenario scenario = *loaded;
    if (!config.robot.empty()) {
      auto robot = object_search::RobotDescription::ByName(config.robot);
      if (!robot.ok()) {
        std::cerr << "npfkct-bench: --robot: " << robot.status().message() << "\n";
        return false;
      }
      scenario.robot = *robot;
    }
    // Validate the map, the planner names and the options once before spending time.
    auto world = sim::InitialWorld(scenario);
    if (!world.ok()) {
      std::cerr << "npfkct-bench: " << world.status().message() << "\n";
      return false;
    }
    ObjectSearchModel probe(std::make_shared<World>(*world));
    for (const std::string& planner : setup.planners) {
      if (setup.registry.Find(planner)->needs_truth) continue;
      auto made = MakePlanner(setup.registry, planner, probe, setup.options, setup.filter_options,
                              setup.net);
      if (!made.ok()) {
        std::cerr << "npfkct-bench: " << made.status().message() << "\n";
        return false;
      }
    }
    scenarios->push_back(std::move(scenario));
  }
  return true;
}

// The jobs, one trial each: trial-major (trial 0 of every scenario and planner, then trial 1,
// ...), so that whatever else the machine does spreads evenly over the planners compared; within
// a trial, scenario-major over the variants (planner x observation mode).
class JobGrid {
 public:
  JobGrid(const std::vector<std::string>& planners, const std::vector<std::string>& modes,
          int scenarios, int trials, std::string label)
      : planners_(planners),
        modes_(modes),
        label_(std::move(label)),
        variants_(static_cast<int>(planners.size() * modes.size())),
        per_trial_(scenarios * variants_),
        jobs_(trials * per_trial_) {}
  int jobs() const { return jobs_; }
  int variants() const { return variants_; }
  void Split(int j, int* scenario, int* variant, int* trial) const {
    *trial = j / per_trial_;
    *scenario = (j % per_trial_) / variants_;
    *variant = j % variants_;
  }
  const std::string& planner(int variant) const {
    return planners_[variant / static_cast<int>(modes_.size())];
  }
  const std::string& mode(int variant) const {
    return modes_[variant % static_cast<int>(modes_.size())];
  }
  // A row of the table: the planner (or its label), with the observation mode when several are
  // compared.
  std::string RowName(int variant) const {
    const std::string& name = label_.empty() ? planner(variant) : label_;
    return modes_.size() == 1 ? name : name + " (" + mode(variant) + ")";
  }
  bool several_modes() const { return modes_.size() > 1; }

 private:
  const std::vector<std::string> planners_, modes_;
  const std::string label_;
  const int variants_, per_trial_, jobs_;
};

// Run the jobs: takes the setup and the scenarios, gives every trial's result by job index.
std::vector<EpisodeResult> RunAllTrials(const SearchBenchConfig& config, const BenchSetup& setup,
                                        const std::vector<sim::Scenario>& scenarios,
                                        const JobGrid& grid) {
  return RunJobs(
      grid.jobs(), config.threads,
      [&](int j) {
        int sc, variant, trial;
        grid.Split(j, &sc, &variant, &trial);
        const sim::Scenario& scenario = scenarios[sc];
        const int max_steps = config.max_steps > 0 ? config.max_steps : scenario.params.max_steps;
        const std::string& planner = grid.planner(variant);
        const std::string& mode = grid.mode(variant);
        std::string render_prefix;
        if (!config.render_dir.empty() && trial == 0) {
          render_prefix = config.render_dir + "/" + scenario.name + "-" + planner +
                          (grid.several_modes() ? "-" + mode : "");
        }
        TrialContext ctx{&scenario,
                         &setup.registry,
                         planner,
                         setup.options,
                         setup.filter_options,
                         setup.budget,
                         max_steps,
                         config.seed * 1000003ULL + static_cast<uint64_t>(trial),
                         render_prefix,
                         config.trace,
                         mode != "geometric",
                         mode == "boxes",
                         setup.net,
                         setup.rollout,
                         config.plan_r_co,
                         setup.obstacle_reward,
                         setup.grid_sampling};
        return RunTrial(ctx);
      },
      "object search");
}

// Print one cell's JSON line: takes its summary, its trials and their perception frame times.
void PrintCell(const SearchBenchConfig& config, const BenchSetup& setup,
               const sim::Scenario& scenario, const std::string& planner, const std::string& mode,
               const RunSummary& s, const std::vector<EpisodeResult>& mine,
               const std::vector<double>& frame_ms) {
  std::string option_list;
  for (size_t i = 0; i < config.options.size(); ++i) {
    if (i > 0) option_list.append(", ");
    option_list.append("\"").append(JsonEscape(config.options[i])).append("\"");
  }
  std::string perception_ms;
  if (!frame_ms.empty()) {
    perception_ms = ", \"median_perception_ms_per_frame\": " + std::to_string(Median(frame_ms));
  }
  // Every trial's outcome, so that tables and comparisons can be recomputed from the file.
  std::string rewards, target_rewards, steps, successes;
  for (size_t k = 0; k < mine.size(); ++k) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%.1f", k ? ", " : "", mine[k].discounted_return);
    rewards += buf;
    std::snprintf(buf, sizeof buf, "%s%.1f", k ? ", " : "", mine[k].target_return);
    target_rewards += buf;
    if (k > 0) {
      steps.append(", ");
      successes.append(", ");
    }
    steps.append(std::to_string(mine[k].steps));
    successes.append(mine[k].success ? "1" : "0");
  }
  const std::string plan_r_co =
      config.plan_r_co ? std::to_string(*config.plan_r_co) : std::string("null");
  const std::string model_name = setup.registry.Find(planner)->takes_sampler && setup.net
                                     ? std::filesystem::path(setup.net->path()).filename().string()
                                     : std::string();
  const std::string name = config.label.empty() ? planner : config.label;
  const std::string base = config.label.empty() ? "" : ", \"base_planner\": \"" + planner + "\"";
  std::printf(
      "{\"scenario\": \"%s\", \"planner\": \"%s\"%s, \"observe\": \"%s\", \"trials\": %d, "
      "\"time_ms\": %g, \"cpu_ms\": %g, \"sims\": %lld, \"robot\": \"%s\", \"seed\": %llu, "
      "\"threads\": %d, \"options\": [%s], \"model\": \"%s\", \"rollout\": \"%s\", "
      "\"obstacle_reward\": \"%s\", \"grid_sampling\": \"%s\", \"plan_r_co\": %s, "
      "\"mean_discounted_reward\": %.1f, "
      "\"ci95\": %.1f, "
      "\"mean_steps\": %.2f, "
      "\"ci95_steps\": %.2f, \"success_rate\": %.3f, \"median_sims_per_step\": %.1f, "
      "\"median_sims_per_second\": %.1f, \"median_sims_per_cpu_second\": %.1f, "
      "\"median_cpu_ms_per_step\": %.1f, \"median_first_step_sims_per_second\": %.1f, "
      "\"wall_seconds\": %.1f, \"failed_trials\": %d, \"rewards\": [%s], "
      "\"target_rewards\": [%s], \"steps\": [%s], \"successes\": [%s]%s%s%s%s}\n",
      JsonEscape(scenario.name).c_str(), JsonEscape(name).c_str(), base.c_str(), mode.c_str(),
      config.trials, config.time_ms, config.cpu_ms, static_cast<long long>(config.sims),
      JsonEscape(scenario.robot.name).c_str(), static_cast<unsigned long long>(config.seed),
      config.threads, option_list.c_str(), JsonEscape(model_name).c_str(), config.rollout.c_str(),
      config.obstacle_reward.c_str(), config.grid_sampling.c_str(), plan_r_co.c_str(),
      s.mean_return, s.ci95_return, s.mean_steps, s.ci95_steps, s.success_rate.value_or(0.0),
      s.median_sims_per_step, s.median_sims_per_second, s.median_sims_per_cpu_second,
      s.median_cpu_ms_per_step, s.median_first_step_sims_per_second, s.wall_seconds,
      s.failed_episodes, rewards.c_str(), target_rewards.c_str(), steps.c_str(), successes.c_str(),
      perception_ms.c_str(), s.first_error.empty() ? "" : ", \"error\": \"",
      JsonEscape(s.first_error).c_str(), s.first_error.empty() ? "" : "\"");
}

// Summarise and print: takes every trial's result, gives each (scenario, variant) cell's
// summary in `table` (by row and scenario) after printing its JSON line; returns the failed
// trials.
int SummariseCells(const SearchBenchConfig& config, const BenchSetup& setup,
                   const std::vector<sim::Scenario>& scenarios, const JobGrid& grid,
                   const std::vector<EpisodeResult>& results, double wall,
                   std::map<std::string, std::map<std::string, RunSummary>>* table) {
  int failures = 0;
  for (size_t sc = 0; sc < scenarios.size(); ++sc) {
    for (int variant = 0; variant < grid.variants(); ++variant) {
      std::vector<EpisodeResult> mine;
      std::vector<double> frame_ms;
      for (int j = 0; j < grid.jobs(); ++j) {
        int s_idx, v_idx, trial;
        grid.Split(j, &s_idx, &v_idx, &trial);
        if (s_idx == static_cast<int>(sc) && v_idx == variant) {
          mine.push_back(results[j]);
          frame_ms.insert(frame_ms.end(), results[j].extra_ms.begin(), results[j].extra_ms.end());
        }
      }
      const RunSummary s = Summarize(mine, true, wall);
      (*table)[grid.RowName(variant)][scenarios[sc].name] = s;
      failures += s.failed_episodes;
      PrintCell(config, setup, scenarios[sc], grid.planner(variant), grid.mode(variant), s, mine,
                frame_ms);
    }
  }
  return failures;
}

// Write the table: a Markdown row per variant, a column per scenario; false (and a message)
// when the file cannot be written.
bool WriteTable(const std::string& path, const std::vector<sim::Scenario>& scenarios,
                const JobGrid& grid,
                std::map<std::string, std::map<std::string, RunSummary>>* table) {
  std::ostringstream md;
  md << "| Planner |";
  for (const auto& sc : scenarios) md << " " << sc.name << " |";
  md << "\n|---|";
  for (size_t i = 0; i < scenarios.size(); ++i) md << "---|";
  md << "\n";
  for (int variant = 0; variant < grid.variants(); ++variant) {
    const std::string row = grid.RowName(variant);
    md << "| " << row << " |";
    for (const auto& sc : scenarios) md << " " << Cell((*table)[row][sc.name]) << " |";
    md << "\n";
  }
  std::ofstream out(path);
  out << md.str();
  if (!out) {
    std::cerr << "npfkct-bench: cannot write " << path << "\n";
    return false;
  }
  return true;
}

}  // namespace

int RunObjectSearchBench(const SearchBenchConfig& config) {
  BenchSetup setup;
  if (!ParseOptions(config, &setup) || !CheckPlanners(config, &setup) ||
      !LoadFilter(config, &setup) || !CheckModesAndRollout(config, &setup)) {
    return 2;
  }
  std::vector<sim::Scenario> scenarios;
  if (!LoadScenarios(config, setup, &scenarios)) return 2;
  if (!config.render_dir.empty()) std::filesystem::create_directories(config.render_dir);
  const JobGrid grid(setup.planners, config.observe, static_cast<int>(scenarios.size()),
                     config.trials, config.label);
  const auto start = Clock::now();
  const std::vector<EpisodeResult> results = RunAllTrials(config, setup, scenarios, grid);
  const double wall = MillisSince(start) / 1000.0;
  std::map<std::string, std::map<std::string, RunSummary>> table;
  const int failures = SummariseCells(config, setup, scenarios, grid, results, wall, &table);
  std::fflush(stdout);
  if (!config.table_path.empty() && !WriteTable(config.table_path, scenarios, grid, &table)) {
    return 2;
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace npfkct::bench
