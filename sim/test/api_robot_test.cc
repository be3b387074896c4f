// The simulated robot as a client of the API: the world it tells the server, the actions it
// takes and the observations it sends are the API's typed requests, which the server reads.
#include "npfkct/sim/api_robot.h"

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "npfkct/api/api.h"
#include "npfkct/api/client_codec.h"

namespace npfkct::sim {
namespace {

using nlohmann::json;

constexpr const char* kScenarios[] = {"complex1", "covered1", "fig16",
                                      "hidden1",  "loose1",   "loose2"};

std::string Path(const std::string& name) {
  return std::string(NPFKCT_SCENARIO_DIR) + "/" + name + ".json";
}

std::string ReadFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

TEST(ApiRobotTest, ThePriorIsTheWorldOfTheScenarioFile) {
  const api::Limits limits;
  for (const char* name : kScenarios) {
    SCOPED_TRACE(name);
    const Scenario scenario = LoadScenario(Path(name)).value();
    // The world as npfkct-drive sent it before it was typed: the scenario file's world members as
    // they stand in the file.
    const json file = json::parse(ReadFile(Path(name)));
    json part = json::object();
    for (const char* key : {"robot", "room", "mapResolution", "furniture", "baseRegions",
                            "discretePoses", "start", "params"}) {
      if (file.contains(key)) part[key] = file[key];
    }
    auto as_file = api::ParseCreateSession(json({{"world", part}}).dump(), limits);
    ASSERT_TRUE(as_file.ok()) << as_file.status().ToString();
    // The world as it goes now: the scenario's prior map, through the API's encoder.
    api::CreateSessionRequest create;
    create.world = scenario.Prior();
    auto as_prior = api::ParseCreateSession(api::EncodeCreateSession(create), limits);
    ASSERT_TRUE(as_prior.ok()) << as_prior.status().ToString();
    // The server reads the same world from both (the encoding covers every field it reads).
    EXPECT_EQ(api::EncodeWorldSpec(as_prior->world), api::EncodeWorldSpec(as_file->world));
    // The API's reader of world specs takes the scenario file as its world part (and reads
    // fig16's -0.0 as 0, as the server does).
    auto read = api::ParseWorldSpec(ReadFile(Path(name)), limits);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    auto prior = api::ParseWorldSpec(api::EncodeWorldSpec(scenario.Prior()), limits);
    ASSERT_TRUE(prior.ok()) << prior.status().ToString();
    EXPECT_EQ(api::EncodeWorldSpec(*read), api::EncodeWorldSpec(*prior));
  }
}

TEST(ApiRobotTest, ObservationsAreRequestsTheServerReads) {
  const Scenario scenario = LoadScenario(Path("loose1")).value();
  ApiRobot robot(scenario, 3);
  ApiRobot twin(scenario, 3);
  // The plan reply's action, as npfkct-sim-robot reads it from a line: to the first discrete
  // pose, the head tilted down.
  const RobotConfig& pose = scenario.discrete_poses.at(0);
  auto move = api::ParseAction(json({{"type", "MOVE"},
                                     {"configuration",
                                      {{"x", pose.x},
                                       {"y", pose.y},
                                       {"yaw", pose.yaw},
                                       {"lift", 0.2},
                                       {"pan", 0.0},
                                       {"tilt", 0.4}}}})
                                   .dump());
  ASSERT_TRUE(move.ok()) << move.status().ToString();
  for (ApiRobot* r : {&robot, &twin}) EXPECT_FALSE(r->Execute(*move).illegal);
  for (bool raw : {false, true}) {
    api::ObserveRequest observation = raw ? robot.ObserveRaw(true, 160, 120) : robot.Observe(true);
    // The same seed draws the same observation.
    EXPECT_EQ(
        api::EncodeObserve(observation).value(),
        api::EncodeObserve(raw ? twin.ObserveRaw(true, 160, 120) : twin.Observe(true)).value());
    observation.action_id = "a1-000001";
    auto back = api::ParseObserve(api::EncodeObserve(observation).value(), api::Limits());
    ASSERT_TRUE(back.ok()) << back.status().ToString();
    ASSERT_TRUE(back->robot_state);
    EXPECT_EQ(back->frame.has_value(), raw);
    if (raw) {
      EXPECT_EQ(back->frame->cloud->size(), observation.frame->cloud->size());
    } else {
      EXPECT_EQ(back->detections.size(), observation.detections.size());
    }
  }
  // A declaration of what the robot never saw is illegal in the true world; a line that is no
  // action is refused as illegal, with the reason.
  api::ActionView remove;
  remove.type = api::ActionView::Type::kRemove;
  remove.object_id = "nothing-here";
  EXPECT_TRUE(robot.Execute(remove).illegal);
  const ExecutionOutcome refused = robot.Refuse("malformed action");
  EXPECT_TRUE(refused.illegal);
  EXPECT_EQ(refused.reward, scenario.params.r_ill);
  EXPECT_FALSE(robot.Look().illegal);
  // The target's photos are PNGs.
  const std::vector<std::string> photos = robot.TargetPhotos();
  ASSERT_FALSE(photos.empty());
  for (const std::string& png : photos) EXPECT_EQ(png.substr(1, 3), "PNG");
}

}  // namespace
}  // namespace npfkct::sim
