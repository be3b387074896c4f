// The simulated robot as a client of the server API: it executes the API's actions and reports
// its observations as typed :observe requests (the API layer's encoders put them on the wire).
// Shared by npfkct-drive and npfkct-sim-robot.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "npfkct/api/types.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::sim {

/// A simulated YOLO-style detector of the target's class run on `frame` (rendered by `sim`): a
/// box around the pixels of each scene object that shows 100 pixels or more and that it fires
/// on, the target with probability 1 - noise.false_detection and any other object with
/// probability noise.false_detection, with a score of 0.85 (+- noise.detection).
std::vector<perception::ImageBox> DetectorBoxes(const Simulator& sim, const Frame& frame, Rng& rng);

/// A simulator plus what the robot has declared so far (removals depend on it).
class ApiRobot {
 public:
  ApiRobot(Scenario scenario, uint64_t seed);

  /// Executes an action of the API: a MOVE to its configuration, or a declaration or removal of
  /// an object (where the server last saw it, when the action says).
  ExecutionOutcome Execute(const api::ActionView& action);
  /// Looks without acting (npfkct-sim-robot's LOOK): a success worth nothing.
  ExecutionOutcome Look() const;
  /// An action the robot could not read, reported as illegal with `why`.
  ExecutionOutcome Refuse(const std::string& why) const;
  /// The observation after the last action, as an :observe request without its actionId: the
  /// achieved configuration and the geometric detections (the simulator's shortcut).
  api::ObserveRequest Observe(bool succeeded);
  /// The same as raw sensor data for the server's perception: the rendered RGB-D frame as a
  /// camera-frame point cloud with its colours and image, the camera's intrinsics, and the pose
  /// as the robot's localization reports it (the truth plus noise.localization*). When the camera
  /// saw nothing within range, only the pose.
  api::ObserveRequest ObserveRaw(bool succeeded, int width = 640, int height = 480);
  /// The same frame's depth (the point cloud, without the image) with the boxes of the
  /// simulated detector (DetectorBoxes).
  api::ObserveRequest ObserveBoxes(bool succeeded, int width = 640, int height = 480);
  /// The geometric detections of Observe as a 3D box detector reports them: each object's box
  /// with one score (the mean of its faces' scores) in place of per-face scores; objects seen
  /// with no face keep none.
  api::ObserveRequest ObserveBoxes3d(bool succeeded);
  /// How the robot reports what it saw: geometric detections (Observe), rendered frames
  /// (ObserveRaw), depth with 2D boxes (ObserveBoxes) or 3D boxes with one score
  /// (ObserveBoxes3d).
  enum class Sensing { kDetections, kRaw, kBoxes, kBoxes3d };
  /// The observation of `sensing`'s kind at 640 x 480.
  api::ObserveRequest ObserveAs(Sensing sensing, bool succeeded);
  /// Photos of the target (PNG bytes), as the robot's operator would give them.
  std::vector<std::string> TargetPhotos() const;

  const Simulator& simulator() const { return sim_; }
  const Scenario& scenario() const { return sim_.scenario(); }

 private:
  // ObserveRaw of a frame rendered already.
  api::ObserveRequest ObserveRaw(bool succeeded, const Frame& frame);

  Simulator sim_;
  Rng rng_;
  std::map<std::string, int8_t> declared_;
};

}  // namespace npfkct::sim
