// npfkct-sim-robot: the simulated robot as a process speaking JSON lines, so that any client (the
// Python client, curl scripts, the ROS node's tests) can play a scenario against the server.
//
// Each input line is an action in the API's form, {"type": "MOVE", "configuration": {...}} or
// {"type": "DECLARE_TARGET" | "DECLARE_OBSTACLE" | "REMOVE", "objectId": "..."}; {"type": "LOOK"}
// only observes. Each output line is {"outcome": {"reward", "terminal", "illegal", "detail"},
// "observation": {...}} where "observation" is an :observe body without its actionId: geometric
// detections, or with --raw the rendered RGB-D frame (point cloud + PNG) for the server's
// perception. A line that is no such action is an illegal action whose detail says why.
// --target-photos prints the target's photos (a JSON array of base64 PNGs) and exits.
#include <CLI/CLI.hpp>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "npfkct/api/client_codec.h"
#include "npfkct/api/wire.h"
#include "npfkct/common/version.h"
#include "npfkct/sim/api_robot.h"

namespace {

using nlohmann::json;

// Whether `line` is {"type": "LOOK"}, the one action of these lines the API does not have.
bool IsLook(const std::string& line) {
  const json j = json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (!j.is_object() || j.size() != 1) return false;
  const auto type = j.find("type");
  return type != j.end() && type->is_string() && type->get<std::string>() == "LOOK";
}

}  // namespace

int main(int argc, char** argv) {
  namespace api = npfkct::api;
  std::string scenario_path;
  uint64_t seed = 1;
  CLI::App app{"npfkct-sim-robot: the simulated robot of a scenario, as JSON lines on stdio"};
  app.set_version_flag("--version", std::string("npfkct-sim-robot ") + npfkct::kVersion);
  app.add_option("--scenario", scenario_path, "scenario file")->required();
  app.add_option("--seed", seed, "seed of the world and of the noise");
  bool raw = false, boxes = false, boxes3d = false, photos = false;
  app.add_flag("--raw", raw, "observations as rendered frames instead of geometric detections");
  app.add_flag("--boxes", boxes,
               "observations as rendered depth with a simulated detector's 2D boxes (imageBoxes)")
      ->excludes("--raw");
  app.add_flag("--boxes3d", boxes3d,
               "observations as 3D boxes with one score each instead of per-face scores")
      ->excludes("--raw")
      ->excludes("--boxes");
  app.add_flag("--target-photos", photos, "print the target's photos as JSON and exit");
  CLI11_PARSE(app, argc, argv);
  auto scenario = npfkct::sim::LoadScenario(scenario_path);
  if (!scenario.ok()) {
    std::cerr << "npfkct-sim-robot: " << scenario.status().message() << "\n";
    return 2;
  }
  using Sensing = npfkct::sim::ApiRobot::Sensing;
  const Sensing sensing = raw       ? Sensing::kRaw
                          : boxes   ? Sensing::kBoxes
                          : boxes3d ? Sensing::kBoxes3d
                                    : Sensing::kDetections;
  npfkct::sim::ApiRobot robot(*scenario, seed);
  if (photos) {
    json out = json::array();
    for (const std::string& png : robot.TargetPhotos()) out.push_back(api::Base64Encode(png));
    std::cout << out.dump() << std::endl;
    return 0;
  }
  std::string line;
  while (std::getline(std::cin, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const npfkct::StatusOr<api::ActionView> action = api::ParseAction(line);
    const npfkct::sim::ExecutionOutcome outcome =
        action.ok()    ? robot.Execute(*action)
        : IsLook(line) ? robot.Look()
                       : robot.Refuse("malformed action (" + action.status().message() + ")");
    const api::ObserveRequest observation = robot.ObserveAs(sensing, !outcome.illegal);
    const npfkct::StatusOr<std::string> body = api::EncodeObserve(observation);
    if (!body.ok()) {
      std::cerr << "npfkct-sim-robot: " << body.status().ToString() << "\n";
      return 1;
    }
    const json result = {{"reward", outcome.reward},
                         {"terminal", outcome.terminal},
                         {"illegal", outcome.illegal},
                         {"detail", outcome.detail}};
    // The members in the order a JSON object keeps them, as before: observation, outcome.
    std::cout << R"({"observation":)" << *body << R"(,"outcome":)"
              << result.dump(-1, ' ', false, json::error_handler_t::replace) << "}" << std::endl;
  }
  return 0;
}
