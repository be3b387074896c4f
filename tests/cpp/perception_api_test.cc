// Raw sensor data through :observe: frames rendered by the simulator go through the server's
// perception pipeline over real HTTP, bad frames get errors naming the field and change nothing,
// and the perception tracks survive a restart.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "npfkct/api/client_codec.h"
#include "npfkct/api/wire.h"
#include "npfkct/perception/perception.h"
#include "npfkct/sim/api_robot.h"
#include "npfkct/sim/frame_io.h"
#include "server_fixture.h"

namespace npfkct::server {
namespace {

sim::Scenario Loose1() {
  return sim::LoadScenario(std::string(NPFKCT_SCENARIO_DIR) + "/loose1.json").value();
}

std::string Png(const cv::Mat& image, const std::string& ext = ".png") {
  std::vector<uchar> bytes;
  cv::imencode(ext, image, bytes);
  return api::Base64Encode(std::string(bytes.begin(), bytes.end()));
}

class PerceptionApiTest : public ServerTest {
 protected:
  // A session on Loose1 whose target photos come from the simulated scene.
  std::string CreateWithPhotos(const sim::ApiRobot& robot) {
    json photos = json::array();
    for (const std::string& png : robot.TargetPhotos()) photos.push_back(api::Base64Encode(png));
    return Create({{"target", {{"description", "the patterned box"}, {"photos", photos}}}});
  }
  // The robot's raw observation as the body it sends.
  static json Body(const api::ObserveRequest& observation) {
    return json::parse(api::EncodeObserve(observation).value());
  }
  // Plans, executes in the simulator and returns the raw observation with its actionId.
  json PlanAndExecute(const std::string& base, sim::ApiRobot* robot, bool* terminal = nullptr) {
    Reply plan = Post(base + ":plan", {{"budget", {{"simulations", 300}}}});
    EXPECT_EQ(plan.status, 200) << plan.raw;
    const auto outcome = robot->Execute(api::ParseAction(plan.body["action"].dump()).value());
    if (terminal != nullptr) *terminal = outcome.terminal;
    json observation = Body(robot->ObserveRaw(!outcome.illegal));
    observation["actionId"] = plan.body["actionId"];
    return observation;
  }
};

TEST_F(PerceptionApiTest, RenderedFramesDriveAnEpisodeThroughPerception) {
  Start();
  sim::ApiRobot robot(Loose1(), 2);
  const std::string id = CreateWithPhotos(robot);
  const std::string base = "/v1/sessions/" + id;
  EXPECT_EQ(Get(base).body["target"]["photoCount"], 4);
  std::set<std::string> ids;
  int registered = 0, frames = 0;
  bool done = false;
  for (int step = 0; step < 25 && !done; ++step) {
    bool terminal = false;
    const json observation = PlanAndExecute(base, &robot, &terminal);
    Reply r = Post(base + ":observe", observation);
    ASSERT_EQ(r.status, 200) << r.raw.substr(0, 400);
    done = r.body["done"];
    EXPECT_EQ(done, terminal);
    if (!observation.contains("pointCloud")) continue;
    ++frames;
    const json& p = r.body["perception"];
    ASSERT_TRUE(p.is_object()) << r.raw.substr(0, 400);
    registered += p["registration"] != "SKIPPED";
    EXPECT_GE(p["timingsMs"]["total"].get<double>(), 0.0);
    for (const json& d : p["detections"]) {
      ids.insert(d["id"].get<std::string>());
      // Every perception id names an object the session now knows.
      const json belief = Get(base + "/belief").body;
      bool known = false;
      for (const json& o : belief["objects"]) known |= o["id"] == d["id"];
      EXPECT_TRUE(known) << d["id"];
    }
    // The corrected pose is where the session believes the robot is.
    EXPECT_EQ(r.body["session"]["robot"], p["robotState"]);
  }
  EXPECT_GT(frames, 0);
  EXPECT_GT(registered, 0);
  EXPECT_GE(ids.size(), 2u);
  EXPECT_TRUE(done) << "the target was not removed within 25 steps";
}

TEST_F(PerceptionApiTest, BadFramesGetErrorsNamingTheFieldAndChangeNothing) {
  Start();
  sim::ApiRobot robot(Loose1(), 3);
  const std::string id = CreateWithPhotos(robot);
  const std::string base = "/v1/sessions/" + id;
  // A first frame so that the pipeline has tracks to protect.
  json first = PlanAndExecute(base, &robot);
  ASSERT_TRUE(first.contains("pointCloud"));
  ASSERT_EQ(Post(base + ":observe", first).status, 200);
  json good = PlanAndExecute(base, &robot);
  for (int tries = 0; tries < 10 && !good.contains("pointCloud"); ++tries) {
    ASSERT_EQ(Post(base + ":observe", good).status, 200);  // the camera saw nothing: retry
    good = PlanAndExecute(base, &robot);
  }
  ASSERT_TRUE(good.contains("pointCloud"));
  const json before = Get(base).body;
  const json belief_before = Get(base + "/belief").body;

  // Clouds: a NaN point, a cloud in the map frame sent as the camera's, broken base64.
  const std::string bytes =
      api::Base64Decode(good["pointCloud"]["data"].get<std::string>(), "data").value();
  auto cloud = api::DecodeCloud(bytes, "xyzrgb", 1'000'000, 1e4, "pointCloud").value();
  auto encode = [](const perception::Cloud& c) { return api::Base64Encode(api::EncodeCloud(c)); };
  auto with_nan = *cloud;
  with_nan[10].y = std::numeric_limits<float>::quiet_NaN();
  const sim::Frame frame = robot.simulator().Render(640, 480);
  const auto in_map = sim::FrameCloud(frame, /*world_frame=*/true);
  cv::Mat small(16, 16, CV_8UC3, cv::Scalar(10, 20, 30));

  struct Case {
    std::string what;
    std::function<void(json*)> edit;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"raw data with detections", [](json* b) { (*b)["detections"] = json::array(); },
       "detections"},
      {"an image alone", [](json* b) { b->erase("pointCloud"); }, "pointCloud"},
      {"an empty cloud", [](json* b) { (*b)["pointCloud"]["data"] = ""; }, "pointCloud.data"},
      {"a NaN point", [&](json* b) { (*b)["pointCloud"]["data"] = encode(with_nan); },
       "pointCloud.data"},
      {"a map-frame cloud sent as the camera's",
       [&](json* b) { (*b)["pointCloud"]["data"] = encode(*in_map); }, "pointCloud.frame"},
      {"an unknown frame", [](json* b) { (*b)["pointCloud"]["frame"] = "base_link"; },
       "pointCloud.frame"},
      {"unknown fields", [](json* b) { (*b)["pointCloud"]["fields"] = "xyzi"; },
       "pointCloud.fields"},
      {"broken base64", [](json* b) { (*b)["pointCloud"]["data"] = "@@@@"; }, "pointCloud.data"},
      {"a cloud that is not whole points",
       [](json* b) { (*b)["pointCloud"]["data"] = api::Base64Encode("1234567"); },
       "pointCloud.data"},
      {"an image of the wrong size", [&](json* b) { (*b)["image"]["data"] = Png(small); },
       "image.data"},
      {"an image in BMP", [&](json* b) { (*b)["image"]["data"] = Png(small, ".bmp"); },
       "image.data"},
      {"an unknown encoding", [](json* b) { (*b)["image"]["encoding"] = "gif"; }, "image.encoding"},
      {"a negative focal length", [](json* b) { (*b)["camera"]["fx"] = -1; }, "camera.fx"},
      {"huge finite coordinates",
       [&](json* b) {
         auto far = *cloud;
         for (int i = 0; i < 3; ++i) far[i].z = 3e38f;
         (*b)["pointCloud"]["data"] = encode(far);
       },
       "pointCloud.data"},
      {"a camera of 4096 x 4096 pixels",
       [](json* b) { (*b)["camera"]["width"] = (*b)["camera"]["height"] = 4096; }, "camera"},
      {"a fractional width", [](json* b) { (*b)["camera"]["width"] = 640.5; }, "camera.width"},
      {"a semantic score out of range",
       [](json* b) {
         (*b)["semanticScores"] = {{"obj-0", 1.5}};
       },
       "semanticScores.obj-0"},
  };
  for (const Case& c : cases) {
    json body = good;
    c.edit(&body);
    Reply r = Post(base + ":observe", body);
    EXPECT_EQ(r.status, 400) << c.what;
    EXPECT_EQ(r.body["error"]["status"], "INVALID_ARGUMENT") << c.what;
    const std::string message = r.body["error"]["message"];
    EXPECT_EQ(message.rfind(c.field, 0), 0u) << c.what << ": " << message;
    // The field travels as data too.
    EXPECT_EQ(r.body["error"]["details"][0]["fieldViolations"][0]["field"], c.field) << c.what;
  }
  // Nothing changed: same state, same belief, same tracks; the good frame still applies.
  Reply after = Get(base);
  EXPECT_EQ(after.body["state"], "ACTION_PENDING");
  EXPECT_EQ(after.body["step"], before["step"]);
  EXPECT_EQ(after.body["perceptionTracks"], before["perceptionTracks"]);
  EXPECT_EQ(Get(base + "/belief").body, belief_before);
  Reply ok = Post(base + ":observe", good);
  EXPECT_EQ(ok.status, 200) << ok.raw.substr(0, 300);

