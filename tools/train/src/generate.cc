#include "npfkct/train/generate.h"

#include <cmath>
#include <memory>
#include <optional>

#include "npfkct/filter/features.h"
#include "npfkct/sim/oracle.h"
#include "npfkct/sim/scenario.h"
#include "npfkct/sim/scenegen.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::filter {
namespace {

// A snapshot of the model's current world with o.queries_per_sample scored configurations, or
// nullopt where the world leaves too few free bases for them: proposals without a free base are
// dropped (ProposeMoves), so a short draw is topped up by further draws, up to 8.
std::optional<Sample> MakeSample(const ObjectSearchModel& model, const GenerateOptions& o,
                                 Rng& rng) {
  const World& w = model.world();
  Sample out;
  const State s = model.SampleInitialState(rng);
  const std::vector<Vec3> placements = SamplePlacements(w, o.placements, rng);
  const std::vector<Vec3> probe = SamplePlacements(w, kProbePlacements, rng);
  out.scene = SceneOf(w, rng);
  for (int draw = 0; draw < 8 && out.num_queries() < o.queries_per_sample; ++draw) {
    const ScoredConfigs scored =
        ScoreConfigs(model, s, placements, probe, o.queries_per_sample - out.num_queries(), rng);
    out.queries.insert(out.queries.end(), scored.queries.begin(), scored.queries.end());
    out.scores.insert(out.scores.end(), scored.scores.begin(), scored.scores.end());
  }
  if (out.num_queries() != o.queries_per_sample) return std::nullopt;
  return out;
}

}  // namespace

Status GenerateOptions::Validate() const {
  if (scene_seed == 0 && scenarios.empty()) {
    return InvalidArgumentError("scenarios: give scenario files or a scene seed range");
  }
  if (scene_seed != 0 && (scene_count < 1 || scene_count > 10000000)) {
    return InvalidArgumentError("scene_count must be in [1, 1e7]");
  }
  if (samples < 1) return InvalidArgumentError("samples must be >= 1");
  if (queries_per_sample < 2) return InvalidArgumentError("queries_per_sample must be >= 2");
  if (placements < 1) return InvalidArgumentError("placements must be >= 1");
  if (max_steps < 0) return InvalidArgumentError("max_steps must be >= 0");
  if (!(oracle_share >= 0.0 && oracle_share <= 1.0)) {
    return InvalidArgumentError("oracle_share must be in [0, 1]");
  }
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
  std::vector<sim::Scenario> files;
  for (const std::string& path : options.scenarios) {
    auto sc = sim::LoadScenario(path);
    if (!sc.ok()) {
      return Status(sc.status().code(), "scenarios: " + path + ": " + sc.status().message());
    }
    files.push_back(*std::move(sc));
  }
  Rng rng(options.seed);
  Dataset data;
  data.queries_per_sample = options.queries_per_sample;
  data.samples.reserve(options.samples);
  int barren = 0;  // scenes in a row that gave no snapshot
  while (static_cast<int>(data.samples.size()) < options.samples) {
    if (++barren > 1000) {
      return FailedPreconditionError(
          "scenarios: 1,000 scenes in a row leave too few free bases for a snapshot's proposals");
    }
    sim::Scenario sc;
    if (options.scene_seed != 0) {
      const uint64_t seed = options.scene_seed + rng.UniformInt(options.scene_count);
      auto parsed = sim::ParseScenario(sim::GenerateScenarioJson(seed));
      if (!parsed.ok()) return parsed.status();
      sc = *std::move(parsed);
    } else {
      // A scenario file with its objects jittered and some non-targets left out.
      sc = files[rng.UniformInt(static_cast<int64_t>(files.size()))];
      sc.noise.object_jitter = options.object_jitter;
      std::vector<sim::SceneObject> kept;
      for (const auto& obj : sc.objects) {
        if (obj.target || !rng.Bernoulli(options.drop_object)) kept.push_back(obj);
      }
      sc.objects = std::move(kept);
    }
    sim::Simulator simulator(sc, rng());
    auto initial = simulator.InitialWorld();
    if (!initial.ok()) return initial.status();
    World world = *std::move(initial);
    if (Status s = object_search::ApplyRealObservation(&world, simulator.Observe(rng)); !s.ok()) {
      return s;
    }
    ObjectSearchModel model(std::make_shared<const World>(world));
    const sim::Oracle oracle(simulator);
    const int steps = static_cast<int>(rng.UniformInt(options.max_steps + 1));
    // A snapshot after every real step.
    for (int step = 0; step <= steps; ++step) {
      if (step > 0) {
        HybridAction a;
        if (rng.Bernoulli(options.oracle_share)) {
          a = oracle.Next(world);
        } else {
          std::vector<RobotConfig> configs;
          object_search::ProposeMoves(model, TrainingProposals(), 1, rng, &configs, nullptr);
          if (configs.empty()) break;  // no feasible base found: no further real step
          a = HybridAction{object_search::kMoveKind, ObjectSearchModel::VecOf(configs[0])};
        }
        const sim::ExecutionOutcome out = simulator.Execute(a, world, rng);
        if (out.terminal) break;  // the target is gone: nothing left to search for
        if (a.kind != object_search::kMoveKind && out.success) {
          if (Status s =
                  object_search::ApplyDiscreteOutcome(&world, object_search::KindObject(a.kind),
                                                      object_search::KindOffset(a.kind), true);
              !s.ok()) {
            return s;
          }
        }
        if (Status s = object_search::ApplyRealObservation(&world, simulator.Observe(rng));
            !s.ok()) {
          return s;
        }
        model.SetWorld(std::make_shared<const World>(world));
      }
      std::optional<Sample> sample = MakeSample(model, options, rng);
      if (!sample.has_value()) break;  // hardly a free base: no snapshot of this scene
      data.samples.push_back(*std::move(sample));
      barren = 0;
      if (progress != nullptr) progress(static_cast<int>(data.samples.size()), options.samples);
      if (static_cast<int>(data.samples.size()) >= options.samples) break;
    }
  }
  return data;
}

}  // namespace npfkct::filter
