// The simulated robot speaking the server API's JSON: it executes API actions and reports its
// observations as :observe bodies. Shared by npfkct-drive and npfkct-sim-robot (library
// npfkct_sim_robot: a client of the API, so it takes the API layer's wire formats; the
// simulator library itself has none).
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "npfkct/sim/simulator.h"

namespace npfkct::sim {

/// A simulator plus what the robot has declared so far (removals depend on it).
class ApiRobot {
 public:
  ApiRobot(Scenario scenario, uint64_t seed);

  /// Executes an action in the API's form ({"type": "MOVE", "configuration": {...}} or
  /// {"type": "DECLARE_TARGET" | "DECLARE_OBSTACLE" | "REMOVE", "objectId": "..."}; "LOOK" only
  /// observes). A malformed action is reported as illegal.
  ExecutionOutcome Execute(const nlohmann::json& action);
  /// The observation after the last action, as an :observe body without the actionId: the
  /// geometric detections (the simulator's shortcut).
  nlohmann::json Observe(bool succeeded);
  /// The same as raw sensor data for the server's perception: the rendered RGB-D frame as a
  /// camera-frame point cloud (base64 float32 xyzrgb) and a PNG, the camera's intrinsics, and
  /// the pose as the robot's localization reports it (the truth plus noise.localization*). When
  /// the camera saw nothing within range, only the pose.
  nlohmann::json ObserveRaw(bool succeeded, int width = 640, int height = 480);
  /// Photos of the target (base64 PNGs), as the robot's operator would give them.
  nlohmann::json TargetPhotosJson() const;

  const Simulator& simulator() const { return sim_; }
  const Scenario& scenario() const { return sim_.scenario(); }

 private:
  Simulator sim_;
  Rng rng_;
  std::map<std::string, int8_t> declared_;
};

/// {"x", "y", "yaw", "lift", "pan", "tilt"}.
nlohmann::json RobotConfigJson(const RobotConfig& c);
/// The detections of a real observation in the API's form.
nlohmann::json DetectionsJson(const object_search::RealObservation& obs);
/// The prior-map part of a scenario file (what the robot is told at session creation).
nlohmann::json WorldJsonOf(const nlohmann::json& scenario_file);

}  // namespace npfkct::sim