  // Photos are checked at creation.
  Reply bad = Post("/v1/sessions", {{"world", WorldOf("loose1")},
                                    {"target", {{"photos", {Png(small), "not an image"}}}}});
  EXPECT_EQ(bad.status, 400);
  EXPECT_EQ(std::string(bad.body["error"]["message"]).rfind("target.photos[1]", 0), 0u) << bad.raw;
}

// The robot's own detector: depth plus 2D boxes of the target's class (imageBoxes), no photos
// and no image. The boxes score the objects; the reply says which object each box went to.
TEST_F(PerceptionApiTest, DetectorBoxesDriveAnEpisode) {
  Start();
  sim::ApiRobot robot(Loose1(), 5);
  const std::string base = "/v1/sessions/" + Create(json::object());
  bool done = false;
  int boxed_frames = 0;
  std::string declared;
  std::map<std::string, int> boxes_per_object;
  for (int step = 0; step < 25 && !done; ++step) {
    Reply plan = Post(base + ":plan", {{"budget", {{"simulations", 300}}}});
    ASSERT_EQ(plan.status, 200) << plan.raw;
    const auto action = api::ParseAction(plan.body["action"].dump()).value();
    if (action.type == api::ActionView::Type::kDeclareTarget) declared = action.object_id;
    const auto outcome = robot.Execute(action);
    json observation = Body(robot.ObserveBoxes(!outcome.illegal));
    observation["actionId"] = plan.body["actionId"];
    Reply r = Post(base + ":observe", observation);
    ASSERT_EQ(r.status, 200) << r.raw.substr(0, 400);
    done = r.body["done"];
    EXPECT_EQ(done, outcome.terminal);
    if (!observation.contains("pointCloud")) continue;
    EXPECT_FALSE(observation.contains("image"));
    const json& p = r.body["perception"];
    const json& boxes = observation["imageBoxes"];
    if (boxes.empty()) {
      EXPECT_FALSE(p.contains("boxObjects"));
      continue;
    }
    ++boxed_frames;
    ASSERT_EQ(p["boxObjects"].size(), boxes.size()) << r.raw.substr(0, 400);
    std::set<std::string> detected;
    for (const json& d : p["detections"]) detected.insert(d["id"].get<std::string>());
    for (const json& id : p["boxObjects"]) {
      if (id.is_null()) continue;
      EXPECT_TRUE(detected.count(id.get<std::string>())) << id;  // an object of this frame
      ++boxes_per_object[id.get<std::string>()];
    }
  }
  EXPECT_TRUE(done) << "the target was not removed within 25 steps";
  EXPECT_GT(boxed_frames, 0);
  // The object the robot declared the target is the one the detector's boxes went to most.
  ASSERT_FALSE(boxes_per_object.empty());
  const auto most = std::max_element(boxes_per_object.begin(), boxes_per_object.end(),
                                     [](auto& a, auto& b) { return a.second < b.second; });
  EXPECT_EQ(declared, most->first);
}

TEST_F(PerceptionApiTest, BadDetectorBoxesGetErrorsNamingTheField) {
  Start();
  sim::ApiRobot robot(Loose1(), 6);
  const std::string base = "/v1/sessions/" + Create(json::object());
  json good;
  for (int tries = 0; tries < 10; ++tries) {
    Reply plan = Post(base + ":plan", {{"budget", {{"simulations", 100}}}});
    ASSERT_EQ(plan.status, 200) << plan.raw;
    const auto outcome = robot.Execute(api::ParseAction(plan.body["action"].dump()).value());
    good = Body(robot.ObserveBoxes(!outcome.illegal));
    good["actionId"] = plan.body["actionId"];
    if (good.contains("pointCloud")) break;
    ASSERT_EQ(Post(base + ":observe", good).status, 200);  // the camera saw nothing: retry
  }
  ASSERT_TRUE(good.contains("pointCloud"));
  good["imageBoxes"] =
      json::array({{{"x", 100}, {"y", 80}, {"width", 50}, {"height", 40}, {"score", 0.9}}});
  const json before = Get(base).body;
  const json box = good["imageBoxes"][0];
  auto with_box = [&](const std::string& key, json value) {
    return [=](json* b) { (*b)["imageBoxes"][0][key] = value; };
  };
  struct Case {
    std::string what;
    std::function<void(json*)> edit;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"a box past the right edge", with_box("x", 600), "imageBoxes[0].x"},
      {"a box past the bottom edge", with_box("height", 401), "imageBoxes[0].y"},
      {"a box left of the image", with_box("x", -1), "imageBoxes[0].x"},
      {"a box of no width", with_box("width", 0), "imageBoxes[0].width"},
      {"a score above 1", with_box("score", 1.5), "imageBoxes[0].score"},
      {"a NaN score, as a string", with_box("score", "NaN"), "imageBoxes[0].score"},
      {"a box without its score", [](json* b) { (*b)["imageBoxes"][0].erase("score"); },
       "imageBoxes[0].score"},
      {"an unknown member", with_box("label", "cup"), "imageBoxes[0].label"},
      {"thousands of boxes",
       [&](json* b) {
         (*b)["imageBoxes"] = json::array();
         for (int i = 0; i < 5000; ++i) (*b)["imageBoxes"].push_back(box);
       },
       "imageBoxes"},
      {"boxes without depth",
       [](json* b) {
         b->erase("pointCloud");
         b->erase("camera");
       },
       "pointCloud"},
  };
  for (const Case& c : cases) {
    json body = good;
    c.edit(&body);
    Reply r = Post(base + ":observe", body);
    EXPECT_EQ(r.status, 400) << c.what << ": " << r.raw.substr(0, 300);
    const std::string message = r.body["error"]["message"];
    EXPECT_EQ(message.rfind(c.field, 0), 0u) << c.what << ": " << message;
    EXPECT_EQ(r.body["error"]["details"][0]["fieldViolations"][0]["field"], c.field) << c.what;
  }
  const json after = Get(base).body;
  EXPECT_EQ(after["step"], before["step"]);
  EXPECT_EQ(after.value("perceptionTracks", json()), before.value("perceptionTracks", json()));
  // 256 boxes, all on the same place, are what the API allows: the frame applies.
  json many = good;
  many["imageBoxes"] = json::array();
  for (int i = 0; i < 256; ++i) many["imageBoxes"].push_back(box);
  Reply ok = Post(base + ":observe", many);
  ASSERT_EQ(ok.status, 200) << ok.raw.substr(0, 300);
  ASSERT_EQ(ok.body["perception"]["boxObjects"].size(), 256u);
  // Boxes on the same pixels go to the same object, or all to none.
  const json first = ok.body["perception"]["boxObjects"][0];
  for (const json& id : ok.body["perception"]["boxObjects"]) EXPECT_EQ(id, first);
}

