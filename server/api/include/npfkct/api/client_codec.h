// The client's direction of the API: typed requests to request bodies, and response bodies to
// typed replies. The encoders write what the server's parsers (api.h) read back to the same
// request; the decoders read what the server's renderers write, parsed within the limits of
// limits.h (nesting, values) and checked against the response schemas of schemas/ before a field
// is read. A reply that is not what the API describes is DATA_LOSS naming the field (as a field
// violation and in the message), never a throw, an abort or an allocation beyond the limits.
//
//   api::CreateSessionRequest create;
//   create.world = scenario.Prior();
//   const std::string body = api::EncodeCreateSession(create);
//   ... POST /v1/sessions ...
//   StatusOr<api::SessionView> session =
//       status == 200 ? api::ParseSessionReply(reply) : api::ParseErrorReply(status, reply);
#pragma once

#include <string>
#include <string_view>

#include "npfkct/api/limits.h"
#include "npfkct/api/types.h"

namespace npfkct::api {

// ---- requests ----

/// POST /v1/sessions: displayName (when not empty), the world (EncodeWorldSpec), the target
/// (its description and its photos as Base64, when given), the planner (name; particles when not
/// the default 300; options keyed in lowerCamelCase, booleans as booleans; model when
/// model_given), seed and ttlSeconds when given.
std::string EncodeCreateSession(const CreateSessionRequest& request);
/// POST :plan: {"budget": {...}} with the fields asked for ({} when none).
std::string EncodePlan(const PlanRequest& request);
/// POST :observe: actionId (left out when empty: npfkct-sim-robot's observations, whose caller
/// adds it), succeeded, robotState when given, and either the raw frame (pointCloud as Base64
/// float32 xyzrgb in its frame, the image as a PNG when there is one, the camera's intrinsics,
/// semanticScores when given) or the detections. INVALID_ARGUMENT on "image" when the image
/// cannot be encoded as a PNG.
StatusOr<std::string> EncodeObserve(const ObserveRequest& request);
/// A world spec as the create request's "world" has it: every field, discrete poses as x, y and
/// yaw, and the params that differ from object_search::SearchParams' defaults (those the schema
/// names; the others are the server's own).
std::string EncodeWorldSpec(const WorldSpec& world);
/// Reads a world spec as the create request's "world" has it, with the server's checks (errors
/// are INVALID_ARGUMENT naming the field). A scenario file is read as its world part: its name,
/// description, noise and objects are left out.
StatusOr<WorldSpec> ParseWorldSpec(std::string_view text, const Limits& limits = Limits());

// ---- replies ----

/// The session resource (POST /v1/sessions, GET /v1/sessions/{id}). planner.takes_model is the
/// built-in registry's; planner.model_given says whether the reply named a model.
StatusOr<SessionView> ParseSessionReply(std::string_view body, const Limits& limits = Limits());
/// The :plan reply, its summary included (option keys in the domain's snake_case).
StatusOr<PlanReply> ParsePlanReply(std::string_view body, const Limits& limits = Limits());
/// The :observe reply: done, reward, the session, and what perception made of raw data when the
/// reply has it (a registration SKIPPED has a NaN fitness).
StatusOr<ObserveReply> ParseObserveReply(std::string_view body, const Limits& limits = Limits());
/// GET /healthz (HTTP 200 while serving, 503 while the session store is unavailable).
StatusOr<HealthView> ParseHealthReply(std::string_view body, const Limits& limits = Limits());
/// An error reply as the Status it carries: the canonical code of its "status", its message and
/// its field violations. A body that is not the API's error is DATA_LOSS whose message names
/// the HTTP status and the field.
Status ParseErrorReply(int http_status, std::string_view body, const Limits& limits = Limits());
/// An action object as the :plan reply has it ({"type": "MOVE", "configuration": {...}} or
/// {"type": "DECLARE_TARGET" | "DECLARE_OBSTACLE" | "REMOVE", "objectId", "objectBox"}).
StatusOr<ActionView> ParseAction(std::string_view body, const Limits& limits = Limits());

/// "MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE" or "REMOVE".
const char* ActionTypeName(ActionView::Type type);

}  // namespace npfkct::api
