// The client's direction of the API: the encoders write what the server's own parsers read back
// to the same request, the decoders read what the server's own renderers write back to the same
// reply, and a reply that is not what the API describes is DATA_LOSS naming the field.
#include "npfkct/api/client_codec.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/common/version.h"
#include "step_codec.h"

namespace npfkct::api {
namespace {

using nlohmann::json;

const Limits kLimits;
constexpr const char* kScenarios[] = {"complex1", "covered1", "fig16",
                                      "hidden1",  "loose1",   "loose2"};

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

std::string Scenario(const std::string& name) {
  return ReadFile(std::string(NPFKCT_SCENARIO_DIR) + "/" + name + ".json");
}

// The first field violation of a failed call.
std::string FieldOf(const Status& s) {
  return s.ok() || s.field_violations().empty() ? "<none: " + s.ToString() + ">"
                                                : s.field_violations()[0].field;
}
template <class T>
std::string FieldOf(const StatusOr<T>& r) {
  return FieldOf(r.status());
}

void ExpectSameConfig(const RobotConfig& a, const RobotConfig& b) {
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.y, b.y);
  EXPECT_EQ(a.yaw, b.yaw);
  EXPECT_EQ(a.lift, b.lift);
  EXPECT_EQ(a.pan, b.pan);
  EXPECT_EQ(a.tilt, b.tilt);
}

void ExpectSameBox(const object_search::Box& a, const object_search::Box& b) {
  EXPECT_EQ(a.center, b.center);
  EXPECT_EQ(a.size, b.size);
  EXPECT_EQ(a.yaw, b.yaw);
}

// Everything of a world spec that goes over the wire.
void ExpectSameWorld(const WorldSpec& a, const WorldSpec& b) {
  EXPECT_EQ(a.robot, b.robot);
  EXPECT_EQ(a.room_min, b.room_min);
  EXPECT_EQ(a.room_max, b.room_max);
  EXPECT_EQ(a.map_resolution, b.map_resolution);
  ASSERT_EQ(a.furniture.size(), b.furniture.size());
  for (size_t i = 0; i < a.furniture.size(); ++i) {
    EXPECT_EQ(a.furniture[i].name, b.furniture[i].name);
    ExpectSameBox(a.furniture[i].box, b.furniture[i].box);
    EXPECT_EQ(a.furniture[i].workspace, b.furniture[i].workspace);
  }
  ASSERT_EQ(a.base_regions.size(), b.base_regions.size());
  for (size_t i = 0; i < a.base_regions.size(); ++i) {
    EXPECT_EQ(a.base_regions[i].min, b.base_regions[i].min);
    EXPECT_EQ(a.base_regions[i].max, b.base_regions[i].max);
  }
  ASSERT_EQ(a.discrete_poses.size(), b.discrete_poses.size());
  for (size_t i = 0; i < a.discrete_poses.size(); ++i) {
    ExpectSameConfig(a.discrete_poses[i], b.discrete_poses[i]);
  }
  ExpectSameConfig(a.start, b.start);
  const object_search::SearchParams &p = a.params, &q = b.params;
  const std::pair<double, double> params[] = {{p.r_max, q.r_max},
                                              {p.r_ct, q.r_ct},
                                              {p.r_co, q.r_co},
                                              {p.r_min, q.r_min},
                                              {p.r_ill, q.r_ill},
                                              {p.discount, q.discount},
                                              {p.c_o, q.c_o},
                                              {p.eta_std, q.eta_std},
                                              {p.nu_p, q.nu_p},
                                              {p.nu_n, q.nu_n},
                                              {p.declare_threshold, q.declare_threshold},
                                              {p.guess_odds, q.guess_odds},
                                              {p.guess_size, q.guess_size},
                                              {p.grid_free_delta, q.grid_free_delta}};
  for (auto [x, y] : params) EXPECT_EQ(x, y);
  EXPECT_EQ(p.n_odds, q.n_odds);
  EXPECT_EQ(p.max_steps, q.max_steps);
}

void ExpectSamePlanner(const PlannerSpec& a, const PlannerSpec& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.particles, b.particles);
  EXPECT_EQ(a.model, b.model);
  EXPECT_EQ(a.model_given, b.model_given);
  EXPECT_EQ(a.takes_model, b.takes_model);
  EXPECT_EQ(a.options, b.options);
  EXPECT_EQ(a.option_is_bool, b.option_is_bool);
}

