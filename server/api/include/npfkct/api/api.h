// The API layer: the only code that touches JSON, Base64, image bytes and world specs. Request
// bodies become typed requests (types.h), validated against the JSON Schemas of schemas/ (with
// valijson) and then by the domain checks a schema cannot express, within the limits of
// limits.h; typed replies and records become bodies. Every error is a Status whose field
// violations name the offending fields as data. The clients' direction (typed requests to
// bodies, reply bodies to typed replies) is client_codec.h's.
//
//   api::Limits limits;
//   StatusOr<api::CreateSessionRequest> req = api::ParseCreateSession(body, limits);
//   if (!req.ok()) return Reply(api::HttpStatusOf(req.status().code()),
//                               api::RenderError(req.status()));
//   StatusOr<World> world = api::BuildWorld(req->world, limits);
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "npfkct/api/limits.h"
#include "npfkct/api/types.h"
#include "npfkct/object_search/planner_registry.h"

namespace npfkct::api {

// ---- requests ----

/// POST /v1/sessions; planner.name is one of `planners`' servable planners (the schema's list
/// of names is theirs).
StatusOr<CreateSessionRequest> ParseCreateSession(
    std::string_view body, const Limits& limits,
    const object_search::PlannerRegistry& planners = object_search::PlannerRegistry::BuiltIn());
/// POST :plan (an empty body asks for the default budget).
StatusOr<PlanRequest> ParsePlan(std::string_view body, const Limits& limits);
/// POST :observe.
StatusOr<ObserveRequest> ParseObserve(std::string_view body, const Limits& limits);
/// GET /v1/sessions?pageSize=&pageToken= (absent parameters: nullopt).
StatusOr<ListRequest> ParseList(const std::optional<std::string>& page_size,
                                const std::optional<std::string>& page_token);
/// GET .../belief?format=json|png.
StatusOr<BeliefFormat> ParseBeliefFormat(const std::optional<std::string>& format);
/// Whether `id` has the form of a session id (32 lower-case hex digits).
bool IsSessionId(std::string_view id);
/// Whether `name` may name a model file (planner.model): letters, digits, '.', '_' and '-', at
/// most 64 characters, not starting with '.'. It names an entry of the server's model folder;
/// it is never used as a path.
bool IsModelName(std::string_view name);

/// The World of a world spec: occupancy map, furniture, base regions, the grid world over the
/// workspaces (2 cm cells) and the robot at the start. Cells are counted in 64 bits against the
/// limits before anything is allocated; errors name the field under "world".
StatusOr<World> BuildWorld(const WorldSpec& spec, const Limits& limits);

/// A robot as a world spec or a scenario file gives it, from its JSON text: "fetch",
/// "stretch", a description ({name, footprintRadius, reach, joints}) or a URDF ({urdf,
/// baseLink, cameraLink, opticalFrame, liftJoint, panJoint, tiltJoint, ...}). Errors are
/// INVALID_ARGUMENT naming the field under `path`. At most 2 MiB of text.
StatusOr<object_search::RobotDescription> ParseRobot(std::string_view json_text,
                                                     const std::string& path);
/// The JSON text ParseRobot reads back: a shipped robot, unchanged, as its name; any other as
/// its description (a URDF's robot as the joints it became).
std::string RobotText(const object_search::RobotDescription& robot);

// ---- replies ----

/// The HTTP status of a canonical code (google.rpc.Code to HTTP mapping).
int HttpStatusOf(StatusCode code);
/// {"error": {"code", "status", "message", "details"}} with a google.rpc.BadRequest detail
/// holding the status's field violations, and a google.rpc.RetryInfo when `retry_after_seconds`
/// is positive. `http_status` overrides the code's HTTP status (405, 411, 413, 415, 416, ...).
std::string RenderError(const Status& status, int http_status = 0, int retry_after_seconds = 0);
/// The session resource.
std::string RenderSession(const SessionView& session);
/// {"sessions": [...], "nextPageToken"}.
std::string RenderSessionList(const std::vector<SessionView>& sessions,
                              const std::string& next_page_token);
std::string RenderPlan(const PlanReply& reply);
/// GET /v1/planners: {"planners": [{"name", "summary", "takesModel", "defaults"}]}.
std::string RenderPlanners(const std::vector<PlannerView>& planners);
std::string RenderObserve(const ObserveReply& reply);
/// Grid-world log-odds per workspace, objects with face odds, the robot and its camera frustum,
/// the furniture and the picture's crop; with `session`, the planned next view (a pending MOVE).
std::string RenderBelief(const World& world, const SessionView* session = nullptr);
/// The belief picture of npfkct/render as PNG bytes (title: session and step; colour bar, scale,
/// labelled objects with face odds, robot, frustum, next view; cropped to the workspaces), at
/// most `max_pixels` pixels.
StatusOr<std::string> RenderBeliefPng(const World& world, const SessionView* session = nullptr,
                                      int64_t max_pixels = 4'000'000);
/// GET /v1/sessions/{id}/steps: {"steps": [...]}, oldest first. With the session's `world`,
/// each observed step's outcome also gives the floor its camera covered ("view").
std::string RenderSteps(const std::vector<StepRecord>& steps, const World* world = nullptr);
/// {"status": "SERVING", "version"}.
std::string RenderHealth();
/// {"status": "SERVING" | "NOT_SERVING" (the store is unavailable), "store": {"backend",
/// "status": "OK" | "UNAVAILABLE", "message"}, "sessionsHeld", "version"}.
std::string RenderHealth(const HealthView& health);
/// {}.
std::string RenderEmpty();

// ---- records ----

/// A session record as snapshot bytes (JSON). With a non-empty `photos_digest`, the target's
/// photos are left out and the digest written in their place: the store keeps them apart (they
/// never change after creation, and a record is saved at every step).
std::string EncodeRecord(const SessionRecord& record, std::string_view photos_digest = {});
/// Reads snapshot bytes; malformed, truncated or out-of-limit records are DATA_LOSS, never a
/// crash or an allocation beyond the limits. A record whose photos are kept apart has none; its
/// digest goes to `photos_digest` (DATA_LOSS when the caller gives none to take it).
StatusOr<SessionRecord> DecodeRecord(std::string_view bytes, const Limits& limits,
                                     std::string* photos_digest = nullptr);
/// A target's photos as the bytes a store keeps apart from the record.
std::string EncodePhotos(const std::vector<std::string>& photos);
/// Reads EncodePhotos' bytes, with DecodeRecord's checks of each photo: DATA_LOSS when malformed
/// or out of limits.
StatusOr<std::vector<std::string>> DecodePhotos(std::string_view bytes, const Limits& limits);
/// Longest summary DecodeSessionSummary reads.
inline constexpr size_t kMaxSummaryBytes = 64 * 1024;
/// A session's API resource as the few hundred bytes a shared store keeps beside its record, so
/// that a list of sessions reads no records.
std::string EncodeSessionSummary(const SessionView& session);
/// Reads EncodeSessionSummary's bytes; malformed or out-of-limit ones are DATA_LOSS.
StatusOr<SessionView> DecodeSessionSummary(std::string_view bytes, const Limits& limits);

/// lowerCamelCase to snake_case per dot-separated segment ("search.maxDepth" ->
/// "search.max_depth"): planner option keys as sent to the keys the planners take.
std::string SnakeCase(const std::string& camel);
/// snake_case to lowerCamelCase per dot-separated segment ("search.max_depth" ->
/// "search.maxDepth"): SnakeCase's inverse for lowerCamelCase keys.
std::string CamelCase(const std::string& snake);

/// A status from below the API layer (a session's, a planner's) with its field paths in the
/// API's spelling: each field violation's path (and the message's "<field>: " prefix) from the
/// domain's snake_case ("robot_state", "planner.options.search.max_depth") to lowerCamelCase.
Status ToWire(const Status& domain);

}  // namespace npfkct::api
