// Actions, planner options, search statistics and history steps as JSON (private to the API
// layer): one form for the requests and replies, the steps resource and the session record.
#pragma once

#include "json_util.h"
#include "npfkct/api/types.h"

namespace npfkct::api::internal {

/// A Unix time in milliseconds as RFC 3339 (UTC, milliseconds).
std::string Rfc3339(int64_t unix_ms);

/// {"type", "configuration"} or {"type", "objectId", "objectBox"}.
json ActionJson(const ActionView& a);
/// Reads ActionJson's output; false when the shape is wrong.
bool ReadAction(const json& j, ActionView* a);

/// planner.options as the API spells them: lowerCamelCase keys, booleans as booleans (the
/// options' option_is_bool), whole numbers as integers.
json PlannerOptionsJson(const PlannerSpec& p);

/// A detection as the :observe request and the perception of its reply have it: {"id", "box",
/// "moveability", "faces": [{"corner", "score"}]}.
json DetectionJson(const object_search::ObjectDetection& d);

/// The :plan reply's "stats" (with "candidates" when candidates were drawn).
json StatsJson(const SearchStats& s, const CandidateStats& candidates);

/// A history step as the API shows it ("planTime", "outcome.time" as RFC 3339) or, with
/// `record`, as a snapshot keeps it (Unix milliseconds).
json StepJson(const StepRecord& s, bool record);
/// Reads a step of a record (StepJson(s, true)); false when the shape is wrong.
bool ReadStep(const json& j, StepRecord* s);

}  // namespace npfkct::api::internal
