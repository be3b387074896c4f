#include "npfkct/sim/api_robot.h"

#include <algorithm>

#include "npfkct/api/wire.h"
#include "npfkct/sim/frame_io.h"

namespace npfkct::sim {

ApiRobot::ApiRobot(Scenario scenario, uint64_t seed)
    : sim_(std::move(scenario), seed), rng_(seed * 7919 + 1) {}

std::vector<perception::ImageBox> DetectorBoxes(const Simulator& sim, const Frame& frame,
                                                Rng& rng) {
  const SimNoise& noise = sim.scenario().noise;
  // The pixels each scene object shows (the rendered ids), as a detector sees them.
  const size_t n = sim.objects().size();
  const int width = frame.width, height = frame.height;
  std::vector<int> u0(n, width), v0(n, height), u1(n, -1), v1(n, -1), pixels(n, 0);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const int id = frame.ids[static_cast<size_t>(v) * width + u];
      if (id < 0 || id >= static_cast<int>(n)) continue;
      u0[id] = std::min(u0[id], u);
      v0[id] = std::min(v0[id], v);
      u1[id] = std::max(u1[id], u);
      v1[id] = std::max(v1[id], v);
      ++pixels[id];
    }
  }
  constexpr int kMinBoxPixels = 100;  // fewer: too small for the detector to box
  std::vector<perception::ImageBox> boxes;
  for (size_t i = 0; i < n; ++i) {
    if (pixels[i] < kMinBoxPixels) continue;
    // It fires on the target unless it misses, on another object when it errs.
    if (rng.Bernoulli(noise.false_detection) == sim.objects()[i].target) continue;
    const double score = std::clamp(0.85 + noise.detection * rng.Normal(), 0.5, 0.99);
    boxes.push_back({1.0 * u0[i], 1.0 * v0[i], u1[i] - u0[i] + 1.0, v1[i] - v0[i] + 1.0, score});
  }
  return boxes;
}

ExecutionOutcome ApiRobot::Execute(const api::ActionView& action) {
  const auto& params = sim_.scenario().params;
  if (action.type == api::ActionView::Type::kMove) {
    return sim_.ExecuteMove(action.configuration, params, rng_);
  }
  const int offset = action.type == api::ActionView::Type::kDeclareTarget     ? 0
                     : action.type == api::ActionView::Type::kDeclareObstacle ? 1
                                                                              : 2;
  const std::string& id = action.object_id;
  const auto it = declared_.find(id);
  const int8_t status =
      it == declared_.end() ? static_cast<int8_t>(object_search::kUpdating) : it->second;
  // Where the server believes the object is (ids from perception name no scene object).
  Box seen;
  if (action.object_box) seen.center = action.object_box->center;
  ExecutionOutcome outcome =
      sim_.ExecuteOnObject(offset, id, status, params, action.object_box ? &seen : nullptr);
  if (outcome.success && offset < 2) {
    declared_[id] = offset == 0 ? object_search::kDeclaredTarget : object_search::kDeclaredObstacle;
  }
  return outcome;
}

ExecutionOutcome ApiRobot::Look() const {
  ExecutionOutcome outcome;
  outcome.success = true;
  outcome.detail = "looked";
  return outcome;
}

ExecutionOutcome ApiRobot::Refuse(const std::string& why) const {
  ExecutionOutcome outcome;
  outcome.reward =
      object_search::RewardOf(sim_.scenario().params, object_search::ActionOutcome::kIllegal);
  outcome.illegal = true;
  outcome.detail = why;
  return outcome;
}

api::ObserveRequest ApiRobot::Observe(bool succeeded) {
  object_search::RealObservation obs = sim_.Observe(rng_);
  api::ObserveRequest out;
  out.succeeded = succeeded;
  out.robot_state = obs.achieved;
  out.detections = std::move(obs.objects);
  return out;
}

api::ObserveRequest ApiRobot::ObserveRaw(bool succeeded, int width, int height) {
  return ObserveRaw(succeeded, sim_.Render(width, height));
}

api::ObserveRequest ApiRobot::ObserveRaw(bool succeeded, const Frame& frame) {
  RobotConfig reported = sim_.robot();
  const SimNoise& noise = sim_.scenario().noise;
  reported.x += noise.localization_xy * rng_.Normal();
  reported.y += noise.localization_xy * rng_.Normal();
  reported.yaw = object_search::WrapAngle(reported.yaw + noise.localization_yaw * rng_.Normal());
  api::ObserveRequest out;
  out.succeeded = succeeded;
  out.robot_state = reported;
  // Pixels without a return carry no point (as a driver drops NaNs before sending).
  auto cloud = FrameCloud(frame, /*world_frame=*/false);
  // Nothing within the sensor's range: the API wants no cloud rather than an empty one.
  if (cloud->empty()) return out;
  perception::SensorFrame raw;
  raw.cloud = std::move(cloud);
  raw.image = FrameBgr(frame);
  raw.intrinsics.width = frame.width;
  raw.intrinsics.height = frame.height;
  raw.intrinsics.fx = frame.fx;
  raw.intrinsics.fy = frame.fy;
  raw.intrinsics.cx = frame.cx;
  raw.intrinsics.cy = frame.cy;
  out.frame = std::move(raw);
  return out;
}

api::ObserveRequest ApiRobot::ObserveBoxes(bool succeeded, int width, int height) {
  const Frame frame = sim_.Render(width, height);
  api::ObserveRequest out = ObserveRaw(succeeded, frame);
  if (!out.frame) return out;
  out.frame->image = cv::Mat();  // depth and boxes: the detector ran on the image
  out.frame->image_boxes = DetectorBoxes(sim_, frame, rng_);
  return out;
}

api::ObserveRequest ApiRobot::ObserveBoxes3d(bool succeeded) {
  api::ObserveRequest out = Observe(succeeded);
  for (object_search::ObjectDetection& d : out.detections) {
    if (d.faces.empty()) continue;
    double sum = 0.0;
    for (const object_search::FaceDetection& f : d.faces) sum += f.score;
    d.score = sum / static_cast<double>(d.faces.size());
    d.faces.clear();
  }
  return out;
}

api::ObserveRequest ApiRobot::ObserveAs(Sensing sensing, bool succeeded) {
  switch (sensing) {
    case Sensing::kRaw:
      return ObserveRaw(succeeded);
    case Sensing::kBoxes:
      return ObserveBoxes(succeeded);
    case Sensing::kBoxes3d:
      return ObserveBoxes3d(succeeded);
    case Sensing::kDetections:
      break;
  }
  return Observe(succeeded);
}

std::vector<std::string> ApiRobot::TargetPhotos() const {
  std::vector<std::string> out;
  for (const cv::Mat& photo : ObjectPhotos(sim_.objects()[sim_.target_index()])) {
    out.push_back(api::EncodePng(photo).value());
  }
  return out;
}

}  // namespace npfkct::sim
