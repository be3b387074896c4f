// The client's direction of the API: typed requests to bodies, reply bodies to typed replies.
#include "npfkct/api/client_codec.h"

#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include "json_util.h"
#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/object_search/planner_registry.h"
#include "schema.h"
#include "step_codec.h"
#include "world_codec.h"

namespace npfkct::api {
namespace {

using internal::At;
using internal::Join;
using internal::json;

// ---- replies: errors ----

// `why` (a parse or schema error naming its field) as the DATA_LOSS of a reply that is not what
// the API describes; `what` names the reply ("the session reply").
Status NotAsDescribed(const std::string& what, const Status& why) {
  Status out(StatusCode::kDataLoss, what + " is not what the API describes: " + why.message());
  for (const FieldViolation& v : why.field_violations()) {
    out.WithFieldViolation(v.field, v.description);
  }
  return out;
}

// The reply `body` parsed within the limits and checked against schemas/`message`.schema.json.
StatusOr<json> ParseReply(std::string_view body, std::string_view message, const std::string& what,
                          const Limits& limits) {
  auto j = internal::ParseBody(body, limits.max_json_depth, limits.max_json_values, false);
  if (!j.ok()) return NotAsDescribed(what, j.status());
  internal::IntegralNumbersAsIntegers(*j);
  if (Status s = internal::ValidateAgainstSchema(message, *j); !s.ok()) {
    return NotAsDescribed(what, s);
  }
  return j;
}

// Reads the members of a schema-checked reply: what the schema cannot say (an integer beyond
// its C++ type, a time that is no RFC 3339 time, a seed beyond 64 bits) is the first error,
// DATA_LOSS naming the field.
class Reader {
 public:
  explicit Reader(std::string what) : what_(std::move(what)) {}

  // j[key], a number (the schema's), or `fallback` when absent.
  double Number(const json& j, const char* key, double fallback = 0.0) {
    return internal::Number(j, key, fallback);
  }
  std::string String(const json& j, const char* key, const std::string& fallback = "") {
    return internal::String(j, key, fallback);
  }
  bool Bool(const json& j, const char* key, bool fallback = false) {
    return internal::Bool(j, key, fallback);
  }
  // j[key], an integer (the schema's) that must fit T; `fallback` when absent.
  template <class T>
  T Int(const json& j, const char* key, const std::string& path, T fallback = 0) {
    if (!j.is_object() || !j.contains(key)) return fallback;
    const json& v = j.at(key);
    if (v.is_number_unsigned()) {
      const uint64_t u = v.get<uint64_t>();
      if (std::in_range<T>(u)) return static_cast<T>(u);
    } else if (v.is_number_integer()) {
      const int64_t i = v.get<int64_t>();
      if (std::in_range<T>(i)) return static_cast<T>(i);
    }
    Fail(Join(path, key), "expected an integer in [" +
                              std::to_string(std::numeric_limits<T>::min()) + ", " +
                              std::to_string(std::numeric_limits<T>::max()) + "]");
    return fallback;
  }
  // A Unix time from an RFC 3339 date-time string.
  std::chrono::system_clock::time_point Time(const json& j, const char* key,
                                             const std::string& path) {
    int64_t ms = 0;
    if (!ParseRfc3339(String(j, key), &ms)) Fail(Join(path, key), "expected an RFC 3339 time");
    return FromUnixMillis(ms);
  }
  // {"x", "y", "yaw", "lift", "pan", "tilt"} (the schema's FullRobotConfig).
  RobotConfig Config(const json& j, const char* key) {
    return j.contains(key) ? internal::ReadConfig(j.at(key)) : RobotConfig{};
  }
  ActionView Action(const json& j, const char* key, const std::string& path) {
    ActionView a;
    if (!j.contains(key) || !internal::ReadAction(j.at(key), &a)) {
      Fail(Join(path, key), "expected an action");
    }
    return a;
  }
  object_search::Box Box(const json& j, const char* key, const std::string& path) {
    object_search::Box b;
    if (!j.contains(key) || !internal::ReadBox(j.at(key), &b)) Fail(Join(path, key), "bad box");
    return b;
  }