void ExpectSameAction(const ActionView& a, const ActionView& b) {
  EXPECT_EQ(a.type, b.type);
  if (a.type == ActionView::Type::kMove) {
    ExpectSameConfig(a.configuration, b.configuration);
    return;
  }
  EXPECT_EQ(a.object_id, b.object_id);
  ASSERT_EQ(a.object_box.has_value(), b.object_box.has_value());
  if (a.object_box) ExpectSameBox(*a.object_box, *b.object_box);
}

void ExpectSameDetections(const std::vector<object_search::ObjectDetection>& a,
                          const std::vector<object_search::ObjectDetection>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].key, b[i].key);
    ExpectSameBox(a[i].box, b[i].box);
    EXPECT_EQ(a[i].moveability, b[i].moveability);
    ASSERT_EQ(a[i].faces.size(), b[i].faces.size());
    for (size_t k = 0; k < a[i].faces.size(); ++k) {
      EXPECT_EQ(a[i].faces[k].corner, b[i].faces[k].corner);
      EXPECT_EQ(a[i].faces[k].score, b[i].faces[k].score);
    }
  }
}

void ExpectSameSession(const SessionView& a, const SessionView& b) {
  EXPECT_EQ(a.id, b.id);
  EXPECT_EQ(a.display_name, b.display_name);
  EXPECT_EQ(a.state, b.state);
  EXPECT_EQ(a.create_time, b.create_time);
  EXPECT_EQ(a.update_time, b.update_time);
  EXPECT_EQ(a.ttl_seconds, b.ttl_seconds);
  ExpectSamePlanner(a.planner, b.planner);
  EXPECT_EQ(a.seed, b.seed);
  EXPECT_EQ(a.target_description, b.target_description);
  EXPECT_EQ(a.photo_count, b.photo_count);
  EXPECT_EQ(a.perception_tracks, b.perception_tracks);
  EXPECT_EQ(a.step, b.step);
  ExpectSameConfig(a.robot, b.robot);
  EXPECT_EQ(a.object_count, b.object_count);
  ASSERT_EQ(a.pending.has_value(), b.pending.has_value());
  if (a.pending) {
    EXPECT_EQ(a.pending->first, b.pending->first);
    ExpectSameAction(a.pending->second, b.pending->second);
  }
  EXPECT_EQ(a.total_simulations, b.total_simulations);
  EXPECT_EQ(a.planning_seconds_used, b.planning_seconds_used);
}

// NaN-aware equality of option values.
void ExpectSameValues(const std::vector<std::pair<std::string, double>>& a,
                      const std::vector<std::pair<std::string, double>>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].first, b[i].first);
    if (std::isnan(a[i].second)) {
      EXPECT_TRUE(std::isnan(b[i].second)) << a[i].first;
    } else {
      EXPECT_EQ(a[i].second, b[i].second) << a[i].first;
    }
  }
}

void ExpectSameBudget(const Budget& a, const Budget& b) {
  EXPECT_EQ(a.time_ms, b.time_ms);
  EXPECT_EQ(a.cpu_ms, b.cpu_ms);
  EXPECT_EQ(a.max_simulations, b.max_simulations);
}

RobotConfig Config(double x, double y, double yaw, double lift, double pan, double tilt) {
  RobotConfig c;
  c.x = x;
  c.y = y;
  c.yaw = yaw;
  c.lift = lift;
  c.pan = pan;
  c.tilt = tilt;
  return c;
}

object_search::ObjectDetection Detection(const std::string& id, double x) {
  object_search::ObjectDetection d;
  d.key = id;
  d.box = {{x, 0.1, 0.82}, 0.3, {0.12, 0.1, 0.14}};
  d.moveability = 0.75;
  d.faces = {{0, 0.2}, {5, 0.875}};
  return d;
}

// A session as a server would show it, with every optional part.
SessionView FullSession() {
  SessionView s;
  s.id = "0123456789abcdef0123456789abcdef";
  s.display_name = "kitchen, take 2";
  s.state = SessionState::kActionPending;
  s.create_time = FromUnixMillis(1767225600123);
  s.update_time = FromUnixMillis(1767225660999);
  s.ttl_seconds = 3600.5;
  s.planner.name = "npfkct";
  s.planner.particles = 250;
  s.planner.model = "filter.pt";
  s.planner.model_given = true;
  s.planner.takes_model = true;
  // Keys in the order a JSON object keeps them (sorted by their lowerCamelCase spelling).
  s.planner.options = {{"k", 4}, {"search.max_depth", 12}, {"use_filter", 1}, {"w1", 0.25}};
  s.planner.option_is_bool = {false, false, true, false};
  s.seed = 18446744073709551615ull;
  s.target_description = "the patterned box";
  s.photo_count = 4;
  s.perception_tracks = 7;
  s.step = 3;
  s.robot = Config(1.5, -0.25, 0.5, 0.2, -0.3, 0.6);
  s.object_count = 5;
  ActionView declare;
  declare.type = ActionView::Type::kDeclareTarget;
  declare.object_id = "track-3";
  declare.object_box = object_search::Box{{1.25, 0.5, 0.8}, 0.125, {0.1, 0.2, 0.3}};
  s.pending = std::make_pair("a4-0001", declare);
  s.total_simulations = int64_t{1} << 40;
  s.planning_seconds_used = 12.75;
  return s;
}

