#include "npfkct/server/codec.h"

#include <gtest/gtest.h>

#include "npfkct/object_search/model.h"
#include "npfkct/server/api_error.h"
#include "npfkct/sim/scenario.h"

namespace npfkct::server {
namespace {

object_search::World Loose1() {
  auto s = sim::LoadScenario(std::string(NPFKCT_SCENARIO_DIR) + "/loose1.json");
  return sim::InitialWorld(*s).value();
}

TEST(CodecTest, WorldSnapshotRoundTripsExactly) {
  object_search::World w = Loose1();
  object_search::ObjectKnowledge o;
  o.key = "cluster-1";
  o.box.center = {1.5, 0.1, 0.8};
  o.box.size = {0.1, 0.2, 0.3};
  o.box.yaw = 0.25;
  o.odds = {0.5f, -1.25f, 2.0f, 0, 0, 0, 0, 3.5f};
  o.status = object_search::kDeclaredObstacle;
  w.objects.push_back(o);
  w.grid.set_log_odds(7, -2.5f);
  w.robot_config.tilt = 0.33;
  w.steps = 4;
  const json j = WorldToJson(w);
  auto back = WorldFromJson(json::parse(j.dump()));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(WorldToJson(*back), j);
  EXPECT_EQ(back->grid.all_log_odds(), w.grid.all_log_odds());
  EXPECT_EQ(back->occupancy.cells(), w.occupancy.cells());
  EXPECT_EQ(back->objects[1].odds, o.odds);
  EXPECT_EQ(back->robot_config, w.robot_config);
}

TEST(CodecTest, CorruptSnapshotsAreDataLossNotCrashes) {
  json j = WorldToJson(Loose1());
  json broken = j;
  broken.erase("grid");
  EXPECT_EQ(WorldFromJson(broken).status().code(), StatusCode::kDataLoss);
  broken = j;
  broken["occupancy"]["runs"] = json::array({-5});
  EXPECT_EQ(WorldFromJson(broken).status().code(), StatusCode::kDataLoss);
  broken = j;
  broken["objects"][0]["odds"] = json::array({1, 2});
  EXPECT_EQ(WorldFromJson(broken).status().code(), StatusCode::kDataLoss);
  broken = j;
  broken["grid"]["logOdds"] = json::array({1.0});
  EXPECT_FALSE(WorldFromJson(broken).ok());
}

TEST(CodecTest, ActionsAndObservationsNameTheField) {
  object_search::World w = Loose1();
  object_search::ObjectKnowledge o;
  o.key = "box";
  w.objects.push_back(o);
  auto a = ActionFromJson(json{{"type", "REMOVE"}, {"objectId", "box"}}, "action", w);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->kind, object_search::RemoveKind(1));
  const json box = {{"center", {0.0, 0.0, 0.0}}, {"size", {1.0, 1.0, 1.0}}, {"yaw", 0.0}};
  EXPECT_EQ(ActionToJson(*a, w),
            (json{{"type", "REMOVE"}, {"objectId", "box"}, {"objectBox", box}}));
  // The box the action carries is accepted back (clients echo actions).
  EXPECT_TRUE(ActionFromJson(ActionToJson(*a, w), "action", w).ok());
  EXPECT_NE(
      ActionFromJson(json{{"type", "JUMP"}}, "action", w).status().message().find("action.type"),
      std::string::npos);
  EXPECT_NE(ActionFromJson(json{{"type", "REMOVE"}, {"objectId", "nope"}}, "action", w)
                .status()
                .message()
                .find("action.objectId"),
            std::string::npos);

  json body = json::parse(R"({"robotState": {"x": 0, "y": 0, "yaw": 0, "lift": 0, "pan": 0,
      "tilt": 0.3}, "detections": [{"id": "c1", "box": {"center": [1, 0, 0.8],
      "size": [0.1, 0.1, 0.1]}, "faces": [{"corner": 2, "score": 0.9}]}]})");
  auto obs = ObservationFromJson(body, w, true);
  ASSERT_TRUE(obs.ok()) << obs.status().ToString();
  EXPECT_EQ(obs->objects[0].faces[0].corner, 2);
  struct Case {
    std::string pointer, value, field;
  };
  const std::vector<Case> cases = {
      {"/detections/0/faces/0/corner", "8", "detections[0].faces[0].corner"},
      {"/detections/0/faces/0/score", "1.5", "detections[0].faces[0].score"},
      {"/detections/0/box/size", "[0.1, 0.1]", "detections[0].box.size"},
      {"/detections/0/box/center", "[1e9, 0, 0]", "detections[0].box.center"},
      {"/detections/0/id", "\"\"", "detections[0].id"},
      {"/detections/0/moveability", "-1", "detections[0].moveability"},
      {"/robotState/tilt", "\"up\"", "robotState.tilt"},
      {"/detections", "{}", "detections"},
  };
  for (const Case& c : cases) {
    json bad = body;
    bad[json::json_pointer(c.pointer)] = json::parse(c.value);
    auto r = ObservationFromJson(bad, w, true);
    ASSERT_FALSE(r.ok()) << c.pointer;
    EXPECT_EQ(ApiError::From(r.status()).field, c.field) << r.status().message();
  }
  json no_state = body;
  no_state.erase("robotState");
  EXPECT_EQ(ApiError::From(ObservationFromJson(no_state, w, true).status()).field, "robotState");
  EXPECT_TRUE(ObservationFromJson(no_state, w, false).ok());
}

TEST(CodecTest, ErrorBodiesFollowGoogleApiConventions) {
  const json j = json::parse(ErrorBody(
      ApiError::From(InvalidArgumentError("world.furniture[0].size: expected 3 numbers"))));
  EXPECT_EQ(j["error"]["code"], 400);
  EXPECT_EQ(j["error"]["status"], "INVALID_ARGUMENT");
  EXPECT_EQ(j["error"]["details"][0]["fieldViolations"][0]["field"], "world.furniture[0].size");
  EXPECT_EQ(j["error"]["details"][0]["fieldViolations"][0]["description"], "expected 3 numbers");
  EXPECT_EQ(HttpStatusOf(StatusCode::kFailedPrecondition), 400);
  EXPECT_EQ(HttpStatusOf(StatusCode::kNotFound), 404);
  EXPECT_EQ(HttpStatusOf(StatusCode::kUnauthenticated), 401);
  EXPECT_EQ(SnakeCase("search.maxDepth"), "search.max_depth");
  EXPECT_EQ(SnakeCase("w1Bar"), "w1_bar");
  EXPECT_EQ(SnakeCase("cR"), "c_r");
}

}  // namespace
}  // namespace npfkct::server