  void Fail(const std::string& field, const std::string& why) {
    if (status_.ok()) status_ = NotAsDescribed(what_, InvalidFieldError(field, why));
  }
  const Status& status() const { return status_; }

 private:
  // "YYYY-MM-DDTHH:MM:SS[.fraction](Z|+HH:MM|-HH:MM)" to Unix milliseconds (fractions beyond
  // milliseconds cut).
  static bool ParseRfc3339(const std::string& s, int64_t* unix_ms) {
    size_t i = 0;
    auto digits = [&](size_t n, int* out) {
      if (i + n > s.size()) return false;
      int v = 0;
      for (size_t k = 0; k < n; ++k) {
        const char c = s[i + k];
        if (c < '0' || c > '9') return false;
        v = v * 10 + (c - '0');
      }
      i += n;
      *out = v;
      return true;
    };
    auto expect = [&](std::string_view chars) {
      if (i >= s.size() || chars.find(s[i]) == std::string_view::npos) return false;
      ++i;
      return true;
    };
    int year, month, day, hour, minute, second;
    if (!digits(4, &year) || !expect("-") || !digits(2, &month) || !expect("-") ||
        !digits(2, &day) || !expect("Tt ") || !digits(2, &hour) || !expect(":") ||
        !digits(2, &minute) || !expect(":") || !digits(2, &second)) {
      return false;
    }
    int64_t ms = 0;
    if (i < s.size() && s[i] == '.') {
      ++i;
      int n = 0;
      for (; i < s.size() && s[i] >= '0' && s[i] <= '9'; ++i, ++n) {
        if (n < 3) ms = ms * 10 + (s[i] - '0');
      }
      if (n == 0) return false;
      for (; n < 3; ++n) ms *= 10;
    }
    int64_t offset_minutes = 0;
    if (i < s.size() && (s[i] == 'Z' || s[i] == 'z')) {
      ++i;
    } else if (i < s.size() && (s[i] == '+' || s[i] == '-')) {
      const int sign = s[i] == '-' ? -1 : 1;
      ++i;
      int oh, om;
      if (!digits(2, &oh) || !expect(":") || !digits(2, &om) || oh > 23 || om > 59) return false;
      offset_minutes = sign * (oh * 60 + om);
    } else {
      return false;
    }
    if (i != s.size()) return false;
    static constexpr int kDays[] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
    const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    if (month < 1 || month > 12 || day < 1 || day > kDays[month - 1] ||
        (month == 2 && day == 29 && !leap) || hour > 23 || minute > 59 || second > 60) {
      return false;
    }
    // Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
    const int64_t y = year - (month <= 2);
    const int64_t era = (y >= 0 ? y : y - 399) / 400;
    const int64_t yoe = y - era * 400;
    const int64_t doy = (153 * (month + (month > 2 ? -3 : 9)) + 2) / 5 + day - 1;
    const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    const int64_t days = era * 146097 + doe - 719468;
    const int64_t seconds = ((days * 24 + hour) * 60 + minute - offset_minutes) * 60 + second;
    *unix_ms = seconds * 1000 + ms;
    return true;
  }

