#include "npfkct/sim/api_robot.h"

#include "npfkct/api/wire.h"
#include "npfkct/sim/frame_io.h"

namespace npfkct::sim {

using nlohmann::json;

ApiRobot::ApiRobot(Scenario scenario, uint64_t seed)
    : sim_(std::move(scenario), seed), rng_(seed * 7919 + 1) {}

ExecutionOutcome ApiRobot::Execute(const json& action) {
  const auto& params = sim_.scenario().params;
  ExecutionOutcome outcome;
  outcome.success = true;
  outcome.detail = "looked";
  auto malformed = [&](const std::string& why) {
    outcome = ExecutionOutcome{};
    outcome.reward = object_search::RewardOf(params, object_search::ActionOutcome::kIllegal);
    outcome.illegal = true;
    outcome.detail = why;
    return outcome;
  };
  if (!action.is_object() || !action.contains("type") || !action["type"].is_string()) {
    return malformed("malformed action");
  }
  const std::string type = action["type"];
  if (type == "LOOK") return outcome;
  if (type == "MOVE") {
    if (!action.contains("configuration") || !action["configuration"].is_object()) {
      return malformed("MOVE without configuration");
    }
    const json& c = action["configuration"];
    RobotConfig rc;
    double* fields[] = {&rc.x, &rc.y, &rc.yaw, &rc.lift, &rc.pan, &rc.tilt};
    const char* names[] = {"x", "y", "yaw", "lift", "pan", "tilt"};
    for (int i = 0; i < 6; ++i) {
      if (!c.contains(names[i]) || !c[names[i]].is_number()) return malformed("bad configuration");
      *fields[i] = c[names[i]].get<double>();
    }
    return sim_.ExecuteMove(rc, params, rng_);
  }
  int offset = -1;
  if (type == "DECLARE_TARGET") offset = 0;
  if (type == "DECLARE_OBSTACLE") offset = 1;
  if (type == "REMOVE") offset = 2;
  if (offset < 0 || !action.contains("objectId") || !action["objectId"].is_string()) {
    return malformed("unknown action");
  }
  const std::string id = action["objectId"];
  const auto it = declared_.find(id);
  const int8_t status =
      it == declared_.end() ? static_cast<int8_t>(object_search::kUpdating) : it->second;
  // Where the server believes the object is (ids from perception name no scene object).
  Box seen;
  bool has_box = false;
  if (action.contains("objectBox") && action["objectBox"].is_object()) {
    const json& b = action["objectBox"];
    if (b.contains("center") && b["center"].is_array() && b["center"].size() == 3 &&
        b["center"][0].is_number() && b["center"][1].is_number() && b["center"][2].is_number()) {
      seen.center = Vec3(b["center"][0].get<double>(), b["center"][1].get<double>(),
                         b["center"][2].get<double>());
      has_box = true;
    }
  }
  outcome = sim_.ExecuteOnObject(offset, id, status, params, has_box ? &seen : nullptr);
  if (outcome.success && offset < 2) {
    declared_[id] = offset == 0 ? object_search::kDeclaredTarget : object_search::kDeclaredObstacle;
  }
  return outcome;
}

json ApiRobot::Observe(bool succeeded) {
  const auto obs = sim_.Observe(rng_);
  return {{"succeeded", succeeded},
          {"robotState", RobotConfigJson(obs.achieved)},
          {"detections", DetectionsJson(obs)}};
}

json ApiRobot::ObserveRaw(bool succeeded, int width, int height) {
  const Frame frame = sim_.Render(width, height);
  RobotConfig reported = sim_.robot();
  const SimNoise& noise = sim_.scenario().noise;
  reported.x += noise.localization_xy * rng_.Normal();
  reported.y += noise.localization_xy * rng_.Normal();
  reported.yaw = object_search::WrapAngle(reported.yaw + noise.localization_yaw * rng_.Normal());
  // Pixels without a return carry no point (as a driver drops NaNs before sending).
  const auto cloud = FrameCloud(frame, /*world_frame=*/false);
  if (cloud->empty()) {
    // Nothing within the sensor's range: the API wants no cloud rather than an empty one.
    return {{"succeeded", succeeded}, {"robotState", RobotConfigJson(reported)}};
  }
  const std::string png = api::EncodePng(FrameBgr(frame)).value();
  return {{"succeeded", succeeded},
          {"robotState", RobotConfigJson(reported)},
          {"pointCloud",
           {{"frame", "camera"},
            {"fields", "xyzrgb"},
            {"data", api::Base64Encode(api::EncodeCloud(*cloud))}}},
          {"image", {{"encoding", "png"}, {"data", api::Base64Encode(png)}}},
          {"camera",
           {{"width", frame.width},
            {"height", frame.height},
            {"fx", frame.fx},
            {"fy", frame.fy},
            {"cx", frame.cx},
            {"cy", frame.cy}}}};
}

json ApiRobot::TargetPhotosJson() const {
  json out = json::array();
  for (const cv::Mat& photo : ObjectPhotos(sim_.objects()[sim_.target_index()])) {
    out.push_back(api::Base64Encode(api::EncodePng(photo).value()));
  }
  return out;
}

json RobotConfigJson(const RobotConfig& c) {
  return {{"x", c.x},       {"y", c.y},     {"yaw", c.yaw},
          {"lift", c.lift}, {"pan", c.pan}, {"tilt", c.tilt}};
}

json DetectionsJson(const object_search::RealObservation& obs) {
  json out = json::array();
  for (const auto& d : obs.objects) {
    json faces = json::array();
    for (const auto& f : d.faces) faces.push_back({{"corner", f.corner}, {"score", f.score}});
    out.push_back({{"id", d.key},
                   {"box",
                    {{"center", {d.box.center.x(), d.box.center.y(), d.box.center.z()}},
                     {"yaw", d.box.yaw},
                     {"size", {d.box.size.x(), d.box.size.y(), d.box.size.z()}}}},
                   {"moveability", d.moveability},
                   {"faces", faces}});
  }
  return out;
}

json WorldJsonOf(const json& scenario) {
  json world;
  for (const char* key : {"robot", "room", "mapResolution", "furniture", "baseRegions",
                          "discretePoses", "start", "params"}) {
    if (scenario.contains(key)) world[key] = scenario[key];
  }
  return world;
}

}  // namespace npfkct::sim
