#include "step_codec.h"

#include <cmath>
#include <ctime>

#include "npfkct/api/api.h"
#include "npfkct/api/client_codec.h"
#include "npfkct/api/limits.h"

namespace npfkct::api::internal {

constexpr const char* kActionTypes[] = {"MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE"};

std::string Rfc3339(int64_t ms) {
  const std::time_t secs = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<int>(ms % 1000));
  return buf;
}

json ActionJson(const ActionView& a) {
  json out = {{"type", kActionTypes[static_cast<int>(a.type)]}};
  if (a.type == ActionView::Type::kMove) {
    out["configuration"] = ConfigJson(a.configuration);
  } else {
    out["objectId"] = a.object_id;
    if (a.object_box) out["objectBox"] = BoxJson(*a.object_box);
  }
  return out;
}

bool ReadAction(const json& j, ActionView* a) {
  const std::string type = String(j, "type");
  for (int i = 0; i < 4; ++i) {
    if (type != kActionTypes[i]) continue;
    a->type = static_cast<ActionView::Type>(i);
    if (a->type == ActionView::Type::kMove) {
      if (!j.contains("configuration") || !j.at("configuration").is_object()) return false;
      a->configuration = ReadConfig(j.at("configuration"));
      return true;
    }
    a->object_id = Utf8Prefix(String(j, "objectId"), HardLimits().max_id_length);
    if (j.contains("objectBox")) {
      object_search::Box box;
      if (!ReadBox(j.at("objectBox"), &box)) return false;
      a->object_box = box;
    }
    return true;
  }
  return false;
}

json PlannerOptionsJson(const PlannerSpec& p) {
  json options = json::object();
  for (size_t i = 0; i < p.options.size(); ++i) {
    const std::string key = CamelCase(p.options[i].first);
    const double value = p.options[i].second;
    if (i < p.option_is_bool.size() && p.option_is_bool[i]) {
      options[key] = value != 0.0;
    } else if (value == std::floor(value) && std::abs(value) < 9e15) {
      options[key] = static_cast<int64_t>(value);
    } else {
      options[key] = value;
    }
  }
  return options;
}

json DetectionJson(const object_search::ObjectDetection& d) {
  json faces = json::array();
  for (const auto& f : d.faces) faces.push_back({{"corner", f.corner}, {"score", f.score}});
  json j = {{"id", d.key}, {"box", BoxJson(d.box)}, {"moveability", d.moveability}};
  // One score for the whole object, or per-face scores.
  if (!std::isnan(d.score)) {
    j["score"] = d.score;
  } else {
    j["faces"] = faces;
  }
  return j;
}

json StatsJson(const SearchStats& s, const CandidateStats& candidates) {
  json out = {{"simulations", s.simulations},
              {"elapsedMs", s.elapsed_ms},
              {"cpuMs", s.cpu_ms},
              {"teardownMs", s.teardown_ms},
              {"treeNodes", s.tree_nodes},
              {"maxDepth", s.max_depth},
              {"rootActions", s.root_actions},
              {"rootVisits", s.root_visits},
              {"reusedVisits", s.reused_visits},
              {"refinements", s.refinements},
              {"budgetExhausted", s.budget_exhausted}};
  if (candidates.sampled > 0) {
    out["candidates"] = {{"sampled", candidates.sampled},
                         {"accepted", candidates.accepted},
                         {"elapsedMs", candidates.elapsed_ms}};
  }
  return out;
}

json StepJson(const StepRecord& s, bool record) {
  json out = {{"step", s.step},
              {"actionId", s.action_id},
              {"action", ActionJson(s.action)},
              {"expectedValue", s.expected_value},
              {"stats", StatsJson(s.stats, s.candidates)}};
  if (record) {
    out["planTimeMs"] = s.plan_time_ms;
  } else {
    out["planTime"] = Rfc3339(s.plan_time_ms);
  }
  if (s.outcome) {
    const StepRecord::Outcome& o = *s.outcome;
    out["outcome"] = {
        {"succeeded", o.succeeded},    {"reward", o.reward}, {"detections", o.detections},
        {"newObjects", o.new_objects}, {"raw", o.raw},       {"done", o.done}};
    if (o.robot) out["outcome"]["robotState"] = ConfigJson(*o.robot);
    if (record) {
      out["outcome"]["timeMs"] = o.time_ms;
    } else {
      out["outcome"]["time"] = Rfc3339(o.time_ms);
    }
  }
  return out;
}

bool ReadStep(const json& j, StepRecord* s) {
  if (!j.is_object() || !j.contains("action") || !ReadAction(j.at("action"), &s->action)) {
    return false;
  }
  s->step = static_cast<int>(std::clamp<int64_t>(Integer(j, "step"), 0, 1'000'000'000));
  s->action_id = Utf8Prefix(String(j, "actionId"), HardLimits().max_id_length);
  s->expected_value = Number(j, "expectedValue");
  s->plan_time_ms = Integer(j, "planTimeMs");
  const json stats = j.value("stats", json::object());
  s->stats.simulations = Integer(stats, "simulations");
  s->stats.elapsed_ms = Number(stats, "elapsedMs");
  s->stats.cpu_ms = Number(stats, "cpuMs");
  s->stats.teardown_ms = Number(stats, "teardownMs");
  s->stats.tree_nodes = Integer(stats, "treeNodes");
  s->stats.max_depth = static_cast<int>(std::clamp<int64_t>(Integer(stats, "maxDepth"), 0, 1000));
  s->stats.root_actions =
      static_cast<int>(std::clamp<int64_t>(Integer(stats, "rootActions"), 0, 1'000'000'000));
  s->stats.root_visits = Integer(stats, "rootVisits");
  s->stats.reused_visits = Integer(stats, "reusedVisits");
  s->stats.refinements = Integer(stats, "refinements");
  s->stats.budget_exhausted = Bool(stats, "budgetExhausted", true);
  if (stats.contains("candidates")) {
    const json& c = stats.at("candidates");
    s->candidates.sampled =
        static_cast<int>(std::clamp<int64_t>(Integer(c, "sampled"), 0, 1 << 30));
    s->candidates.accepted =
        static_cast<int>(std::clamp<int64_t>(Integer(c, "accepted"), 0, 1 << 30));
    s->candidates.elapsed_ms = Number(c, "elapsedMs");
  }
  if (j.contains("outcome")) {
    const json& o = j.at("outcome");
    if (!o.is_object()) return false;
    StepRecord::Outcome out;
    out.succeeded = Bool(o, "succeeded", true);
    out.reward = Number(o, "reward");
    out.detections = static_cast<int>(std::clamp<int64_t>(Integer(o, "detections"), 0, 1 << 20));
    out.new_objects = static_cast<int>(std::clamp<int64_t>(Integer(o, "newObjects"), 0, 1 << 20));
    out.raw = Bool(o, "raw");
    out.done = Bool(o, "done");
    out.time_ms = Integer(o, "timeMs");
    if (o.contains("robotState") && o.at("robotState").is_object()) {
      out.robot = ReadConfig(o.at("robotState"));
    }
    s->outcome = out;
  }
  return true;
}

}  // namespace npfkct::api::internal

namespace npfkct::api {

const char* ActionTypeName(ActionView::Type type) {
  return internal::kActionTypes[static_cast<int>(type)];
}

}  // namespace npfkct::api
