// Typed replies to response bodies.
#include <cmath>
#include <ctime>
#include <opencv2/imgproc.hpp>

#include "json_util.h"
#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "world_codec.h"

namespace npfkct::api {
namespace {

using internal::json;

std::string Rfc3339(std::chrono::system_clock::time_point t) {
  const int64_t ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
  const std::time_t secs = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<int>(ms % 1000));
  return buf;
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

json ActionJson(const ActionView& a) {
  static const char* kTypes[] = {"MOVE", "DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE"};
  json out = {{"type", kTypes[static_cast<int>(a.type)]}};
  if (a.type == ActionView::Type::kMove) {
    out["configuration"] = internal::ConfigJson(a.configuration);
  } else {
    out["objectId"] = a.object_id;
    if (a.object_box) out["objectBox"] = internal::BoxJson(*a.object_box);
  }
  return out;
}

json OptionsJson(const PlannerSpec& p) {
  json options = json::object();
  for (size_t i = 0; i < p.options.size(); ++i) {
    const auto& [key, value] = p.options[i];
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
                  {"options", OptionsJson(s.planner)}};
  if (!s.planner.model.empty()) j["planner"]["model"] = s.planner.model;
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
  const SearchStats& s = r.stats;
  out["stats"] = {{"simulations", s.simulations},
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
  if (r.candidates.sampled > 0) {
    out["stats"]["candidates"] = {{"sampled", r.candidates.sampled},
                                  {"accepted", r.candidates.accepted},
                                  {"elapsedMs", r.candidates.elapsed_ms}};
  }
  out["budget"] = BudgetJson(r.budget);
  out["session"] = SessionJson(r.session);
  return internal::Dump(out);
}

std::string RenderObserve(const ObserveReply& r) {
  json out;
  out["done"] = r.done;
  out["reward"] = r.reward;
  if (r.perception) {
    const perception::PerceptionResult& p = *r.perception;
    json objects = json::array();
    for (const auto& d : p.observation.objects) {
      json faces = json::array();
      for (const auto& f : d.faces) faces.push_back({{"corner", f.corner}, {"score", f.score}});
      objects.push_back({{"id", d.key},
                         {"box", internal::BoxJson(d.box)},
                         {"moveability", d.moveability},
                         {"faces", faces}});
    }
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
  }
  out["session"] = SessionJson(r.session);
  return internal::Dump(out);
}

std::string RenderBelief(const World& world) { return internal::Dump(internal::BeliefJson(world)); }

StatusOr<std::string> RenderBeliefPng(const World& world, int64_t max_pixels) {
  const auto& occ = world.occupancy;
  const object_search::Vec2 lo = occ.min(), hi = occ.max();
  const double area = std::max(1e-6, (hi.x() - lo.x()) * (hi.y() - lo.y()));
  // 150 pixels per metre, fewer for a large room so that the picture stays within max_pixels.
  const double ppm =
      std::max(1e-3, std::min(150.0, std::sqrt(static_cast<double>(max_pixels) / area)));
  const int w = std::clamp(static_cast<int>((hi.x() - lo.x()) * ppm), 1, 8192);
  const int h = std::clamp(static_cast<int>((hi.y() - lo.y()) * ppm), 1, 8192);
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(245, 245, 245));
  auto px = [&](double x, double y) {
    return cv::Point(static_cast<int>((x - lo.x()) * ppm), static_cast<int>((hi.y() - y) * ppm));
  };
  // Occupied map cells: the map at its own resolution, scaled up (row 0 is the top, max y).
  if (occ.nx() > 0 && occ.ny() > 0) {
    cv::Mat cells(occ.ny(), occ.nx(), CV_8U, const_cast<uint8_t*>(occ.cells().data()));
    cv::Mat flipped, mask;
    cv::flip(cells, flipped, 0);
    cv::resize(flipped, mask, cv::Size(w, h), 0, 0, cv::INTER_NEAREST);
    img.setTo(cv::Scalar(200, 200, 200), mask);
  }
  for (const auto& region : world.base_regions) {
    cv::rectangle(img, px(region.min.x(), region.max.y()), px(region.max.x(), region.min.y()),
                  cv::Scalar(60, 60, 220), 1);
  }
  // Grid-world odds as colour: blue (0) -> white (0.5) -> red (1).
  const auto& grid = world.grid;
  const double half = 0.5 * grid.resolution();
  for (int c = 0; c < grid.num_cells(); ++c) {
    const auto p = grid.CellCenter(c);
    const double prob = 1.0 / (1.0 + std::exp(-grid.log_odds(c)));
    const cv::Scalar color = prob > 0.5
                                 ? cv::Scalar(255 * (2 - 2 * prob), 255 * (2 - 2 * prob), 255)
                                 : cv::Scalar(255, 255 * 2 * prob, 255 * 2 * prob);
    cv::rectangle(img, px(p.x() - half, p.y() + half), px(p.x() + half, p.y() - half), color,
                  cv::FILLED);
  }
  for (size_t i = 1; i < world.objects.size(); ++i) {
    const auto& o = world.objects[i];
    if (o.status == object_search::kRemoved) continue;
    const auto k = o.box.Corners();
    const std::vector<cv::Point> poly = {px(k[0].x(), k[0].y()), px(k[1].x(), k[1].y()),
                                         px(k[3].x(), k[3].y()), px(k[2].x(), k[2].y())};
    const cv::Scalar color = o.status == object_search::kDeclaredTarget ? cv::Scalar(0, 160, 0)
                             : o.status == object_search::kDeclaredObstacle
                                 ? cv::Scalar(0, 0, 0)
                                 : cv::Scalar(90, 90, 90);
    cv::polylines(img, poly, true, color, 2);
  }
  const auto& c = world.robot_config;
  cv::circle(img, px(c.x, c.y), std::max(1, static_cast<int>(world.robot.footprint_radius * ppm)),
             cv::Scalar(40, 40, 40), 2);
  const double heading = c.yaw + c.pan;
  cv::arrowedLine(img, px(c.x, c.y),
                  px(c.x + 0.6 * std::cos(heading), c.y + 0.6 * std::sin(heading)),
                  cv::Scalar(0, 120, 255), 2);
  return EncodePng(img);
}

std::string RenderHealth() { return R"({"status":"SERVING"})"; }

std::string RenderHealth(const HealthView& h) {
  json store = {{"backend", h.store_backend}, {"status", h.store_ok ? "OK" : "UNAVAILABLE"}};
  if (!h.store_ok) store["message"] = h.store_message;
  json j = {{"status", h.store_ok ? "SERVING" : "NOT_SERVING"},
            {"store", store},
            {"sessionsHeld", h.sessions_held}};
  return internal::Dump(j);
}
std::string RenderEmpty() { return "{}"; }

}  // namespace npfkct::api
