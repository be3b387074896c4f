// Training data of the neural process filter and its file format. Generating it (paper
// algorithm 4, with the simulator) is the job of npfkct-train (tools/generate.h), so that the
// runtime filter does not link the simulator.
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

#include "npfkct/common/status.h"
#include "npfkct/filter/features.h"

namespace npfkct::filter {

/// One planning snapshot: the scene and M scored queries.
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

/// Writes `data` in the format above.
Status WriteDataset(const Dataset& data, const std::string& path);
/// Reads a file written by WriteDataset; truncated or foreign files are INVALID_ARGUMENT.
StatusOr<Dataset> ReadDataset(const std::string& path);

}  // namespace npfkct::filter
