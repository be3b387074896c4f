// Generation of the neural process filter's training data (paper algorithm 4) with the built-in
// simulator. A tool (library npfkct_filter_tools, used by npfkct-train and the filter's tests):
// the run-time filter library does not link the simulator.
#pragma once

#include <string>
#include <vector>

#include "npfkct/filter/dataset.h"
#include "npfkct/solver/status.h"

namespace npfkct::filter {

/// Options of GenerateDataset.
struct GenerateOptions {
  std::vector<std::string> scenarios;  ///< Scenario files to draw scenes from.
  int samples = 1000;
  int queries_per_sample = 64;
  int placements = 64;          ///< Target placements per score.
  int max_steps = 6;            ///< Random real steps before a snapshot: 0..max_steps.
  double object_jitter = 0.08;  ///< Std of object placement per scene (m).
  double drop_object = 0.15;    ///< Probability that a non-target object is left out of a scene.
  uint64_t seed = 1;
  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// Generates samples by the paper's algorithm 4 with the built-in simulator: a random scene
/// (scenario, jitter, dropped objects), a random number of random moves each followed by the
/// simulator's observation and the real-step update, then M configurations scored by
/// VisibilityScore. `progress` (may be null) is called after each sample.
StatusOr<Dataset> GenerateDataset(const GenerateOptions& options,
                                  void (*progress)(int done, int total) = nullptr);

}  // namespace npfkct::filter