// ---- requests: the server's parsers read the encoders' bodies back ----

TEST(EncodeCreateSession, TheServerReadsBackTheRequest) {
  CreateSessionRequest req;
  req.display_name = "npfkct-drive loose1";
  req.world = ParseWorldSpec(Scenario("loose1"), kLimits).value();
  req.world.params.r_max = 2e5;
  req.world.params.discount = 0.95;
  req.world.params.guess_odds = 0.1;
  req.world.params.n_odds = 4;
  req.world.params.max_steps = 30;
  req.target.description = "a red box";
  cv::Mat photo(20, 24, CV_8UC3, cv::Scalar(10, 200, 30));
  req.target.photos = {EncodePng(photo).value(), EncodePng(photo.t()).value()};
  req.planner.name = "npfkct";
  req.planner.particles = 200;
  req.planner.model = "filter.pt";
  req.planner.model_given = true;
  req.planner.takes_model = true;
  req.planner.options = {{"k", 4}, {"search.max_depth", 12}, {"use_filter", 1}, {"w1", 0.25}};
  req.planner.option_is_bool = {false, false, true, false};
  req.seed = 18446744073709551615ull;
  req.ttl_seconds = 120.5;
  auto back = ParseCreateSession(EncodeCreateSession(req), kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->display_name, req.display_name);
  ExpectSameWorld(back->world, req.world);
  EXPECT_EQ(back->target.description, req.target.description);
  EXPECT_EQ(back->target.photos, req.target.photos);
  ExpectSamePlanner(back->planner, req.planner);
  EXPECT_EQ(back->seed, req.seed);
  EXPECT_EQ(back->ttl_seconds, req.ttl_seconds);

  // The least of requests: a world; the rest as the server assumes it.
  CreateSessionRequest least;
  least.world = req.world;
  least.planner.takes_model = true;  // npfkct's registry entry
  const json body = json::parse(EncodeCreateSession(least));
  EXPECT_EQ(body["planner"], json({{"name", "npfkct"}}));
  EXPECT_FALSE(body.contains("target") || body.contains("seed") || body.contains("ttlSeconds") ||
               body.contains("displayName"));
  auto least_back = ParseCreateSession(body.dump(), kLimits);
  ASSERT_TRUE(least_back.ok()) << least_back.status().ToString();
  ExpectSamePlanner(least_back->planner, least.planner);
  EXPECT_FALSE(least_back->seed || least_back->ttl_seconds);
  // "" asks for no model; it is sent.
  least.planner.model_given = true;
  auto no_model = ParseCreateSession(EncodeCreateSession(least), kLimits);
  ASSERT_TRUE(no_model.ok()) << no_model.status().ToString();
  EXPECT_TRUE(no_model->planner.model_given);
  EXPECT_EQ(no_model->planner.model, "");
}

TEST(EncodeWorldSpec, EveryScenarioWorldGoesOverTheWireWhole) {
  for (const char* name : kScenarios) {
    SCOPED_TRACE(name);
    auto world = ParseWorldSpec(Scenario(name), kLimits);
    ASSERT_TRUE(world.ok()) << world.status().ToString();
    CreateSessionRequest req;
    req.world = *world;
    auto back = ParseCreateSession(EncodeCreateSession(req), kLimits);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ExpectSameWorld(back->world, *world);
    // The defaults are not written: none of the scenarios sets params.
    EXPECT_FALSE(json::parse(EncodeWorldSpec(*world)).contains("params"));
    auto again = ParseWorldSpec(EncodeWorldSpec(*world), kLimits);
    ASSERT_TRUE(again.ok()) << again.status().ToString();
    ExpectSameWorld(*again, *world);
  }
}

