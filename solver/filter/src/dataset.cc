#include "npfkct/filter/dataset.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <memory>

#include "npfkct/sim/scenario.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::filter {
namespace {

constexpr char kMagic[8] = {'N', 'P', 'F', 'K', 'D', 'S', '0', '1'};
constexpr int32_t kVersion = 1;

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

template <class T>
void Put(std::ofstream& f, const T* data, size_t n) {
  f.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(n * sizeof(T)));
}

template <class T>
bool Get(std::ifstream& f, T* data, size_t n) {
  f.read(reinterpret_cast<char*>(data), static_cast<std::streamsize>(n * sizeof(T)));
  return static_cast<size_t>(f.gcount()) == n * sizeof(T);
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

Status WriteDataset(const Dataset& data, const std::string& path) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  if (!f) return InvalidArgumentError("cannot write " + path);
  const int32_t header[8] = {kVersion,
                             kPoints,
                             kPointDim,
                             kImageSize,
                             kImageChannels,
                             kQueryDim,
                             data.queries_per_sample,
                             static_cast<int32_t>(data.samples.size())};
  f.write(kMagic, sizeof(kMagic));
  Put(f, header, 8);
  std::vector<uint8_t> image(kImageChannels * kImageSize * kImageSize);
  for (const Sample& s : data.samples) {
    if (s.num_queries() != data.queries_per_sample ||
        s.queries.size() != s.scores.size() * kQueryDim ||
        s.scene.points.size() != static_cast<size_t>(kPoints * kPointDim) ||
        s.scene.image.size() != image.size()) {
      return InvalidArgumentError("dataset: a sample has the wrong shape");
    }
    Put(f, s.scene.points.data(), s.scene.points.size());
    for (size_t i = 0; i < image.size(); ++i) {
      image[i] = static_cast<uint8_t>(std::lround(std::clamp(s.scene.image[i], 0.0f, 1.0f) * 255));
    }
    Put(f, image.data(), image.size());
    Put(f, s.queries.data(), s.queries.size());
    Put(f, s.scores.data(), s.scores.size());
  }
  f.flush();
  if (!f) return InternalError("write failed: " + path);
  return OkStatus();
}

StatusOr<Dataset> ReadDataset(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return InvalidArgumentError("cannot open " + path);
  char magic[8];
  int32_t header[8];
  if (!Get(f, magic, 8) || std::memcmp(magic, kMagic, 8) != 0) {
    return InvalidArgumentError(path + ": not an npfkct filter dataset (bad magic)");
  }
  if (!Get(f, header, 8)) return InvalidArgumentError(path + ": truncated header");
  const int32_t expect[6] = {kVersion, kPoints, kPointDim, kImageSize, kImageChannels, kQueryDim};
  if (std::memcmp(header, expect, sizeof(expect)) != 0) {
    return InvalidArgumentError(path + ": dataset version or feature sizes differ from this build");
  }
  const int m = header[6], n = header[7];
  if (m < 1 || n < 0) return InvalidArgumentError(path + ": bad sample counts");
  Dataset data;
  data.queries_per_sample = m;
  data.samples.resize(n);
  std::vector<uint8_t> image(kImageChannels * kImageSize * kImageSize);
  for (int i = 0; i < n; ++i) {
    Sample& s = data.samples[i];
    s.scene.points.resize(kPoints * kPointDim);
    s.scene.image.resize(image.size());
    s.queries.resize(static_cast<size_t>(m) * kQueryDim);
    s.scores.resize(m);
    if (!Get(f, s.scene.points.data(), s.scene.points.size()) ||
        !Get(f, image.data(), image.size()) || !Get(f, s.queries.data(), s.queries.size()) ||
        !Get(f, s.scores.data(), s.scores.size())) {
      return InvalidArgumentError(path + ": truncated at sample " + std::to_string(i));
    }
    for (size_t k = 0; k < image.size(); ++k) s.scene.image[k] = image[k] / 255.0f;
  }
  return data;
}

}  // namespace npfkct::filter
