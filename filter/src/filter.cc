#include "npfkct/filter/filter.h"

#include <xmmintrin.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <numeric>
#include <tuple>

#include "dense_net.h"
#include "net_shape.h"
#include "npfkct/object_search/proposals.h"
#include "npfkct/solver/option_table.h"
#ifdef NPFKCT_WITH_TORCH
#include "network.h"
#endif

// OpenBLAS's own thread count (libtorch's set_num_threads does not reach it). Weak: absent when
// the BLAS in use is another one.
extern "C" void openblas_set_num_threads(int num_threads) __attribute__((weak));

namespace npfkct::filter {

void SetComputeThreads(int threads) {
  threads = std::max(1, threads);
#ifdef NPFKCT_WITH_TORCH
  torch::set_num_threads(threads);
#endif
  if (openblas_set_num_threads != nullptr) openblas_set_num_threads(threads);
}

// A model's networks: libtorch's (a .pt file) or the dense ones (a .npw weight file).
struct NeuralFilter::Impl {
#ifdef NPFKCT_WITH_TORCH
  std::vector<NpNet> members;
#endif
  std::vector<DenseNet> dense;
  size_t size() const {
#ifdef NPFKCT_WITH_TORCH
    if (!members.empty()) return members.size();
#endif
    return dense.size();
  }
};

namespace {

using object_search::kMoveKind;

// Flushes denormal floats to zero on this thread while the network runs, and restores the
// thread's floating-point mode after: trained weights and activations near zero become
// denormals, which the BLAS kernels process many times slower (on a machine whose OpenBLAS falls
// back to its generic kernel, 1,000 candidates took 30 ms without this and 4 ms with it). The
// planner's own arithmetic around the call keeps the caller's mode.
class FlushDenormals {
 public:
  FlushDenormals() : saved_(_mm_getcsr()) { _mm_setcsr(saved_ | kFlushToZero | kDenormalsAreZero); }
  ~FlushDenormals() { _mm_setcsr(saved_); }
  FlushDenormals(const FlushDenormals&) = delete;
  FlushDenormals& operator=(const FlushDenormals&) = delete;

 private:
  static constexpr unsigned kFlushToZero = 0x8000;       // MXCSR.FTZ
  static constexpr unsigned kDenormalsAreZero = 0x0040;  // MXCSR.DAZ
  unsigned saved_;
};

// Inference runs on the calling thread: one libtorch intra-op thread, one OpenBLAS thread.
void SingleThreaded() {
  static std::once_flag once;
  std::call_once(once, [] { SetComputeThreads(1); });
}

#ifdef NPFKCT_WITH_TORCH
torch::Tensor FromVector(const std::vector<float>& v, std::vector<int64_t> shape) {
  return torch::from_blob(const_cast<float*>(v.data()), shape, torch::kFloat32);
}
#endif

bool IsWeightFile(const std::string& path) { return path.ends_with(".npw"); }

class NetSam final : public CandidateSampler<State> {
 public:
  NetSam(std::shared_ptr<const NeuralFilter> filter, const ObjectSearchModel& model,
         FilterOptions options)
      : filter_(std::move(filter)), model_(model), options_(options) {}

  std::vector<std::pair<std::string, double>> Settings() const override {
    return OptionValues(options_);
  }