TEST(ParseWorldSpec, ChecksAsTheServerDoes) {
  json s = json::parse(Scenario("loose1"));
  s["params"] = {{"baseClearance", 0.1}};  // a scenario file's, not the API's
  EXPECT_EQ(FieldOf(ParseWorldSpec(s.dump(), kLimits)), "params.baseClearance");
  s = json::parse(Scenario("loose1"));
  s["furniture"][0]["size"][0] = -1;
  EXPECT_EQ(FieldOf(ParseWorldSpec(s.dump(), kLimits)), "furniture[0].size[0]");
  s = json::parse(Scenario("loose1"));
  for (json& f : s["furniture"]) f["workspace"] = false;
  EXPECT_EQ(FieldOf(ParseWorldSpec(s.dump(), kLimits)), "furniture");
  EXPECT_EQ(ParseWorldSpec("[", kLimits).status().code(), StatusCode::kInvalidArgument);
}

TEST(EncodePlan, TheServerReadsBackTheBudget) {
  PlanRequest req;
  req.time_ms = 250.5;
  req.cpu_ms = 100;
  req.simulations = 5000;
  auto back = ParsePlan(EncodePlan(req), kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->time_ms, req.time_ms);
  EXPECT_EQ(back->cpu_ms, req.cpu_ms);
  EXPECT_EQ(back->simulations, req.simulations);
  auto none = ParsePlan(EncodePlan(PlanRequest{}), kLimits);
  ASSERT_TRUE(none.ok()) << none.status().ToString();
  EXPECT_FALSE(none->time_ms || none->cpu_ms || none->simulations);
  PlanRequest sims;
  sims.simulations = 300;
  EXPECT_EQ(EncodePlan(sims), R"({"budget":{"simulations":300}})");
}

TEST(EncodeObserve, TheServerReadsBackDetections) {
  ObserveRequest req;
  req.action_id = "a2-000017";
  req.succeeded = false;
  req.robot_state = Config(0.5, -1.25, 3.0, 0.3, 0.1, 0.7);
  req.detections = {Detection("box-1", 1.4), Detection("box-2", 1.6)};
  auto body = EncodeObserve(req);
  ASSERT_TRUE(body.ok()) << body.status().ToString();
  auto back = ParseObserve(*body, kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->action_id, req.action_id);
  EXPECT_EQ(back->succeeded, req.succeeded);
  ASSERT_TRUE(back->robot_state);
  ExpectSameConfig(*back->robot_state, *req.robot_state);
  ExpectSameDetections(back->detections, req.detections);
  EXPECT_FALSE(back->frame);
  // Nothing seen is an empty list; without an actionId (npfkct-sim-robot's observations) the body
  // is the rest.
  ObserveRequest empty;
  EXPECT_EQ(EncodeObserve(empty).value(), R"({"detections":[],"succeeded":true})");
}

