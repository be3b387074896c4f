// Typed replies to response bodies.
#include <cmath>
#include <ctime>

#include "json_util.h"
#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/common/version.h"
#include "npfkct/render/belief_picture.h"
#include "step_codec.h"
#include "world_codec.h"

namespace npfkct::api {
namespace {

using internal::json;

std::string Rfc3339(std::chrono::system_clock::time_point t) {
  return internal::Rfc3339(
      std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count());
}

const char* StateName(SessionState s) {
  switch (s) {
    case SessionState::kReady:
      return "READY";
    case SessionState::kActionPending:
      return "ACTION_PENDING";
    case SessionState::kDone:
      return "DONE";
  }
  return "READY";
}

using internal::ActionJson;

// Option values keyed in the API's spelling (lowerCamelCase): whole numbers as integers, an
// automatic value (NaN) as null.
json OptionValuesJson(const std::vector<std::pair<std::string, double>>& values) {
  json out = json::object();
  for (const auto& [key, value] : values) {
    const std::string k = CamelCase(key);
    if (std::isnan(value)) {
      out[k] = nullptr;
    } else if (value == std::trunc(value) && std::abs(value) < 9007199254740992.0) {
      out[k] = static_cast<int64_t>(value);
    } else {
      out[k] = value;
    }
  }
  return out;
}

json SessionJson(const SessionView& s) {
  json j;
  j["name"] = "sessions/" + s.id;
  j["id"] = s.id;
  if (!s.display_name.empty()) j["displayName"] = s.display_name;
  j["state"] = StateName(s.state);
  j["createTime"] = Rfc3339(s.create_time);
  j["updateTime"] = Rfc3339(s.update_time);
  j["ttlSeconds"] = s.ttl_seconds;
  j["planner"] = {{"name", s.planner.name},
                  {"particles", s.planner.particles},
                  {"options", internal::PlannerOptionsJson(s.planner)}};
  // The model that plans: a planner that takes one always says (""), so that uniform candidates
  // are never silent.
  if (!s.planner.model.empty() || s.planner.takes_model) j["planner"]["model"] = s.planner.model;
  j["seed"] = std::to_string(s.seed);
  j["target"] = {{"description", s.target_description}, {"photoCount", s.photo_count}};
  if (s.perception_tracks) j["perceptionTracks"] = *s.perception_tracks;
  j["step"] = s.step;
  j["robot"] = internal::ConfigJson(s.robot);
  j["objectCount"] = s.object_count;
  if (s.pending) {
    j["pendingAction"] = {{"actionId", s.pending->first},
                          {"action", ActionJson(s.pending->second)}};
  }
  j["totalSimulations"] = s.total_simulations;
  j["planningSecondsUsed"] = s.planning_seconds_used;
  return j;
}

json BudgetJson(const Budget& b) {
  return {{"timeMs", b.time_ms}, {"cpuMs", b.cpu_ms}, {"simulations", b.max_simulations}};
}

}  // namespace

int HttpStatusOf(StatusCode code) {
  switch (code) {
    case StatusCode::kOk:
      return 200;
    case StatusCode::kCancelled:
      return 499;
    case StatusCode::kInvalidArgument:
    case StatusCode::kFailedPrecondition:
    case StatusCode::kOutOfRange:
      return 400;
    case StatusCode::kDeadlineExceeded:
      return 504;
    case StatusCode::kNotFound:
      return 404;
    case StatusCode::kAlreadyExists:
    case StatusCode::kAborted:
      return 409;
    case StatusCode::kPermissionDenied:
      return 403;
    case StatusCode::kUnauthenticated:
      return 401;
    case StatusCode::kResourceExhausted:
      return 429;
    case StatusCode::kUnimplemented:
      return 501;
    case StatusCode::kUnavailable:
      return 503;
    case StatusCode::kUnknown:
    case StatusCode::kInternal:
    case StatusCode::kDataLoss:
      return 500;
  }
  return 500;
}

std::string RenderError(const Status& status, int http_status, int retry_after_seconds) {
  json body;
  body["error"]["code"] = http_status > 0 ? http_status : HttpStatusOf(status.code());
  body["error"]["status"] = std::string(StatusCodeName(status.code()));
  body["error"]["message"] = status.message();
  body["error"]["details"] = json::array();
  if (!status.field_violations().empty()) {
    json violations = json::array();
    for (const FieldViolation& v : status.field_violations()) {
      violations.push_back({{"field", v.field}, {"description", v.description}});
    }
    body["error"]["details"].push_back(
        {{"@type", "type.googleapis.com/google.rpc.BadRequest"}, {"fieldViolations", violations}});
  }
  if (retry_after_seconds > 0) {
    body["error"]["details"].push_back({{"@type", "type.googleapis.com/google.rpc.RetryInfo"},
                                        {"retryDelay", std::to_string(retry_after_seconds) + "s"}});
  }
  return internal::Dump(body);
}

std::string RenderSession(const SessionView& session) {
  return internal::Dump(SessionJson(session));
}

std::string RenderSessionList(const std::vector<SessionView>& sessions,
                              const std::string& next_page_token) {
  json out;
  out["sessions"] = json::array();
  for (const SessionView& s : sessions) out["sessions"].push_back(SessionJson(s));
  if (!next_page_token.empty()) out["nextPageToken"] = next_page_token;
  return internal::Dump(out);
}

std::string RenderPlan(const PlanReply& r) {
  json out;
  out["actionId"] = r.action_id;
  out["action"] = ActionJson(r.action);
  out["expectedValue"] = r.expected_value;
  out["stats"] = internal::StatsJson(r.stats, r.candidates);
  out["budget"] = BudgetJson(r.budget);
  out["summary"] = {{"budgetGiven", BudgetJson(r.summary.budget_given)},
                    {"optionsGiven", OptionValuesJson(r.summary.options_given)},
                    {"optionsUsed", OptionValuesJson(r.summary.options_used)},
                    {"resolved", OptionValuesJson(r.summary.resolved)}};
  out["session"] = SessionJson(r.session);
  return internal::Dump(out);
}

std::string RenderPlanners(const std::vector<PlannerView>& planners) {
  json out;
  out["planners"] = json::array();
  for (const PlannerView& p : planners) {
    out["planners"].push_back({{"name", p.name},
                               {"summary", p.summary},
                               {"takesModel", p.takes_model},
                               {"defaults", OptionValuesJson(p.defaults)}});
  }
  return internal::Dump(out);
}

Status ToWire(const Status& domain) {
  if (domain.field_violations().empty()) return domain;
  const std::string& first = domain.field_violations().front().field;
  std::string message = domain.message();
  if (message.rfind(first + ": ", 0) == 0) {
    message = CamelCase(first) + message.substr(first.size());
  }
  Status out(domain.code(), std::move(message));
  for (const FieldViolation& v : domain.field_violations()) {
    out.WithFieldViolation(CamelCase(v.field), v.description);
  }
  return out;
}

std::string RenderObserve(const ObserveReply& r) {
  json out;
  out["done"] = r.done;
  out["reward"] = r.reward;
  if (r.perception) {
    const perception::PerceptionResult& p = *r.perception;
    json objects = json::array();
    for (const auto& d : p.observation.objects) objects.push_back(internal::DetectionJson(d));
    const bool registered = std::isfinite(p.fitness);
    out["perception"] = {
        {"robotState", internal::ConfigJson(p.observation.achieved)},
        {"registration", registered ? (p.used_ransac ? "RANSAC_ICP" : "ICP") : "SKIPPED"},
        {"fitness", registered ? json(p.fitness) : json(nullptr)},
        {"clusters", p.clusters},
        {"detections", objects},
        {"timingsMs",
         {{"registration", p.timings.registration},
          {"segmentation", p.timings.segmentation},
          {"association", p.timings.association},
          {"detection", p.timings.detection},
          {"total", p.timings.total}}}};
    if (!p.box_objects.empty()) {  // the request's imageBoxes, each with its object or null
      json given = json::array();
      for (const std::string& id : p.box_objects) given.push_back(id.empty() ? json() : json(id));
      out["perception"]["boxObjects"] = given;
    }
  }
  out["session"] = SessionJson(r.session);
  return internal::Dump(out);
}

std::string RenderBelief(const World& world, const SessionView* session) {
  return internal::Dump(internal::BeliefJson(world, session));
}

StatusOr<std::string> RenderBeliefPng(const World& world, const SessionView* session,
                                      int64_t max_pixels) {
  render::BeliefPictureOptions options;
  options.max_pixels = max_pixels;
  options.title = "step " + std::to_string(world.steps);
  if (session) {
    options.title = "session " + session->id.substr(0, 12) + " - step " +
                    std::to_string(world.steps) + " - " + StateName(session->state);
    options.subtitle = session->planner.name;
    if (!session->planner.model.empty()) {
      options.subtitle += " (model " + session->planner.model + ")";
    }
    if (!session->target_description.empty()) {
      options.subtitle += " - target: " + session->target_description.substr(0, 80);
    }
    options.done = session->state == SessionState::kDone;
    if (session->pending) {
      const ActionView& a = session->pending->second;
      if (a.type == ActionView::Type::kMove) {
        options.next_view = a.configuration;
      } else {
        static const char* kTypes[] = {"MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE"};
        options.next_action = std::string(kTypes[static_cast<int>(a.type)]) + " " + a.object_id;
      }
    }
  }
  return EncodePng(render::RenderBelief(world, options));
}

std::string RenderSteps(const std::vector<StepRecord>& steps, const World* world) {
  json out;
  out["steps"] = json::array();
  for (const StepRecord& s : steps) {
    json step = internal::StepJson(s, false);
    // The floor the camera covered from where the robot stood after the step.
    if (world != nullptr && s.outcome && s.outcome->robot) {
      step["outcome"]["view"] = internal::FrustumJson(*world, *s.outcome->robot);
    }
    out["steps"].push_back(std::move(step));
  }
  return internal::Dump(out);
}

std::string RenderHealth() {
  return internal::Dump(json{{"status", "SERVING"}, {"version", kVersion}});
}

std::string RenderHealth(const HealthView& h) {
  json store = {{"backend", h.store_backend}, {"status", h.store_ok ? "OK" : "UNAVAILABLE"}};
  if (!h.store_ok) store["message"] = h.store_message;
  json j = {{"status", h.store_ok ? "SERVING" : "NOT_SERVING"},
            {"store", store},
            {"sessionsHeld", h.sessions_held},
            {"version", kVersion}};
  return internal::Dump(j);
}
std::string RenderEmpty() { return "{}"; }

}  // namespace npfkct::api