  Status Sample(const ParticleBelief<State>& belief, int kind, const BoxSpace& box, int count,
                const TerminationCondition& stop, Rng& rng, std::vector<ActionVec>* out,
                CandidateStats* stats) override {
    // Discrete kinds, and a belief without the guessed target, get uniform candidates.
    if (kind != kMoveKind || belief.size() == 0 || belief.particles()[0].objects.empty()) {
      UniformCandidateSampler<State> uniform;
      return uniform.Sample(belief, kind, box, count, stop, rng, out, stats);
    }
    const World& w = model_.world();
    const State& s = belief.Sample(rng);
    const int candidate = object_search::TargetCandidate(w);
    object_search::ProposalOptions mix;
    mix.target_share = options_.target_share;
    mix.object_share = options_.object_share;
    // Proposals: aimed at the target candidate, at other known objects, or uniform.
    std::vector<RobotConfig> configs;
    std::vector<object_search::ProposalSource> sources;
    object_search::ProposeMoves(model_, mix, options_.candidates, rng, &configs, &sources, &stop);
    const int proposed = static_cast<int>(configs.size());  // fewer when the search must stop
    // The proposals as they are, unscored.
    auto unfiltered = [&] {
      const int n = std::min(count, proposed);
      for (int i = 0; i < n; ++i) out->push_back(box.Clamp(ObjectSearchModel::VecOf(configs[i])));
      if (stats != nullptr) {
        stats->sampled += proposed;
        stats->accepted += n;
      }
      return OkStatus();
    };
    // Every face of the candidate is confirmed: it can be declared, no view scores. Or the search
    // must stop (its budget, a cancellation, a resource limit) before the filter is through.
    if ((candidate > 0 && object_search::UnconfirmedFaces(w, candidate, +1) == 0) ||
        stop.ShouldStop(0)) {
      return unfiltered();
    }
    const std::vector<Vec3> placements = SamplePlacements(w, options_.placements, rng);
    const std::vector<Vec3> probe = SamplePlacements(w, kProbePlacements, rng);
    const SceneFeatures scene = SceneOf(w, rng);
    // Context: configurations scored exactly, drawn as in training.
    const ScoredConfigs context =
        ScoreConfigs(model_, s, placements, probe, options_.context, rng, &stop);
    if (stop.ShouldStop(0)) return unfiltered();
    std::vector<std::pair<double, ActionVec>> known_good;
    for (size_t i = 0; i < context.scores.size(); ++i) {
      const ActionVec x = ObjectSearchModel::VecOf(context.configs[i]);
      if (context.scores[i] > kEfficientScore && box.Contains(x)) {
        known_good.push_back({context.scores[i], x});
      }
    }
    // The network scores the views of the target candidate and the uniform ones; views aimed at
    // other objects' faces serve their declaration as obstacles, which g does not score.
    std::vector<int> scored, objects;
    for (int i = 0; i < proposed; ++i) {
      (sources[i] == object_search::ProposalSource::kObject ? objects : scored).push_back(i);
    }
    std::vector<float> q(scored.size() * kQueryDim);
    for (size_t j = 0; j < scored.size(); ++j) {
      if (j % 256 == 255 && stop.ShouldStop(0)) return unfiltered();
      QueryOf(w, configs[scored[j]], candidate, probe, &q[j * kQueryDim]);
    }
    Prediction p;
    if (options_.exact != 0) {
      p.mu.resize(scored.size());
      p.sigma.assign(scored.size(), 0.0f);
      for (size_t j = 0; j < scored.size(); ++j) {
        // One exact score checks every placement (up to 10,000 of them).
        if (stop.ShouldStop(0)) return unfiltered();
        p.mu[j] =
            static_cast<float>(TargetScore(model_, s, candidate, configs[scored[j]], placements));
      }
    } else {
      p = filter_->Predict(scene, context.queries, context.scores, q, &stop);
    }
    if (p.mu.size() < scored.size()) return unfiltered();
    const double beta = options_.Beta();
    std::vector<std::pair<double, int>> ranked(scored.size());
    for (size_t j = 0; j < scored.size(); ++j) {
      ranked[j] = {p.mu[j] - beta * p.sigma[j], scored[j]};
    }
    std::sort(ranked.begin(), ranked.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    std::sort(known_good.begin(), known_good.end(),
              [](const auto& a, const auto& b) { return a.first > b.first; });
    const int added = Keep(count, box, configs, sources, known_good, ranked, objects, out);
    // The caller (kCT's EnsureSpheres) times the call into stats->elapsed_ms.
    if (stats != nullptr) {
      stats->sampled += proposed + static_cast<int>(context.scores.size());
      stats->accepted += added;
    }
    return OkStatus();
  }

 private:
  // Net_sam's choice (algorithm 5) among the proposals: mu > beta* sigma, best first, with the
  // exactly scored efficient context configurations; at least min_keep; the object views in
  // their share of `count`; a share of uniform (explore) configurations the filter did not keep.
  // Appends them to `out` and returns how many.
  int Keep(int count, const BoxSpace& box, const std::vector<RobotConfig>& configs,
           const std::vector<object_search::ProposalSource>& sources,
           const std::vector<std::pair<double, ActionVec>>& known_good,
           const std::vector<std::pair<double, int>>& ranked, const std::vector<int>& objects,
           std::vector<ActionVec>* out) const {
    const int proposed = static_cast<int>(configs.size());
    const int object_keep = std::min(static_cast<int>(objects.size()),
                                     static_cast<int>(std::lround(options_.object_share * count)));
    const int explore = static_cast<int>(std::lround(options_.explore * count));
    const int filtered = std::max(1, count - explore - object_keep);
    std::vector<bool> used(proposed, false);
    int added = 0;
    for (const auto& [g, x] : known_good) {
      if (added >= filtered) break;
      out->push_back(x);
      ++added;
    }
    for (const auto& [score, i] : ranked) {
      if (added >= filtered) break;
      if (score <= 0.0 && added >= options_.min_keep) break;
      out->push_back(box.Clamp(ObjectSearchModel::VecOf(configs[i])));
      used[i] = true;
      ++added;
    }
    for (int k = 0; k < object_keep; ++k) {
      out->push_back(box.Clamp(ObjectSearchModel::VecOf(configs[objects[k]])));
      used[objects[k]] = true;
      ++added;
    }
    for (int i = 0; i < proposed && added < count && explore > 0; ++i) {
      if (used[i] || sources[i] != object_search::ProposalSource::kUniform) continue;
      out->push_back(box.Clamp(ObjectSearchModel::VecOf(configs[i])));
      ++added;
    }
    return added;
  }

  std::shared_ptr<const NeuralFilter> filter_;
  const ObjectSearchModel& model_;
  FilterOptions options_;
};

}  // namespace

Status FilterOptions::Validate() const {
  // Upper bounds keep one request from asking for gigabytes of candidates.
  if (candidates < 1 || candidates > 100000) {
    return InvalidArgumentError("candidates must be in [1, 100000]");
  }
  if (!(confidence > 0.0 && confidence < 1.0)) {
    return InvalidArgumentError("confidence must be in (0, 1)");
  }
  if (context < 1 || context > 1000) return InvalidArgumentError("context must be in [1, 1000]");
  if (placements < 1 || placements > 10000) {
    return InvalidArgumentError("placements must be in [1, 10000]");
  }
  if (min_keep < 1) return InvalidArgumentError("min_keep must be >= 1");
  if (!(explore >= 0.0 && explore < 1.0)) return InvalidArgumentError("explore must be in [0, 1)");
  if (!(target_share >= 0.0 && target_share <= 1.0)) {
    return InvalidArgumentError("target_share must be in [0, 1]");
  }
  if (!(object_share >= 0.0 && object_share <= 1.0 - target_share)) {
    return InvalidArgumentError("object_share must be in [0, 1 - target_share]");
  }
  if (exact != 0 && exact != 1) return InvalidArgumentError("exact must be 0 or 1");
  if (explore + object_share >= 1.0) {
    return InvalidArgumentError("explore + object_share must be below 1");
  }
  return OkStatus();
}

namespace {

const option_table::Table<FilterOptions>& FilterTable() {
  using option_table::Int;
  using option_table::Real;
  static const auto* table = new option_table::Table<FilterOptions>{
      {"candidates", Int(&FilterOptions::candidates)},
      {"confidence", Real(&FilterOptions::confidence)},
      {"context", Int(&FilterOptions::context)},
      {"placements", Int(&FilterOptions::placements)},
      {"min_keep", Int(&FilterOptions::min_keep)},
      {"explore", Real(&FilterOptions::explore)},
      {"target_share", Real(&FilterOptions::target_share)},
      {"object_share", Real(&FilterOptions::object_share)},
      {"exact", Int(&FilterOptions::exact)},
  };
  return *table;
}

}  // namespace

Status SetOption(FilterOptions* o, std::string_view key, double value) {
  return option_table::Apply(FilterTable(), o, key, value);
}

std::vector<std::pair<std::string, double>> OptionValues(const FilterOptions& o) {
  return option_table::Values(FilterTable(), o);
}

double FilterOptions::Beta() const { return std::sqrt(2.0 * std::log(1.0 / (1.0 - confidence))); }

NeuralFilter::~NeuralFilter() = default;

bool CanLoadModel(std::string_view name) {
  if (name.ends_with(".npw")) return true;
#ifdef NPFKCT_WITH_TORCH
  return name.ends_with(".pt");
#else
  return false;
#endif
}

StatusOr<std::shared_ptr<NeuralFilter>> NeuralFilter::Load(const std::string& path) {
  SingleThreaded();
  std::shared_ptr<NeuralFilter> f(new NeuralFilter());
  f->impl_ = std::make_unique<Impl>();
  f->path_ = path;
  if (IsWeightFile(path)) {
    auto dense = ReadWeights(path);
    if (!dense.ok()) return dense.status();
    f->impl_->dense = *std::move(dense);
    return f;
  }
#ifdef NPFKCT_WITH_TORCH
  auto members = LoadMembers(path);
  if (!members.ok()) return members.status();
  f->impl_->members = *std::move(members);
  return f;
#else
  return InvalidArgumentError("'" + path +
                              "': this build has no libtorch and reads weight files (.npw) only "
                              "(npfkct-train export writes one from a .pt model)");
#endif
}

Status NeuralFilter::ExportWeights(const std::string& model, const std::string& out) {
#ifdef NPFKCT_WITH_TORCH
  auto members = LoadMembers(model);
  if (!members.ok()) return members.status();
  std::vector<std::vector<NamedTensor>> tensors;
  for (NpNet& net : *members) tensors.push_back(ExportTensors(net));
  return WriteWeights(tensors, out);
#else
  (void)model;
  (void)out;
  return Status(StatusCode::kUnimplemented, "this build has no libtorch to read .pt models");
#endif
}

Status NeuralFilter::Combine(const std::vector<std::string>& paths, const std::string& out) {
#ifndef NPFKCT_WITH_TORCH
  (void)paths;
  (void)out;
  return Status(StatusCode::kUnimplemented, "this build has no libtorch to write .pt models");
#else
  std::vector<NpNet> all;
  for (const std::string& path : paths) {
    auto members = LoadMembers(path);
    if (!members.ok()) return members.status();
    if (all.size() + members->size() > static_cast<size_t>(kMaxMembers)) {
      return InvalidArgumentError("an ensemble holds at most " + std::to_string(kMaxMembers) +
                                  " networks");
    }
    for (NpNet& net : *members) all.push_back(net);
  }
  return SaveMembers(all, out);
#endif
}

int NeuralFilter::members() const { return static_cast<int>(impl_->size()); }

Prediction NeuralFilter::Predict(const SceneFeatures& scene,
                                 const std::vector<float>& context_queries,
                                 const std::vector<float>& context_scores,
                                 const std::vector<float>& queries,
                                 const TerminationCondition* stop) const {
  const FlushDenormals flush;
  const int64_t n = static_cast<int64_t>(queries.size() / kQueryDim);
  if (n == 0 || context_scores.empty()) {
    // Without context the latent path is undefined: every query passes.
    Prediction out;
    out.mu.assign(n, 1.0f);
    out.sigma.assign(n, static_cast<float>(kMinSigma));
    return out;
  }
  if (!impl_->dense.empty())
    return PredictDense(scene, context_queries, context_scores, queries, stop);
#ifndef NPFKCT_WITH_TORCH
  return Prediction{};
#else
  torch::InferenceMode guard;
  const int64_t m = static_cast<int64_t>(context_scores.size());
  Prediction out;
  // Per network: the scene and the context encoded once, then the queries in blocks (given the
  // context, each query's prediction is its own: blocks change no result).
  struct Encoded {
    torch::Tensor scene, xc, z;
  };
  const torch::Tensor yc = FromVector(context_scores, {1, m, 1});
  std::vector<Encoded> encoded;
  for (NpNet& net : impl_->members) {
    Encoded e;
    e.scene =
        net->EncodeScene(FromVector(scene.points, {1, kPoints, kPointDim}),
                         FromVector(scene.image, {1, kImageChannels, kImageSize, kImageSize}));
    e.xc = net->EncodeQuery(FromVector(context_queries, {1, m, kQueryDim}));
    e.z = net->Latent(e.scene, e.xc, yc).first;
    encoded.push_back(std::move(e));
  }
  const double members = static_cast<double>(impl_->members.size());
  constexpr int64_t kBlock = 4096;
  out.mu.reserve(n);
  out.sigma.reserve(n);
  for (int64_t a = 0; a < n; a += kBlock) {
    if (a > 0 && stop != nullptr && stop->ShouldStop(0)) break;
    const int64_t rows = std::min(kBlock, n - a);
    const torch::Tensor block = torch::from_blob(const_cast<float*>(queries.data() + a * kQueryDim),
                                                 {1, rows, kQueryDim}, torch::kFloat32);
    // Network k's mu and sigma of the block.
    auto predict = [&](size_t k) {
      NpNet& net = impl_->members[k];
      const Encoded& e = encoded[k];
      const torch::Tensor xt = net->EncodeQuery(block);
      return net->Decode(e.scene, xt, net->Deterministic(e.scene, e.xc, yc, xt), e.z);
    };
    torch::Tensor mu, sigma;
    if (members == 1) {
      std::tie(mu, sigma) = predict(0);
    } else {
      // The mixture's first two moments.
      torch::Tensor sum_mu, sum_second;
      for (size_t k = 0; k < impl_->members.size(); ++k) {
        // Each network costs one prediction: after the first block the search's stop is heard
        // between them too (the block is then dropped).
        if (a > 0 && k > 0 && stop != nullptr && stop->ShouldStop(0)) return out;
        auto [mu_k, sigma_k] = predict(k);
        const torch::Tensor second = sigma_k * sigma_k + mu_k * mu_k;
        sum_mu = k == 0 ? mu_k : sum_mu + mu_k;
        sum_second = k == 0 ? second : sum_second + second;
      }
      mu = sum_mu / members;
      sigma = torch::sqrt(torch::clamp_min(sum_second / members - mu * mu, kMinSigma * kMinSigma));
    }
    mu = mu.contiguous();
    sigma = sigma.contiguous();
    out.mu.insert(out.mu.end(), mu.data_ptr<float>(), mu.data_ptr<float>() + rows);
    out.sigma.insert(out.sigma.end(), sigma.data_ptr<float>(), sigma.data_ptr<float>() + rows);
  }
  return out;
#endif
}

// Predict's dense path, given a context and queries: the same steps as libtorch's (the scene and
// the context encoded once per network, the queries in blocks, an ensemble's mixture moments).
Prediction NeuralFilter::PredictDense(const SceneFeatures& scene,
                                      const std::vector<float>& context_queries,
                                      const std::vector<float>& context_scores,
                                      const std::vector<float>& queries,
                                      const TerminationCondition* stop) const {
  const int m = static_cast<int>(context_scores.size());
  const int64_t n = static_cast<int64_t>(queries.size() / kQueryDim);
  Prediction out;
  struct Encoded {
    DenseNet::Vector scene, z;
    DenseNet::Matrix xc;
  };
  std::vector<Encoded> encoded;
  for (const DenseNet& net : impl_->dense) {
    Encoded e;
    e.scene = net.EncodeScene(scene.points.data(), scene.image.data());
    e.xc = net.EncodeQuery(context_queries.data(), m);
    e.z = net.LatentMean(e.scene, e.xc, context_scores.data());
    encoded.push_back(std::move(e));
  }
  const float members = static_cast<float>(impl_->dense.size());
  constexpr int64_t kBlock = 4096;
  out.mu.reserve(n);
  out.sigma.reserve(n);
  for (int64_t a = 0; a < n; a += kBlock) {
    if (a > 0 && stop != nullptr && stop->ShouldStop(0)) break;
    const int rows = static_cast<int>(std::min(kBlock, n - a));
    DenseNet::Vector sum_mu = DenseNet::Vector::Zero(rows);
    DenseNet::Vector sum_second = DenseNet::Vector::Zero(rows);
    DenseNet::Vector mu, sigma;
    for (size_t k = 0; k < impl_->dense.size(); ++k) {
      if (a > 0 && k > 0 && stop != nullptr && stop->ShouldStop(0)) return out;
      const DenseNet& net = impl_->dense[k];
      const Encoded& e = encoded[k];
      const DenseNet::Matrix xt = net.EncodeQuery(queries.data() + a * kQueryDim, rows);
      auto [mu_k, sigma_k] = net.Decode(e.scene, e.xc, context_scores.data(), xt, e.z);
      if (impl_->dense.size() == 1) {
        mu = std::move(mu_k);
        sigma = std::move(sigma_k);
        break;
      }
      sum_mu += mu_k;
      sum_second += (sigma_k.array().square() + mu_k.array().square()).matrix();
    }
    if (impl_->dense.size() > 1) {
      mu = sum_mu / members;
      const float floor = static_cast<float>(kMinSigma * kMinSigma);
      sigma = (sum_second / members - mu.cwiseProduct(mu)).cwiseMax(floor).cwiseSqrt();
    }
    out.mu.insert(out.mu.end(), mu.data(), mu.data() + rows);
    out.sigma.insert(out.sigma.end(), sigma.data(), sigma.data() + rows);
  }
  return out;
}

StatusOr<std::shared_ptr<CandidateSampler<State>>> MakeNetSam(
    std::shared_ptr<const NeuralFilter> filter, const ObjectSearchModel& model,
    FilterOptions options) {
  if (Status s = options.Validate(); !s.ok()) return s;
  if (!filter) return InvalidArgumentError("filter: no model loaded");
  return std::shared_ptr<CandidateSampler<State>>(
      std::make_shared<NetSam>(std::move(filter), model, options));
}

}  // namespace npfkct::filter
