// npfkct-train: the neural process filter's dataset generation, training, evaluation and timing.
//   npfkct-train generate --out train.bin --samples 4000 --seed 1
//   npfkct-train train --train train.bin --val val.bin --out filter.pt
//   npfkct-train ensemble --models a.pt,b.pt,c.pt --out filter.pt
//   npfkct-train evaluate --model filter.pt --test test.bin
//   npfkct-train bench --model filter.pt
#include <torch/torch.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "npfkct/common/stats.h"
#include "npfkct/common/version.h"
#include "npfkct/filter/dataset.h"
#include "npfkct/filter/filter.h"
#include "npfkct/filter/train.h"
#include "npfkct/sim/scenario.h"
#include "npfkct/sim/scenegen.h"
#include "npfkct/sim/simulator.h"
#include "npfkct/solver/belief.h"
#include "npfkct/solver/planner.h"
#include "npfkct/train/generate.h"

namespace {

using namespace npfkct;
using namespace npfkct::filter;

// A progress bar on a terminal; nothing when stderr is a file or a pipe (logs stay readable).
void Bar(const std::string& label, int done, int total, const std::string& tail) {
  if (!isatty(STDERR_FILENO)) return;
  constexpr int kWidth = 30;
  const int filled = total > 0 ? done * kWidth / total : kWidth;
  std::fprintf(stderr, "\r%s [%s%s] %d/%d %s", label.c_str(), std::string(filled, '#').c_str(),
               std::string(kWidth - filled, ' ').c_str(), done, total, tail.c_str());
  std::fflush(stderr);
}

int Fail(const npfkct::Status& s) {
  std::cerr << "npfkct-train: " << s.ToString() << "\n";
  return 1;
}

// npfkct-train generate: a dataset file, and one JSON line of what it holds.
int Generate(const GenerateOptions& gen, const std::string& gen_out) {
  if (gen.scene_seed != 0 && gen.scene_seed + gen.scene_count > sim::kHeldOutSeedBase + 1 &&
      gen.scene_seed <= sim::kHeldOutSeedBase + 30) {
    std::cerr << "npfkct-train: note: scene seeds overlap the benchmark's held-out scenes ("
              << sim::kHeldOutSeedBase + 1 << "-" << sim::kHeldOutSeedBase + 30
              << "): use them for test sets only\n";
  }
  auto data = GenerateDataset(gen, [](int done, int total) {
    if (done % 10 == 0 || done == total) Bar("generate", done, total, "");
  });
  if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\n");
  if (!data.ok()) return Fail(data.status());
  int efficient = 0, total = 0;
  for (const Sample& s : data->samples) {
    for (float g : s.scores) efficient += g > kEfficientScore, ++total;
  }
  if (Status s = WriteDataset(*data, gen_out); !s.ok()) return Fail(s);
  std::printf(
      "{\"samples\": %zu, \"queries\": %d, \"efficient_fraction\": %.4f, \"file\": \"%s\"}\n",
      data->samples.size(), total, total ? double(efficient) / total : 0.0, gen_out.c_str());
  return 0;
}

// npfkct-train train: the best epoch's model file, and one JSON line.
int Train(const std::string& train_file, const std::string& val_file, const TrainOptions& train,
          const std::string& model_out, int threads) {
  SetComputeThreads(threads);
  auto t = ReadDataset(train_file);
  if (!t.ok()) return Fail(t.status());
  auto v = ReadDataset(val_file);
  if (!v.ok()) return Fail(v.status());
  auto report = TrainFilter(
      *t, *v, train, model_out,
      [&](int epoch, int step, int steps, double loss) {
        if (step % 5 == 0 || step == steps) {
          char tail[64];
          std::snprintf(tail, sizeof(tail), "loss %.4f", loss);
          Bar("epoch " + std::to_string(epoch) + "/" + std::to_string(train.epochs), step, steps,
              tail);
        }
      },
      [](const EpochReport& e) {
        std::fprintf(stderr, "%sepoch %d: train loss %.4f, validation loss %.4f (%.1f s)\n",
                     isatty(STDERR_FILENO) ? "\n" : "", e.epoch, e.train_loss, e.val_loss,
                     e.seconds);
      });
  if (!report.ok()) return Fail(report.status());
  std::printf("{\"best_epoch\": %d, \"best_val_loss\": %.5f, \"model\": \"%s\"}\n",
              report->best_epoch, report->best_val_loss, model_out.c_str());
  return 0;
}

// npfkct-train ensemble: the networks of several model files as one.
int Ensemble(const std::vector<std::string>& member_files, const std::string& ensemble_out) {
  if (Status s = NeuralFilter::Combine(member_files, ensemble_out); !s.ok()) return Fail(s);
  auto written = NeuralFilter::Load(ensemble_out);
  if (!written.ok()) return Fail(written.status());
  std::printf("{\"networks\": %d, \"model\": \"%s\"}\n", (*written)->members(),
              ensemble_out.c_str());
  return 0;
}

// npfkct-train evaluate: the test set's accuracy figures as one JSON line in *line.
Status Evaluate(const NeuralFilter& filter, const std::string& test_file, const FilterOptions& fo,
                const std::string& label, std::string* line) {
  auto test = ReadDataset(test_file);
  if (!test.ok()) return test.status();
  auto m = EvaluateFilter(filter, *test, fo);
  if (!m.ok()) return m.status();
  char buf[512];
  std::snprintf(buf, sizeof(buf),
                "{\"test_set\": \"%s\", \"test_samples\": %zu, \"queries\": %d, \"efficient\": "
                "%d, \"accuracy\": %.4f, \"accuracy_ci95\": %.4f, \"accuracy_clear\": %.4f, "
                "\"specificity\": %.4f, \"kept_efficient\": %.4f, \"dropped_useless\": %.4f, "
                "\"mean_abs_error\": %.4f, \"within_2_sigma\": %.4f}",
                label.c_str(), test->samples.size(), m->queries, m->efficient, m->accuracy,
                m->accuracy_ci95, m->accuracy_clear, m->specificity, m->kept_efficient,
                m->dropped_useless, m->mean_abs_error, m->within_2_sigma);
  *line = buf;
  return OkStatus();
}

// npfkct-train bench: the medians of scoring candidates on one core as one JSON line in *line.
Status Bench(const std::shared_ptr<NeuralFilter>& filter, const std::string& bench_scenario,
             const FilterOptions& fo, int runs, std::string* line) {
  // One core: the filter runs on the planning thread.
  auto sc = sim::LoadScenario(bench_scenario);
  if (!sc.ok()) return sc.status();
  sim::Simulator simulator(*sc, 1);
  auto world = simulator.InitialWorld();
  if (!world.ok()) return world.status();
  Rng rng(7);
  // One real step so that objects and odds are in the scene.
  const auto manual = world->ManualConfigurations();
  if (!manual.empty()) simulator.ExecuteMove(manual[0], world->params, rng);
  if (Status s = object_search::ApplyRealObservation(&*world, simulator.Observe(rng)); !s.ok()) {
    return s;
  }
  object_search::ObjectSearchModel model(std::make_shared<const object_search::World>(*world));
  std::vector<State> particles;
  for (int i = 0; i < 200; ++i) particles.push_back(model.SampleInitialState(rng));
  ParticleBelief<State> belief(particles);
  const State& s = particles[0];
  const auto placements = SamplePlacements(*world, fo.placements, rng);
  const SceneFeatures scene = SceneOf(*world, rng);
  const std::vector<Vec3> probe = SamplePlacements(*world, kProbePlacements, rng);
  const ScoredConfigs context = ScoreConfigs(model, s, placements, probe, fo.context, rng);
  const int candidate = object_search::TargetCandidate(*world);
  std::vector<object_search::RobotConfig> configs;
  object_search::ProposeMoves(model, TrainingProposals(), fo.candidates, rng, &configs, nullptr);
  std::vector<float> q(configs.size() * kQueryDim);
  for (size_t i = 0; i < configs.size(); ++i)
    QueryOf(*world, configs[i], candidate, probe, &q[i * kQueryDim]);
  std::vector<double> network, netsam, exact, scene_ms;
  auto sampler = MakeNetSam(filter, model, fo);
  if (!sampler.ok()) return sampler.status();
  for (int r = 0; r < runs + 3; ++r) {
    double t0 = ThreadCpuMillis();  // CPU time: the figures hold on a loaded machine
    const Prediction p = filter->Predict(scene, context.queries, context.scores, q);
    const double ms = ThreadCpuMillis() - t0;
    const TerminationCondition unlimited(Budget::Time(60'000.0));  // a fresh one each run
    t0 = ThreadCpuMillis();
    std::vector<ActionVec> out;
    CandidateStats stats;
    if (Status st = (*sampler)->Sample(belief, object_search::kMoveKind,
                                       model.KindSpace(object_search::kMoveKind), 256, unlimited,
                                       rng, &out, &stats);
        !st.ok()) {
      return st;
    }
    const double ns = ThreadCpuMillis() - t0;
    t0 = ThreadCpuMillis();
    const SceneFeatures encoded = SceneOf(*world, rng);
    const double sc_ms = ThreadCpuMillis() - t0;
    if (encoded.points.empty()) return InternalError("no scene features");
    if (r < 3) continue;  // warm-up
    network.push_back(ms);
    netsam.push_back(ns);
    scene_ms.push_back(sc_ms);
    if (r < 3 + 5) {
      t0 = ThreadCpuMillis();
      for (const auto& c : configs) TargetScore(model, s, candidate, c, placements);
      exact.push_back(ThreadCpuMillis() - t0);
    }
  }
  char buf[512];
  std::snprintf(
      buf, sizeof(buf),
      "{\"scenario\": \"%s\", \"networks\": %d, \"candidates\": %d, \"runs\": %d, "
      "\"threads\": 1, "
      "\"clock\": \"thread CPU\", \"median_network_ms\": %.3f, \"median_net_sam_ms\": %.3f, "
      "\"median_scene_features_ms\": %.3f, \"median_exact_score_ms\": %.3f}",
      sc->name.c_str(), filter->members(), fo.candidates, runs, Median(network), Median(netsam),
      Median(scene_ms), Median(exact));
  *line = buf;
  return OkStatus();
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"npfkct-train: dataset, training and evaluation of the neural process filter"};
  app.set_version_flag("--version", std::string("npfkct-train ") + npfkct::kVersion);
  app.require_subcommand(1);

  GenerateOptions gen;
  std::string gen_out;
  auto* generate = app.add_subcommand(
      "generate", "generate a dataset (paper algorithm 4) from scenario files or generated scenes");
  generate->add_option("--out", gen_out, "dataset file to write")->required();
  generate->add_option("--scenarios", gen.scenarios, "scenario files")->delimiter(',');
  generate->add_option("--scene-seed", gen.scene_seed,
                       "first npfkct-scenegen seed of the scenes (instead of files); training "
                       "data must stay below " +
                           std::to_string(sim::kHeldOutSeedBase));
  generate->add_option("--scene-count", gen.scene_count, "consecutive scene seeds");
  generate->add_option("--oracle-share", gen.oracle_share,
                       "share of the real steps before a snapshot chosen by the oracle");
  generate->add_option("--samples", gen.samples, "snapshots");
  generate->add_option("--queries", gen.queries_per_sample, "scored configurations per snapshot");
  generate->add_option("--placements", gen.placements, "target placements per score");
  generate->add_option("--max-steps", gen.max_steps, "random real steps before a snapshot");
  generate->add_option("--seed", gen.seed, "random seed");

  TrainOptions train;
  std::string train_file, val_file, model_out;
  int threads = 2;
  auto* tr = app.add_subcommand("train", "train the network (ELBO) and save the best epoch");
  tr->add_option("--train", train_file, "training dataset")->required();
  tr->add_option("--val", val_file, "validation dataset")->required();
  tr->add_option("--out", model_out, "model file to write")->required();
  tr->add_option("--epochs", train.epochs, "epochs");
  tr->add_option("--batch", train.batch, "snapshots per step");
  tr->add_option("--lr", train.learning_rate, "Adam learning rate");
  tr->add_option("--weight-decay", train.weight_decay, "Adam L2 penalty");
  tr->add_option("--lr-decay", train.lr_decay,
                 "factor on the learning rate every --lr-decay-every");
  tr->add_option("--lr-decay-every", train.lr_decay_every, "epochs between learning-rate decays");
  tr->add_option("--patience", train.patience, "epochs without a better validation loss to stop");
  tr->add_option("--seed", train.seed, "random seed");
  tr->add_option("--threads", threads, "libtorch threads");

  std::vector<std::string> member_files;
  std::string ensemble_out;
  auto* ens = app.add_subcommand(
      "ensemble", "write the networks of several model files as one ensemble model file");
  ens->add_option("--models", member_files, "model files (1 to 8 networks in all)")
      ->required()
      ->delimiter(',');
  ens->add_option("--out", ensemble_out, "model file to write")->required();

  std::string export_model, export_out;
  auto* exp = app.add_subcommand(
      "export", "write a model's weights as a .npw weight file (the filter without libtorch)");
  exp->add_option("--model", export_model, ".pt model file")->required();
  exp->add_option("--out", export_out, ".npw weight file to write")->required();

  FilterOptions fo;
  std::string model_file, test_file, json_out;
  auto* ev = app.add_subcommand("evaluate", "test-set accuracy (paper appendix G)");
  ev->add_option("--model", model_file, "model file")->required();
  ev->add_option("--test", test_file, "test dataset")->required();
  ev->add_option("--context", fo.context, "context configurations");
  ev->add_option("--confidence", fo.confidence, "C_threshold of Net_sam");
  ev->add_option("--json", json_out, "also write the figures to this file");
  std::string label;
  ev->add_option("--label", label, "name of the test set in the figures");

  std::string bench_scenario = std::string(NPFKCT_SCENARIO_DIR) + "/complex1.json";
  int runs = 50;
  auto* bench = app.add_subcommand("bench", "time scoring candidates on one core (medians)");
  bench->add_option("--model", model_file, "model file")->required();
  bench->add_option("--scenario", bench_scenario, "scenario file");
  bench->add_option("--candidates", fo.candidates, "candidates per call");
  bench->add_option("--runs", runs, "timed calls");
  bench->add_option("--json", json_out, "also write the figures to this file");

  CLI11_PARSE(app, argc, argv);

  if (*generate) return Generate(gen, gen_out);
  if (*tr) return Train(train_file, val_file, train, model_out, threads);
  if (*ens) return Ensemble(member_files, ensemble_out);
  if (*exp) {
    if (Status s = NeuralFilter::ExportWeights(export_model, export_out); !s.ok()) return Fail(s);
    std::printf("wrote %s\n", export_out.c_str());
    return 0;
  }
  auto filter = NeuralFilter::Load(model_file);
  if (!filter.ok()) return Fail(filter.status());
  std::string line;
  const Status made = *ev ? Evaluate(**filter, test_file, fo, label, &line)
                          : Bench(*filter, bench_scenario, fo, runs, &line);
  if (!made.ok()) return Fail(made);
  std::printf("%s\n", line.c_str());
  if (!json_out.empty()) {
    std::ofstream f(json_out, std::ios::app);
    f << line << "\n";
    if (!f) return Fail(InternalError("cannot write " + json_out));
  }
  return 0;
}
