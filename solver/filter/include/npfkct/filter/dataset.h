// Training data of the neural process filter (paper algorithm 4) and its file format.
//
// File format (little-endian):
//   8 bytes   magic "NPFKDS01"
//   8 int32   version (1), kPoints, kPointDim, kImageSize, kImageChannels, kQueryDim,
//             queries per sample M, number of samples N
//   N samples, each:
//     float32[kPoints * kPointDim]                    object cloud
//     uint8[kImageChannels * kImageSize * kImageSize] image, value * 255 rounded
//     float32[M * kQueryDim]                          queries
//     float32[M]                                      scores g in [0, 1]
#pragma once

#include <string>
#include <vector>

#include "npfkct/filter/features.h"
#include "npfkct/solver/status.h"

namespace npfkct::filter {

/// One planning snapshot: the scene and M scored queries (half aimed at a placement, half uniform).
struct Sample {
  SceneFeatures scene;
  std::vector<float> queries;  ///< M x kQueryDim.
  std::vector<float> scores;   ///< M.
  int num_queries() const { return static_cast<int>(scores.size()); }
};

/// A set of samples with the same number of queries each.
struct Dataset {
  int queries_per_sample = 0;
  std::vector<Sample> samples;
};

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

/// Writes `data` in the format above.
Status WriteDataset(const Dataset& data, const std::string& path);
/// Reads a file written by WriteDataset; truncated or foreign files are INVALID_ARGUMENT.
StatusOr<Dataset> ReadDataset(const std::string& path);

}  // namespace npfkct::filter