TEST(EncodeObserve, TheServerReadsBackARawFrame) {
  ObserveRequest req;
  req.action_id = "a1-000001";
  req.robot_state = Config(0.1, 0.2, 0.3, 0.0, 0.4, 0.5);
  perception::SensorFrame frame;
  auto cloud = pcl::make_shared<perception::Cloud>();
  for (int i = 0; i < 50; ++i) {
    pcl::PointXYZRGB p;
    p.x = 0.01f * i;
    p.y = -0.5f + 0.02f * i;
    p.z = 1.0f + 0.001f * i;
    p.r = static_cast<uint8_t>(5 * i);
    p.g = 7;
    p.b = static_cast<uint8_t>(255 - i);
    cloud->push_back(p);
  }
  frame.cloud = cloud;
  frame.cloud_in_map_frame = true;
  frame.intrinsics.width = 24;
  frame.intrinsics.height = 16;
  frame.intrinsics.fx = 20.5;
  frame.intrinsics.fy = 19.25;
  frame.intrinsics.cx = 12;
  frame.intrinsics.cy = 8;
  frame.image = cv::Mat(16, 24, CV_8UC3);
  cv::randu(frame.image, 0, 255);
  frame.semantic_scores = {{"track-1", 0.25}, {"track-2", 1.0}};
  req.frame = frame;
  auto body = EncodeObserve(req);
  ASSERT_TRUE(body.ok()) << body.status().ToString();
  auto back = ParseObserve(*body, kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->action_id, req.action_id);
  ASSERT_TRUE(back->robot_state);
  ExpectSameConfig(*back->robot_state, *req.robot_state);
  EXPECT_TRUE(back->detections.empty());
  ASSERT_TRUE(back->frame);
  const perception::SensorFrame& f = *back->frame;
  EXPECT_TRUE(f.cloud_in_map_frame);
  ASSERT_EQ(f.cloud->size(), cloud->size());
  for (size_t i = 0; i < cloud->size(); ++i) {
    const auto &a = (*f.cloud)[i], &b = (*cloud)[i];
    EXPECT_EQ(a.x, b.x);
    EXPECT_EQ(a.y, b.y);
    EXPECT_EQ(a.z, b.z);
    EXPECT_EQ(a.r, b.r);
    EXPECT_EQ(a.g, b.g);
    EXPECT_EQ(a.b, b.b);
  }
  EXPECT_EQ(f.intrinsics.width, 24);
  EXPECT_EQ(f.intrinsics.height, 16);
  EXPECT_EQ(f.intrinsics.fx, 20.5);
  EXPECT_EQ(f.intrinsics.fy, 19.25);
  EXPECT_EQ(f.intrinsics.cx, 12);
  EXPECT_EQ(f.intrinsics.cy, 8);
  ASSERT_EQ(f.image.size(), frame.image.size());
  EXPECT_EQ(cv::norm(f.image, frame.image, cv::NORM_INF), 0.0);
  EXPECT_EQ(f.semantic_scores, frame.semantic_scores);

  // What ApiRobot::ObserveRaw sent by hand: the cloud in the camera frame as xyzrgb, the image as
  // a PNG, the intrinsics.
  req.frame->cloud_in_map_frame = false;
  req.frame->semantic_scores.clear();
  const json j = json::parse(EncodeObserve(req).value());
  EXPECT_EQ(j["pointCloud"]["frame"], "camera");
  EXPECT_EQ(j["pointCloud"]["fields"], "xyzrgb");
  EXPECT_EQ(j["pointCloud"]["data"], Base64Encode(EncodeCloud(*cloud)));
  EXPECT_EQ(j["image"]["encoding"], "png");
  EXPECT_EQ(j["image"]["data"], Base64Encode(EncodePng(frame.image).value()));
  EXPECT_EQ(
      j["camera"],
      json(
          {{"width", 24}, {"height", 16}, {"fx", 20.5}, {"fy", 19.25}, {"cx", 12.0}, {"cy", 8.0}}));
  EXPECT_FALSE(j.contains("detections") || j.contains("semanticScores"));
  // An image PNG cannot hold is the caller's error.
  req.frame->image = cv::Mat(16, 24, CV_32FC(7));
  EXPECT_EQ(FieldOf(EncodeObserve(req)), "image");
}

// ---- replies: the decoders read the server's renderers back ----