TEST_F(PerceptionApiTest, TracksSurviveARestart) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("npfkct-perc-" + std::to_string(getpid())))
          .string();
  std::filesystem::remove_all(dir);
  ServerOptions o;
  o.state_dir = dir;
  Start(o);
  sim::ApiRobot robot(Loose1(), 4);
  const std::string id = CreateWithPhotos(robot);
  const std::string base = "/v1/sessions/" + id;
  // Observe until perception has seen objects.
  json last;
  for (int step = 0; step < 10; ++step) {
    const json observation = PlanAndExecute(base, &robot);
    Reply r = Post(base + ":observe", observation);
    ASSERT_EQ(r.status, 200);
    if (r.body.contains("perception") && !r.body["perception"]["detections"].empty()) {
      last = r.body["perception"];
      break;
    }
  }
  ASSERT_FALSE(last.is_null());
  const json tracks = Get(base).body["perceptionTracks"];
  server_->Stop();

  Start(o);
  EXPECT_EQ(Get(base).body["perceptionTracks"], tracks);
  // The same view again (a LOOK in place): the objects keep their ids.
  Reply plan = Post(base + ":plan", {{"budget", {{"simulations", 100}}}});
  ASSERT_EQ(plan.status, 200);
  // Whatever the plan was, the robot did not do it (succeeded: false) and looked again.
  json look = Body(robot.ObserveRaw(false));
  look["actionId"] = plan.body["actionId"];
  Reply r = Post(base + ":observe", look);
  ASSERT_EQ(r.status, 200) << r.raw.substr(0, 300);
  std::set<std::string> before_ids, after_ids;
  for (const json& d : last["detections"]) before_ids.insert(d["id"]);
  for (const json& d : r.body["perception"]["detections"]) after_ids.insert(d["id"]);
  EXPECT_EQ(after_ids, before_ids);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace npfkct::server
