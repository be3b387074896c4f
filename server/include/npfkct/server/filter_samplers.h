// The server's default candidate samplers: the neural process filter for NPF-kCT sessions that
// name a model file (planner.modelPath), uniform candidates otherwise.
#pragma once

#include <string>

#include "npfkct/server/session.h"

namespace npfkct::server {

/// Whether a planner option (snake_case key) is one of Net_sam's ("filter.explore", ...), which
/// the factory consumes and the planner never sees.
bool IsFilterOption(const std::string& key);

/// A factory that loads planner.modelPath once per path (shared by every session using it) and
/// returns Net_sam over the session's model. A missing or unreadable file, or a model path on a
/// planner other than "npfkct", is INVALID_ARGUMENT naming planner.modelPath; "filter.*" planner
/// options (candidates, confidence, context, placements, minKeep, explore) set Net_sam's
/// FilterOptions, and bad ones are INVALID_ARGUMENT naming the option.
SamplerFactory FilterSamplerFactory();

}  // namespace npfkct::server
