// Candidate continuous actions for NPF-kCT's action lists: where Net_sam plugs in.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/common/status.h"
#include "npfkct/solver/belief.h"
#include "npfkct/solver/planner.h"
#include "npfkct/solver/spaces.h"

namespace npfkct {

/// What a candidate sampler reports about one call.
struct CandidateStats {
  int sampled = 0;   ///< Configurations drawn.
  int accepted = 0;  ///< Configurations returned (e.g. those kept by the neural filter).
  double elapsed_ms = 0.0;
};

/// Supplies candidate points of a continuous action kind for the current belief. NPF-kCT clusters
/// them into hyperspheres (paper algorithm 1, lines 4-6). The neural process filter implements this
/// interface in npfkct_filter; the solver core only sees it through this header.
template <class State>
class CandidateSampler {
 public:
  virtual ~CandidateSampler() = default;
  /// Appends up to `count` candidate points of `box` (the box of action `kind`) to `out`. Once
  /// `stop` says the search must stop (its budget, a cancellation, a resource limit), returns
  /// early with the points found so far, possibly none.
  virtual Status Sample(const ParticleBelief<State>& belief, int kind, const BoxSpace& box,
                        int count, const TerminationCondition& stop, Rng& rng,
                        std::vector<ActionVec>* out, CandidateStats* stats) = 0;
  /// Its settings as (key, value), for reports of what a planner ran with; none by default.
  virtual std::vector<std::pair<std::string, double>> Settings() const { return {}; }
};

/// Candidates drawn uniformly from the box: NPF-kCT without the neural filter.
template <class State>
class UniformCandidateSampler final : public CandidateSampler<State> {
 public:
  Status Sample(const ParticleBelief<State>& /*belief*/, int /*kind*/, const BoxSpace& box,
                int count, const TerminationCondition& /*stop*/, Rng& rng,
                std::vector<ActionVec>* out, CandidateStats* stats) override {
    for (int i = 0; i < count; ++i) out->push_back(box.SampleUniform(rng));
    if (stats != nullptr) {
      stats->sampled += count;
      stats->accepted += count;
    }
    return OkStatus();
  }
};

}  // namespace npfkct
