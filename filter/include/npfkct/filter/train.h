// Training and evaluation of the neural process filter (ELBO, paper section 4.1).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/filter/dataset.h"
#include "npfkct/filter/filter.h"

namespace npfkct::filter {

/// Settings of TrainFilter.
struct TrainOptions {
  int epochs = 40;
  int batch = 16;  ///< Samples (scenes) per step.
  double learning_rate = 1e-3;
  double weight_decay = 1e-4;  ///< L2 penalty of Adam.
  /// The learning rate is multiplied by lr_decay after every lr_decay_every epochs.
  int lr_decay_every = 5;
  double lr_decay = 0.5;
  /// Training stops when the validation loss has not improved for this many epochs.
  int patience = 6;
  int min_context = 8;  ///< Context size drawn per step in [min_context, max_context].
  int max_context = 24;
  int eval_context = 16;  ///< Context size of the validation loss.
  uint64_t seed = 1;
  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// What one epoch did.
struct EpochReport {
  int epoch = 0;
  double train_loss = 0.0;
  double val_loss = 0.0;
  double seconds = 0.0;
};

/// What TrainFilter did.
struct TrainReport {
  std::vector<EpochReport> epochs;
  int best_epoch = 0;
  double best_val_loss = 0.0;
};

/// Trains a new network on `train`, validating on `val` after every epoch, and saves the weights
/// of the epoch with the lowest validation loss to `path`. `progress` (may be empty) is called
/// after every step with (epoch, step, steps per epoch, running loss) and after every epoch.
StatusOr<TrainReport> TrainFilter(
    const Dataset& train, const Dataset& val, const TrainOptions& options, const std::string& path,
    const std::function<void(int, int, int, double)>& step_progress = {},
    const std::function<void(const EpochReport&)>& epoch_done = {});

/// Test-set figures: the first `context` queries of each sample condition the network, the rest
/// are predicted.
struct FilterMetrics {
  int queries = 0;
  int efficient = 0;  ///< Queries with g > kEfficientScore.
  /// The paper's accuracy: efficient queries not misclassified as useless (mu >= kEfficientScore).
  double accuracy = 0.0;
  /// Half-width of the accuracy's 95% interval over the test samples (RatioHalfWidth95 of
  /// solver/stats.h over each sample's correct and efficient queries); the samples of one scene
  /// are not independent, so this is a lower bound on the uncertainty.
  double accuracy_ci95 = 0.0;
  /// The same accuracy among the queries with g > 2 kEfficientScore: how much of the error is
  /// near the threshold, where g (a share of sampled placements) has sampling noise of its own.
  double accuracy_clear = 0.0;
  /// Queries with g <= kEfficientScore predicted useless (mu < kEfficientScore).
  double specificity = 0.0;
  /// Efficient queries kept by Net_sam's rule mu > beta* sigma.
  double kept_efficient = 0.0;
  /// Queries with g == 0 dropped by that rule.
  double dropped_useless = 0.0;
  double mean_abs_error = 0.0;
  /// Fraction of queries with |g - mu| <= 2 sigma.
  double within_2_sigma = 0.0;
};

/// Evaluates `filter` on `test` with Net_sam's rule at `options`.
StatusOr<FilterMetrics> EvaluateFilter(const NeuralFilter& filter, const Dataset& test,
                                       const FilterOptions& options);

}  // namespace npfkct::filter
