// The trained neural process filter and Net_sam (paper algorithm 5): candidate configurations
// scored by the network, those with mu > beta* sigma kept as NPF-kCT's candidates. libtorch stays
// behind this header.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/filter/features.h"
#include "npfkct/solver/candidates.h"

namespace npfkct::filter {

/// Settings of Net_sam.
struct FilterOptions {
  int candidates = 1000;    ///< Configurations scored per call.
  double confidence = 0.5;  ///< C_threshold: beta* = sqrt(2 log(1 / (1 - C))).
  int context = 16;         ///< Configurations scored exactly to condition the network.
  int placements = 64;      ///< Target placements per exact score.
  int min_keep = 16;        ///< When fewer pass, the best min_keep by mu - beta* sigma.
  /// Share of the candidates returned that are uniform ones the filter did not keep.
  double explore = 0.0;
  /// The proposals scored: share aimed at the target candidate (placements of the guessed target
  /// or unconfirmed faces of a detected one), share aimed at other known objects' unconfirmed
  /// faces (kept unscored, up to that share of the candidates returned: g does not value views
  /// that confirm an obstacle), the rest uniform.
  double target_share = 0.7;
  double object_share = 0.2;
  /// 1: rank the proposals by g computed exactly in place of the network's prediction (sigma 0):
  /// the filter's ceiling, a network that predicted its label without error. 0: the network.
  int exact = 0;
  /// Checks every field; the message names the offending one.
  Status Validate() const;
  /// beta* of the confidence.
  double Beta() const;
};

/// Sets FilterOptions field `key` (snake_case: candidates, confidence, context, placements,
/// min_keep, explore, target_share, object_share, exact) to `value`; unknown keys and non-integers
/// for integer fields are INVALID_ARGUMENT naming the key (Validate() checks the ranges).
Status SetOption(FilterOptions* o, std::string_view key, double value);
/// Every FilterOptions field as (key, value), keyed as SetOption's keys, in key order.
std::vector<std::pair<std::string, double>> OptionValues(const FilterOptions& o);

/// The file name of the shipped model this build loads by default: filter.pt, or filter.npw in a
/// build without libtorch.
inline constexpr char kDefaultModelName[] = NPFKCT_DEFAULT_MODEL_NAME;

/// Whether this build loads a model file of this name: .npw weight files always, .pt models with
/// libtorch.
bool CanLoadModel(std::string_view file_name);

/// Sets how many threads libtorch and OpenBLAS use for the filter's tensor work in this process.
/// Planning uses 1 (the default the filter sets before its first use): inference then runs on
/// the planning thread alone, so a CPU-time budget counts all of it, and no BLAS worker threads
/// spin on a loaded machine.
void SetComputeThreads(int threads);

/// The network's prediction of the score of each query.
struct Prediction {
  std::vector<float> mu;
  std::vector<float> sigma;
};

/// A trained filter loaded from a file written by npfkct-train: one network, or an ensemble of
/// networks trained alike from different seeds; a .pt model runs on libtorch, a .npw weight file
/// (npfkct-train export) on Eigen, with the same predictions. Thread-safe.
class NeuralFilter {
 public:
  ~NeuralFilter();
  /// Loads a model (.pt, or a .npw weight file); a missing, truncated or foreign file is
  /// INVALID_ARGUMENT saying why.
  static StatusOr<std::shared_ptr<NeuralFilter>> Load(const std::string& path);
  /// Writes the networks of the model files `paths` (1 to 8 networks in all) as one ensemble
  /// model file at `out` (needs libtorch).
  static Status Combine(const std::vector<std::string>& paths, const std::string& out);
  /// Writes the weights of the .pt model `model` as a weight file `out` (.npw), which a build
  /// without libtorch loads: the same networks, run by Eigen (needs libtorch).
  static Status ExportWeights(const std::string& model, const std::string& out);
  /// Predicts the scores of `queries` (n x kQueryDim) in `scene`, conditioned on context queries
  /// (m >= 1 rows of kQueryDim) with their exact scores. The queries are scored in blocks of
  /// 4,096; when `stop` (if given) says the search must stop, the predictions of the first blocks
  /// only (fewer than n). An ensemble's prediction is the mixture of its networks' Gaussians:
  /// mu their mean, sigma^2 the mean of their sigma^2 plus the variance of their mu.
  Prediction Predict(const SceneFeatures& scene, const std::vector<float>& context_queries,
                     const std::vector<float>& context_scores, const std::vector<float>& queries,
                     const TerminationCondition* stop = nullptr) const;
  const std::string& path() const { return path_; }
  /// The number of networks (1 unless an ensemble).
  int members() const;

  struct Impl;

 private:
  NeuralFilter() = default;
  Prediction PredictDense(const SceneFeatures& scene, const std::vector<float>& context_queries,
                          const std::vector<float>& context_scores,
                          const std::vector<float>& queries,
                          const TerminationCondition* stop) const;
  std::unique_ptr<Impl> impl_;
  std::string path_;
};

/// Net_sam as NPF-kCT's candidate sampler for the object-search model: move candidates come from
/// the filter, discrete kinds (zero-dimensional) are passed through uniformly. `model` must outlive
/// it. Invalid options are INVALID_ARGUMENT naming the field.
StatusOr<std::shared_ptr<CandidateSampler<State>>> MakeNetSam(
    std::shared_ptr<const NeuralFilter> filter, const ObjectSearchModel& model,
    FilterOptions options = {});

}  // namespace npfkct::filter