TEST(ParseSessionReply, ReadsTheRenderedSession) {
  const SessionView s = FullSession();
  auto back = ParseSessionReply(RenderSession(s), kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectSameSession(*back, s);
  // The least of sessions: no display name, no tracks, nothing pending, a planner without a
  // model.
  SessionView least;
  least.id = s.id;
  least.planner.name = "kct";
  auto least_back = ParseSessionReply(RenderSession(least), kLimits);
  ASSERT_TRUE(least_back.ok()) << least_back.status().ToString();
  ExpectSameSession(*least_back, least);
  // A MOVE pending.
  least.pending = std::make_pair("a1-0000", ActionView{});
  least.pending->second.configuration = Config(1, 2, 3, 0.1, 0.2, 0.3);
  least_back = ParseSessionReply(RenderSession(least), kLimits);
  ASSERT_TRUE(least_back.ok()) << least_back.status().ToString();
  ExpectSameSession(*least_back, least);
}

TEST(ParsePlanReply, ReadsTheRenderedPlanAndItsSummary) {
  PlanReply p;
  p.action_id = "a4-0001";
  p.action.type = ActionView::Type::kRemove;
  p.action.object_id = "box-3";
  p.expected_value = -12.5;
  p.stats = {123456, 250.5, 240.25, 1.5, 98765, 7, 12, 130000, 6544, 3, false};
  p.candidates = {400, 120, 8.5};
  p.budget = {1000, 5000, 0};
  p.summary.budget_given = {0, 5000, 0};
  p.summary.options_given = {{"search.max_depth", 12}};
  p.summary.options_used = {{"c_r", 0.5},
                            {"exploration_c", std::numeric_limits<double>::quiet_NaN()},
                            {"k", 4},
                            {"search.max_depth", 12}};
  p.summary.resolved = {{"value_scale", 1e5}, {"w2", 0.125}};
  p.session = FullSession();
  auto back = ParsePlanReply(RenderPlan(p), kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->action_id, p.action_id);
  ExpectSameAction(back->action, p.action);
  EXPECT_EQ(back->expected_value, p.expected_value);
  const SearchStats &a = back->stats, &b = p.stats;
  EXPECT_EQ(a.simulations, b.simulations);
  EXPECT_EQ(a.elapsed_ms, b.elapsed_ms);
  EXPECT_EQ(a.cpu_ms, b.cpu_ms);
  EXPECT_EQ(a.teardown_ms, b.teardown_ms);
  EXPECT_EQ(a.tree_nodes, b.tree_nodes);
  EXPECT_EQ(a.max_depth, b.max_depth);
  EXPECT_EQ(a.root_actions, b.root_actions);
  EXPECT_EQ(a.root_visits, b.root_visits);
  EXPECT_EQ(a.reused_visits, b.reused_visits);
  EXPECT_EQ(a.refinements, b.refinements);
  EXPECT_EQ(a.budget_exhausted, b.budget_exhausted);
  EXPECT_EQ(back->candidates.sampled, p.candidates.sampled);
  EXPECT_EQ(back->candidates.accepted, p.candidates.accepted);
  EXPECT_EQ(back->candidates.elapsed_ms, p.candidates.elapsed_ms);
  ExpectSameBudget(back->budget, p.budget);
  ExpectSameBudget(back->summary.budget_given, p.summary.budget_given);
  ExpectSameValues(back->summary.options_given, p.summary.options_given);
  ExpectSameValues(back->summary.options_used, p.summary.options_used);
  ExpectSameValues(back->summary.resolved, p.summary.resolved);
  ExpectSameSession(back->session, p.session);

  // A MOVE, no candidates drawn.
  p.action = ActionView{};
  p.action.configuration = Config(-1, 2.5, 0.75, 0.35, 0.5, 0.25);
  p.candidates = {};
  back = ParsePlanReply(RenderPlan(p), kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ExpectSameAction(back->action, p.action);
  EXPECT_EQ(back->candidates.sampled, 0);
}

TEST(ParseObserveReply, ReadsTheRenderedReplyWithAndWithoutPerception) {
  ObserveReply o;
  o.done = true;
  o.reward = 1e5;
  o.session = FullSession();
  o.session.state = SessionState::kDone;
  o.session.pending.reset();
  auto back = ParseObserveReply(RenderObserve(o), kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->done, o.done);
  EXPECT_EQ(back->reward, o.reward);
  EXPECT_FALSE(back->perception);
  ExpectSameSession(back->session, o.session);

  for (const char* registration : {"ICP", "RANSAC_ICP", "SKIPPED"}) {
    SCOPED_TRACE(registration);
    perception::PerceptionResult p;
    p.observation.achieved = Config(0.5, 0.25, 1.0, 0.1, 0.2, 0.3);
    p.observation.objects = {Detection("track-1", 1.25), Detection("track-2", 1.5)};
    p.used_ransac = std::string(registration) == "RANSAC_ICP";
    p.fitness =
        std::string(registration) == "SKIPPED" ? std::numeric_limits<double>::quiet_NaN() : 1.5e-4;
    p.clusters = 3;
    p.timings = {10.5, 20.25, 1.0, 30.0, 61.75};
    o.perception = p;
    back = ParseObserveReply(RenderObserve(o), kLimits);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ASSERT_TRUE(back->perception);
    const perception::PerceptionResult& q = *back->perception;
    ExpectSameConfig(q.observation.achieved, p.observation.achieved);
    ExpectSameDetections(q.observation.objects, p.observation.objects);
    EXPECT_EQ(q.used_ransac, p.used_ransac);
    EXPECT_EQ(std::isnan(q.fitness), std::isnan(p.fitness));
    if (!std::isnan(p.fitness)) {
      EXPECT_EQ(q.fitness, p.fitness);
    }
    EXPECT_EQ(q.clusters, p.clusters);
    EXPECT_EQ(q.timings.registration, p.timings.registration);
    EXPECT_EQ(q.timings.segmentation, p.timings.segmentation);
    EXPECT_EQ(q.timings.association, p.timings.association);
    EXPECT_EQ(q.timings.detection, p.timings.detection);
    EXPECT_EQ(q.timings.total, p.timings.total);
  }
}

TEST(ParseHealthReply, ReadsBothFormsOfHealth) {
  for (bool ok : {true, false}) {
    HealthView h;
    h.store_backend = "postgresql";
    h.store_ok = ok;
    h.store_message = ok ? "" : "connection refused";
    h.sessions_held = 17;
    auto back = ParseHealthReply(RenderHealth(h), kLimits);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    EXPECT_EQ(back->store_backend, h.store_backend);
    EXPECT_EQ(back->store_ok, h.store_ok);
    EXPECT_EQ(back->store_message, h.store_message);
    EXPECT_EQ(back->sessions_held, h.sessions_held);
    EXPECT_EQ(back->version, kVersion);
  }
  auto plain = ParseHealthReply(RenderHealth(), kLimits);
  ASSERT_TRUE(plain.ok()) << plain.status().ToString();
  EXPECT_TRUE(plain->store_ok);
  EXPECT_EQ(plain->store_backend, "memory");
  EXPECT_EQ(plain->version, kVersion);
  // A server that says it serves while its store is unavailable contradicts itself.
  auto contradiction = ParseHealthReply(
      R"({"status": "SERVING", "store": {"backend": "memory", "status": "UNAVAILABLE"}})", kLimits);
  EXPECT_EQ(contradiction.status().code(), StatusCode::kDataLoss);
  EXPECT_EQ(FieldOf(contradiction), "store.status");
}

TEST(ParseErrorReply, ReadsTheCanonicalCodeMessageAndViolations) {
  Status s = InvalidFieldError("budget.timeMs", "must be <= 60000");
  s.WithFieldViolation("budget.cpuMs", "must be <= 60000");
  const Status back = ParseErrorReply(400, RenderError(s), kLimits);
  EXPECT_EQ(back.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(back.message(), s.message());
  EXPECT_EQ(back.field_violations(), s.field_violations());
  // With a RetryInfo detail and another HTTP status.
  const Status busy =
      ParseErrorReply(429, RenderError(ResourceExhaustedError("planning queue full"), 0, 2));
  EXPECT_EQ(busy.code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(busy.message(), "planning queue full");
  EXPECT_TRUE(busy.field_violations().empty());
  for (int c = 1; c <= 16; ++c) {
    const auto code = static_cast<StatusCode>(c);
    EXPECT_EQ(ParseErrorReply(HttpStatusOf(code), RenderError(Status(code, "x"))).code(), code);
  }
  // What the API does not describe: a proxy's page, the odd error of a hostile server.
  const Status page = ParseErrorReply(502, "<html>Bad Gateway</html>");
  EXPECT_EQ(page.code(), StatusCode::kDataLoss);
  EXPECT_NE(page.message().find("HTTP 502"), std::string::npos) << page.message();
  const Status odd = ParseErrorReply(
      400, R"({"error": {"status": 5, "message": [1], "details": [{"fieldViolations": "x"}, 3]}})");
  EXPECT_EQ(odd.code(), StatusCode::kDataLoss);
  EXPECT_NE(odd.message().find("HTTP 400"), std::string::npos) << odd.message();
  EXPECT_EQ(ParseErrorReply(404, R"({"error": {"code": 404, "status": "OK", "message": "",
                                 "details": []}})")
                .code(),
            StatusCode::kDataLoss);
}

TEST(ParseAction, ReadsThePlanRepliesActions) {
  ActionView move;
  move.configuration = Config(1, -2, 0.5, 0.25, -0.5, 0.75);
  ActionView declare;
  declare.type = ActionView::Type::kDeclareObstacle;
  declare.object_id = "box-2";
  declare.object_box = object_search::Box{{1, 2, 0.8}, 0.5, {0.1, 0.2, 0.3}};
  ActionView remove;
  remove.type = ActionView::Type::kRemove;
  remove.object_id = "track-7";
  for (const ActionView& a : {move, declare, remove}) {
    auto back = ParseAction(internal::ActionJson(a).dump(), kLimits);
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ExpectSameAction(*back, a);
  }
  EXPECT_STREQ(ActionTypeName(ActionView::Type::kDeclareTarget), "DECLARE_TARGET");
  // Not an action of the API: a LOOK, a MOVE without its whole configuration, a declaration
  // without its object, an unknown member, not JSON.
  for (const char* text :
       {R"({"type": "LOOK"})", R"({"type": "MOVE", "configuration": {"x": 1}})",
        R"({"type": "REMOVE"})", R"({"type": "REMOVE", "objectId": "a", "why": 1})", "MOVE",
        R"({"type": "MOVE", "configuration": {"x": 1e999, "y": 0, "yaw": 0, "lift": 0,
             "pan": 0, "tilt": 0}})"}) {
    SCOPED_TRACE(text);
    auto r = ParseAction(text, kLimits);
    EXPECT_EQ(r.status().code(), StatusCode::kDataLoss);
    EXPECT_FALSE(r.status().field_violations().empty());
  }
}

