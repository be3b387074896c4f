// Dataset generation (paper algorithm 4) with the built-in simulator: a tool of the filter,
// kept out of the run-time library npfkct_filter so that it does not link the simulator.
#include "generate.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>

#include "npfkct/sim/scenario.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::filter {
namespace {

Sample MakeSample(const ObjectSearchModel& model, const GenerateOptions& o, Rng& rng) {
  const World& w = model.world();
  Sample out;
  const State s = model.SampleInitialState(rng);
  const std::vector<Vec3> placements = SamplePlacements(w, o.placements, rng);
  out.scene = SceneOf(w, rng);
  // Aimed and uniform queries alternate, so both kinds are in every context drawn from them.
  ScoredConfigs scored = ScoreConfigs(model, s, placements, o.queries_per_sample, rng);
  out.queries = std::move(scored.queries);
  out.scores = std::move(scored.scores);
  return out;
}

}  // namespace

Status GenerateOptions::Validate() const {
  if (scenarios.empty()) return InvalidArgumentError("scenarios: at least one scenario file");
  if (samples < 1) return InvalidArgumentError("samples must be >= 1");
  if (queries_per_sample < 2) return InvalidArgumentError("queries_per_sample must be >= 2");
  if (placements < 1) return InvalidArgumentError("placements must be >= 1");
  if (max_steps < 0) return InvalidArgumentError("max_steps must be >= 0");
  if (!(object_jitter >= 0.0) || !std::isfinite(object_jitter)) {
    return InvalidArgumentError("object_jitter must be >= 0");
  }
  if (!(drop_object >= 0.0 && drop_object < 1.0)) {
    return InvalidArgumentError("drop_object must be in [0, 1)");
  }
  return OkStatus();
}

StatusOr<Dataset> GenerateDataset(const GenerateOptions& options,
                                  void (*progress)(int done, int total)) {
  if (Status s = options.Validate(); !s.ok()) return s;
  std::vector<sim::Scenario> scenarios;
  for (const std::string& path : options.scenarios) {
    auto sc = sim::LoadScenario(path);
    if (!sc.ok()) {
      return Status(sc.status().code(), "scenarios: " + path + ": " + sc.status().message());
    }
    scenarios.push_back(*std::move(sc));
  }
  Rng rng(options.seed);
  Dataset data;
  data.queries_per_sample = options.queries_per_sample;
  data.samples.reserve(options.samples);
  while (static_cast<int>(data.samples.size()) < options.samples) {
    // A random scene: one of the scenarios, objects jittered, some non-targets left out.
    sim::Scenario sc = scenarios[rng.UniformInt(static_cast<int64_t>(scenarios.size()))];
    sc.noise.object_jitter = options.object_jitter;
    std::vector<sim::SceneObject> kept;
    for (const auto& obj : sc.objects) {
      if (obj.target || !rng.Bernoulli(options.drop_object)) kept.push_back(obj);
    }
    sc.objects = std::move(kept);
    sim::Simulator simulator(sc, rng());
    auto initial = simulator.InitialWorld();
    if (!initial.ok()) return initial.status();
    World world = *std::move(initial);
    ObjectSearchModel model(std::make_shared<const World>(world));
    const std::vector<RobotConfig> manual = world.ManualConfigurations();
    const int steps = static_cast<int>(rng.UniformInt(options.max_steps + 1));
    // A random action sequence; a snapshot after every real step.
    for (int step = 0; step <= steps; ++step) {
      if (step > 0) {
        RobotConfig c;
        const double u = rng.Uniform();
        if (u < 1.0 / 3.0 && !manual.empty()) {
          c = manual[rng.UniformInt(static_cast<int64_t>(manual.size()))];
        } else {
          c = SampleConfig(model, SamplePlacements(world, 8, rng), u < 2.0 / 3.0, rng);
        }
        simulator.ExecuteMove(c, world.params, rng);
        if (Status s = object_search::ApplyRealObservation(&world, simulator.Observe(rng));
            !s.ok()) {
          return s;
        }
        model.SetWorld(std::make_shared<const World>(world));
      }
      data.samples.push_back(MakeSample(model, options, rng));
      if (progress != nullptr) progress(static_cast<int>(data.samples.size()), options.samples);
      if (static_cast<int>(data.samples.size()) >= options.samples) break;
    }
  }
  return data;
}

}  // namespace npfkct::filter