  std::string what_;
  Status status_;
};

// ---- replies: the parts ----

SessionState StateOf(const std::string& name) {
  return name == "DONE"             ? SessionState::kDone
         : name == "ACTION_PENDING" ? SessionState::kActionPending
                                    : SessionState::kReady;
}

// Option values by lowerCamelCase key (number, or null: NaN) in the domain's snake_case.
std::vector<std::pair<std::string, double>> OptionValues(const json& j) {
  std::vector<std::pair<std::string, double>> out;
  if (!j.is_object()) return out;
  for (auto it = j.begin(); it != j.end(); ++it) {
    out.emplace_back(SnakeCase(it.key()), it->is_number()
                                              ? it->get<double>()
                                              : std::numeric_limits<double>::quiet_NaN());
  }
  return out;
}

Budget ReadBudget(Reader& r, const json& j, const std::string& path) {
  Budget b;
  b.time_ms = r.Number(j, "timeMs");
  b.cpu_ms = r.Number(j, "cpuMs");
  b.max_simulations = r.Int<int64_t>(j, "simulations", path);
  return b;
}

PlannerSpec ReadPlanner(Reader& r, const json& p, const std::string& path) {
  PlannerSpec spec;
  spec.name = r.String(p, "name", spec.name);
  spec.particles = r.Int<int>(p, "particles", path, spec.particles);
  if (p.contains("model")) {
    spec.model = r.String(p, "model");
    spec.model_given = true;
  }
  const object_search::PlannerEntry* entry =
      object_search::PlannerRegistry::BuiltIn().Find(spec.name);
  spec.takes_model = entry != nullptr && entry->takes_sampler;
  if (p.contains("options")) {
    const json& o = p.at("options");
    for (auto it = o.begin(); it != o.end(); ++it) {
      const bool is_bool = it->is_boolean();
      spec.options.emplace_back(SnakeCase(it.key()),
                                is_bool ? (it->get<bool>() ? 1.0 : 0.0) : it->get<double>());
      spec.option_is_bool.push_back(is_bool);
    }
  }
  return spec;
}

SessionView ReadSession(Reader& r, const json& j, const std::string& path) {
  SessionView v;
  v.id = r.String(j, "id");
  if (r.String(j, "name") != "sessions/" + v.id) r.Fail(Join(path, "name"), "not sessions/{id}");
  v.display_name = r.String(j, "displayName");
  v.state = StateOf(r.String(j, "state"));
  v.create_time = r.Time(j, "createTime", path);
  v.update_time = r.Time(j, "updateTime", path);
  v.ttl_seconds = r.Number(j, "ttlSeconds");
  v.planner = ReadPlanner(r, j.at("planner"), Join(path, "planner"));
  // The seed as decimal digits (the schema's pattern), at most 2^64 - 1.
  const std::string seed = r.String(j, "seed");
  for (char c : seed) {
    const uint64_t digit = static_cast<uint64_t>(c - '0');
    if (v.seed > (std::numeric_limits<uint64_t>::max() - digit) / 10) {
      r.Fail(Join(path, "seed"), "beyond 2^64 - 1");
      break;
    }
    v.seed = v.seed * 10 + digit;
  }
  const json& target = j.at("target");
  v.target_description = r.String(target, "description");
  v.photo_count = r.Int<int>(target, "photoCount", Join(path, "target"));
  if (j.contains("perceptionTracks")) v.perception_tracks = r.Int<int>(j, "perceptionTracks", path);
  v.step = r.Int<int>(j, "step", path);
  v.robot = r.Config(j, "robot");
  v.object_count = r.Int<int>(j, "objectCount", path);
  if (j.contains("pendingAction")) {
    const json& pending = j.at("pendingAction");
    const std::string at = Join(path, "pendingAction");
    v.pending = std::make_pair(r.String(pending, "actionId"), r.Action(pending, "action", at));
  }
  v.total_simulations = r.Int<int64_t>(j, "totalSimulations", path);
  v.planning_seconds_used = r.Number(j, "planningSecondsUsed");
  return v;
}

object_search::ObjectDetection ReadDetection(Reader& r, const json& d, const std::string& path) {
  object_search::ObjectDetection det;
  det.key = r.String(d, "id");
  det.box = r.Box(d, "box", path);
  det.moveability = r.Number(d, "moveability", 1.0);
  if (d.contains("faces")) {
    const json& faces = d.at("faces");
    for (size_t i = 0; i < faces.size(); ++i) {
      det.faces.push_back({r.Int<int>(faces[i], "corner", At(Join(path, "faces"), i)),
                           r.Number(faces[i], "score")});
    }
  }
  if (d.contains("score")) det.score = r.Number(d, "score");
  return det;
}

perception::PerceptionResult ReadPerception(Reader& r, const json& p, const std::string& path) {
  perception::PerceptionResult out;
  out.observation.achieved = r.Config(p, "robotState");
  const std::string registration = r.String(p, "registration");
  out.used_ransac = registration == "RANSAC_ICP";
  const json& fitness = p.at("fitness");
  // The renderer's rule: a pose registered has a finite fitness, one left as reported none.
  if ((registration == "SKIPPED") != fitness.is_null()) {
    r.Fail(Join(path, "fitness"), registration == "SKIPPED" ? "a fitness for a registration SKIPPED"
                                                            : "no fitness for a registered pose");
  }
  out.fitness =
      fitness.is_number() ? fitness.get<double>() : std::numeric_limits<double>::quiet_NaN();
  out.clusters = r.Int<int>(p, "clusters", path);
  const json& detections = p.at("detections");
  for (size_t i = 0; i < detections.size(); ++i) {
    out.observation.objects.push_back(
        ReadDetection(r, detections[i], At(Join(path, "detections"), i)));
  }
  const json& t = p.at("timingsMs");
  out.timings.registration = r.Number(t, "registration");
  out.timings.segmentation = r.Number(t, "segmentation");
  out.timings.association = r.Number(t, "association");
  out.timings.detection = r.Number(t, "detection");
  out.timings.total = r.Number(t, "total");
  if (p.contains("boxObjects")) {
    for (const json& id : p.at("boxObjects")) {
      out.box_objects.push_back(id.is_string() ? id.get<std::string>() : "");
    }
  }
  return out;
}

}  // namespace

// ---- requests ----

std::string EncodeWorldSpec(const WorldSpec& world) {
  return internal::Dump(internal::WorldSpecJson(world));
}

StatusOr<WorldSpec> ParseWorldSpec(std::string_view text, const Limits& limits) {
  auto j = internal::ParseBody(text, limits.max_json_depth, limits.max_json_values, false);
  if (!j.ok()) return j.status();
  // A scenario file's own parts: what the robot is not told.
  for (const char* key : {"name", "description", "noise", "objects"}) j->erase(key);
  internal::IntegralNumbersAsIntegers(*j);
  if (Status s = internal::ValidateAgainstSchema("world", *j); !s.ok()) return s;
  return internal::ReadWorldSpec(*j, "", limits);
}

std::string EncodeCreateSession(const CreateSessionRequest& request) {
  json j = json::object();
  if (!request.display_name.empty()) j["displayName"] = request.display_name;
  j["world"] = internal::WorldSpecJson(request.world);
  const TargetSpec& target = request.target;
  if (!target.description.empty() || !target.photos.empty()) {
    json t = json::object();
    if (!target.description.empty()) t["description"] = target.description;
    if (!target.photos.empty()) {
      t["photos"] = json::array();
      for (const std::string& photo : target.photos) t["photos"].push_back(Base64Encode(photo));
    }
    j["target"] = std::move(t);
  }
  const PlannerSpec& p = request.planner;
  json planner = {{"name", p.name}};
  if (p.particles != PlannerSpec().particles) planner["particles"] = p.particles;
  if (!p.options.empty()) planner["options"] = internal::PlannerOptionsJson(p);
  if (p.model_given) planner["model"] = p.model;
  j["planner"] = std::move(planner);
  if (request.seed) j["seed"] = *request.seed;
  if (request.ttl_seconds) j["ttlSeconds"] = *request.ttl_seconds;
  return internal::Dump(j);
}

std::string EncodePlan(const PlanRequest& request) {
  json budget = json::object();
  if (request.time_ms) budget["timeMs"] = *request.time_ms;
  if (request.cpu_ms) budget["cpuMs"] = *request.cpu_ms;
  if (request.simulations) budget["simulations"] = *request.simulations;
  return internal::Dump(json{{"budget", budget}});
}

StatusOr<std::string> EncodeObserve(const ObserveRequest& request) {
  json j = json::object();
  if (!request.action_id.empty()) j["actionId"] = request.action_id;
  j["succeeded"] = request.succeeded;
  if (request.robot_state) j["robotState"] = internal::ConfigJson(*request.robot_state);
  if (!request.frame) {
    j["detections"] = json::array();
    for (const auto& d : request.detections) j["detections"].push_back(internal::DetectionJson(d));
    return internal::Dump(j);
  }
  const perception::SensorFrame& frame = *request.frame;
  j["pointCloud"] = {{"frame", frame.cloud_in_map_frame ? "map" : "camera"},
                     {"fields", "xyzrgb"},
                     {"data", frame.cloud ? Base64Encode(EncodeCloud(*frame.cloud)) : ""}};
  if (!frame.image.empty()) {
    auto png = EncodePng(frame.image);
    if (!png.ok()) return InvalidFieldError("image", png.status().message());
    j["image"] = {{"encoding", "png"}, {"data", Base64Encode(*png)}};
  }
  const perception::CameraIntrinsics& in = frame.intrinsics;
  j["camera"] = {{"width", in.width}, {"height", in.height}, {"fx", in.fx},
                 {"fy", in.fy},       {"cx", in.cx},         {"cy", in.cy}};
  if (!frame.semantic_scores.empty()) j["semanticScores"] = frame.semantic_scores;
  if (frame.image_boxes) {
    j["imageBoxes"] = json::array();
    for (const perception::ImageBox& b : *frame.image_boxes) {
      j["imageBoxes"].push_back(
          {{"x", b.x}, {"y", b.y}, {"width", b.width}, {"height", b.height}, {"score", b.score}});
    }
  }
  return internal::Dump(j);
}

// ---- replies ----

StatusOr<SessionView> ParseSessionReply(std::string_view body, const Limits& limits) {
  const std::string what = "the session reply";
  auto j = ParseReply(body, "session", what, limits);
  if (!j.ok()) return j.status();
  Reader r(what);
  SessionView v = ReadSession(r, *j, "");
  if (!r.status().ok()) return r.status();
  return v;
}

StatusOr<PlanReply> ParsePlanReply(std::string_view body, const Limits& limits) {
  const std::string what = "the plan reply";
  auto parsed = ParseReply(body, "plan_response", what, limits);
  if (!parsed.ok()) return parsed.status();
  const json& j = *parsed;
  Reader r(what);
  PlanReply p;
  p.action_id = r.String(j, "actionId");
  p.action = r.Action(j, "action", "");
  p.expected_value = r.Number(j, "expectedValue");
  const json& s = j.at("stats");
  p.stats.simulations = r.Int<int64_t>(s, "simulations", "stats");
  p.stats.elapsed_ms = r.Number(s, "elapsedMs");
  p.stats.cpu_ms = r.Number(s, "cpuMs");
  p.stats.teardown_ms = r.Number(s, "teardownMs");
  p.stats.tree_nodes = r.Int<int64_t>(s, "treeNodes", "stats");
  p.stats.max_depth = r.Int<int>(s, "maxDepth", "stats");
  p.stats.root_actions = r.Int<int>(s, "rootActions", "stats");
  p.stats.root_visits = r.Int<int64_t>(s, "rootVisits", "stats");
  p.stats.reused_visits = r.Int<int64_t>(s, "reusedVisits", "stats");
  p.stats.refinements = r.Int<int64_t>(s, "refinements", "stats");
  p.stats.budget_exhausted = r.Bool(s, "budgetExhausted", true);
  if (s.contains("candidates")) {
    const json& c = s.at("candidates");
    p.candidates.sampled = r.Int<int>(c, "sampled", "stats.candidates");
    p.candidates.accepted = r.Int<int>(c, "accepted", "stats.candidates");
    p.candidates.elapsed_ms = r.Number(c, "elapsedMs");
  }
  p.budget = ReadBudget(r, j.at("budget"), "budget");
  const json& summary = j.at("summary");
  p.summary.budget_given = ReadBudget(r, summary.at("budgetGiven"), "summary.budgetGiven");
  p.summary.options_given = OptionValues(summary.at("optionsGiven"));
  p.summary.options_used = OptionValues(summary.at("optionsUsed"));
  p.summary.resolved = OptionValues(summary.at("resolved"));
  p.session = ReadSession(r, j.at("session"), "session");
  if (!r.status().ok()) return r.status();
  return p;
}

StatusOr<ObserveReply> ParseObserveReply(std::string_view body, const Limits& limits) {
  const std::string what = "the observe reply";
  auto parsed = ParseReply(body, "observe_response", what, limits);
  if (!parsed.ok()) return parsed.status();
  const json& j = *parsed;
  Reader r(what);
  ObserveReply o;
  o.done = r.Bool(j, "done");
  o.reward = r.Number(j, "reward");
  if (j.contains("perception")) o.perception = ReadPerception(r, j.at("perception"), "perception");
  o.session = ReadSession(r, j.at("session"), "session");
  if (!r.status().ok()) return r.status();
  return o;
}

StatusOr<HealthView> ParseHealthReply(std::string_view body, const Limits& limits) {
  const std::string what = "the health reply";
  auto parsed = ParseReply(body, "health", what, limits);
  if (!parsed.ok()) return parsed.status();
  const json& j = *parsed;
  Reader r(what);
  HealthView h;
  h.store_ok = r.String(j, "status") == "SERVING";
  if (j.contains("store")) {
    const json& store = j.at("store");
    h.store_backend = r.String(store, "backend", h.store_backend);
    h.store_message = r.String(store, "message");
    if ((r.String(store, "status") == "OK") != h.store_ok) {
      r.Fail("store.status", "the store is " + r.String(store, "status") + " and the server " +
                                 r.String(j, "status"));
    }
  }
  h.sessions_held = r.Int<int>(j, "sessionsHeld", "");
  h.version = r.String(j, "version");
  if (!r.status().ok()) return r.status();
  return h;
}

Status ParseErrorReply(int http_status, std::string_view body, const Limits& limits) {
  const std::string what = "HTTP " + std::to_string(http_status) + ": the error reply";
  auto parsed = ParseReply(body, "error", what, limits);
  if (!parsed.ok()) return parsed.status();
  const json& e = parsed->at("error");
  const std::string name = internal::String(e, "status");
  StatusCode code = StatusCode::kUnknown;
  for (int c = 1; c <= static_cast<int>(StatusCode::kUnauthenticated); ++c) {
    if (StatusCodeName(static_cast<StatusCode>(c)) == name) code = static_cast<StatusCode>(c);
  }
  Status out(code, internal::String(e, "message"));
  for (const json& detail : e.at("details")) {
    if (!detail.contains("fieldViolations")) continue;
    const json& violations = detail.at("fieldViolations");
    // "additionalProperties": true lets a detail carry any member: only an array is read.
    if (!violations.is_array()) continue;
    for (const json& v : violations) {
      if (!v.is_object()) continue;
      out.WithFieldViolation(internal::String(v, "field"), internal::String(v, "description"));
    }
  }
  return out;
}

StatusOr<ActionView> ParseAction(std::string_view body, const Limits& limits) {
  const std::string what = "the action";
  auto parsed = ParseReply(body, "action", what, limits);
  if (!parsed.ok()) return parsed.status();
  ActionView a;
  if (!internal::ReadAction(*parsed, &a)) {
    return NotAsDescribed(what, InvalidFieldError("body", "expected an action"));
  }
  return a;
}

}  // namespace npfkct::api
