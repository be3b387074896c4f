// Training data of the neural process filter by the paper's algorithm 4, with the built-in
// simulator playing Gazebo's role: npfkct-train's part that needs the simulator (the runtime filter
// library does not link it).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/filter/dataset.h"

namespace npfkct::filter {

/// Options of GenerateDataset. Scenes come from scenario files or from npfkct-scenegen seeds.
struct GenerateOptions {
  std::vector<std::string> scenarios;  ///< Scenario files to draw scenes from, or
  uint64_t scene_seed = 0;             ///< the first npfkct-scenegen seed (0: use the files),
  int scene_count = 0;                 ///< and how many consecutive seeds.
  int samples = 1000;
  int queries_per_sample = 64;
  int placements = 64;          ///< Target placements per score of the guessed target.
  int max_steps = 8;            ///< Real steps before a snapshot: 0..max_steps.
  double oracle_share = 0.5;    ///< Share of those steps the oracle chooses (the rest: random).
  double object_jitter = 0.08;  ///< Std of object placement per scene from files (m).
  double drop_object = 0.15;    ///< Probability that a non-target object of a file is left out.
  uint64_t seed = 1;
  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// Generates samples: a scene (a scenario file with its objects jittered and some left out, or a
/// generated scene), then a random number of real steps, each chosen by the oracle (so that
/// targets get detected and covers removed) or a random proposal, executed by the simulator and
/// followed by its observation and the real-step update; after each step a snapshot with M
/// configurations scored by TargetScore for the current target candidate. `progress` (may be
/// null) is called after each sample.
StatusOr<Dataset> GenerateDataset(const GenerateOptions& options,
                                  void (*progress)(int done, int total) = nullptr);

}  // namespace npfkct::filter