// ---- hostile replies ----

TEST(HostileReplies, AreDataLossNamingTheField) {
  const json session = json::parse(RenderSession(FullSession()));
  // DATA_LOSS whose first field violation, also in the message, is `field` ("": any field).
  auto expect_loss = [](const Status& s, const std::string& field) {
    EXPECT_EQ(s.code(), StatusCode::kDataLoss) << s.ToString();
    ASSERT_FALSE(s.field_violations().empty()) << s.ToString();
    if (field.empty()) return;
    EXPECT_EQ(FieldOf(s), field) << s.ToString();
    EXPECT_NE(s.message().find(field), std::string::npos) << s.ToString();
  };
  // Not JSON, not an object, nested without end, more values than the limit.
  expect_loss(ParseSessionReply("not json", kLimits).status(), "body");
  expect_loss(ParseSessionReply("", kLimits).status(), "body");
  expect_loss(ParseSessionReply("[1, 2, 3]", kLimits).status(), "body");
  expect_loss(ParsePlanReply(std::string(200000, '[') + std::string(200000, ']'), kLimits).status(),
              "body");
  std::string many = R"({"x": [)";
  for (int i = 0; i < 200000; ++i) many += "0,";
  many += "0]}";
  expect_loss(ParseObserveReply(many, kLimits).status(), "body");
  // Wrong types (the hostile server's), missing fields.
  expect_loss(ParseSessionReply(R"({"id": 5, "planner": [1], "action": 7})", kLimits).status(), "");
  for (const char* field : {"robot", "planner", "seed", "createTime"}) {
    json j = session;
    j.erase(field);
    expect_loss(ParseSessionReply(j.dump(), kLimits).status(), field);
  }
  json j = session;
  j["robot"]["x"] = "far";
  expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "robot.x");
  // Numbers: beyond a double, beyond an int, beyond 2^64, not integral.
  std::string text = session.dump();
  text.replace(text.find("\"step\":3"), 8, "\"step\":1" + std::string(400, '0'));
  expect_loss(ParseSessionReply(text, kLimits).status(), "body");
  j = session;
  j["step"] = 3'000'000'000ll;
  expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "step");
  j = session;
  j["totalSimulations"] = 18446744073709551615ull;
  expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "totalSimulations");
  j = session;
  j["objectCount"] = 2.5;
  expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "objectCount");
  j = session;
  j["seed"] = "99999999999999999999999";
  expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "seed");
  // What the schema cannot say: times, the name of the id.
  for (const char* time : {"yesterday", "2026-02-30T00:00:00Z", "2026-01-01T00:00:00",
                           "2026-01-01T24:00:00Z", "2026-01-01T00:00:00.Z"}) {
    j = session;
    j["createTime"] = time;
    expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "createTime");
  }
  j = session;
  j["name"] = "sessions/ffffffffffffffffffffffffffffffff";
  expect_loss(ParseSessionReply(j.dump(), kLimits).status(), "name");
  // Inside a plan and an observe reply, the fields are named from the top.
  PlanReply plan;
  plan.session = FullSession();
  json p = json::parse(RenderPlan(plan));
  p["session"]["state"] = "LOST";
  expect_loss(ParsePlanReply(p.dump(), kLimits).status(), "session.state");
  p = json::parse(RenderPlan(plan));
  p["stats"]["maxDepth"] = 1ll << 40;
  expect_loss(ParsePlanReply(p.dump(), kLimits).status(), "stats.maxDepth");
  p = json::parse(RenderPlan(plan));
  p["summary"].erase("optionsUsed");
  expect_loss(ParsePlanReply(p.dump(), kLimits).status(), "summary.optionsUsed");
  ObserveReply observe;
  observe.session = FullSession();
  observe.perception = perception::PerceptionResult{};
  observe.perception->fitness = 1e-4;
  json o = json::parse(RenderObserve(observe));
  o["perception"]["fitness"] = nullptr;
  expect_loss(ParseObserveReply(o.dump(), kLimits).status(), "perception.fitness");
  o = json::parse(RenderObserve(observe));
  o["perception"]["detections"] = {{{"id", "x"}, {"box", 1}}};
  expect_loss(ParseObserveReply(o.dump(), kLimits).status(), "perception.detections[0].box");
  expect_loss(ParseHealthReply(R"({"status": "FINE"})", kLimits).status(), "status");
  expect_loss(ParseHealthReply(R"({"status": "SERVING", "sessionsHeld": -1})", kLimits).status(),
              "sessionsHeld");
}

}  // namespace
}  // namespace npfkct::api
