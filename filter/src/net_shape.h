// The filter network's sizes, shared by its libtorch form (network.h) and its inference form
// without libtorch (dense_net.h). Internal to npfkct_filter.
#pragma once

#include "npfkct/filter/features.h"

namespace npfkct::filter {

inline constexpr int kHidden = 64;
inline constexpr int kLatent = 32;
inline constexpr int kHeads = 4;
inline constexpr int kFormatVersion = 1;
/// The floor of the predicted standard deviation.
inline constexpr double kMinSigma = 0.02;

}  // namespace npfkct::filter
