// npfkct-sim-robot: the simulated robot as a process speaking JSON lines, so that any client (the
// Python client, curl scripts, the ROS node's tests) can play a scenario against the server.
//
// Each input line is an action in the API's form, {"type": "MOVE", "configuration": {...}} or
// {"type": "DECLARE_TARGET" | "DECLARE_OBSTACLE" | "REMOVE", "objectId": "..."}; {"type": "LOOK"}
// only observes. Each output line is {"outcome": {"reward", "terminal", "illegal", "detail"},
// "observation": {...}} where "observation" is an :observe body without its actionId: geometric
// detections, or with --raw the rendered RGB-D frame (point cloud + PNG) for the server's
// perception. --target-photos prints the target's photos (a JSON array of base64 PNGs) and exits.
#include <CLI/CLI.hpp>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "npfkct/sim/api_robot.h"

int main(int argc, char** argv) {
  using nlohmann::json;
  std::string scenario_path;
  uint64_t seed = 1;
  CLI::App app{"npfkct-sim-robot: the simulated robot of a scenario, as JSON lines on stdio"};
  app.add_option("--scenario", scenario_path, "scenario file")->required();
  app.add_option("--seed", seed, "seed of the world and of the noise");
  bool raw = false, photos = false;
  app.add_flag("--raw", raw, "observations as rendered frames instead of geometric detections");
  app.add_flag("--target-photos", photos, "print the target's photos as JSON and exit");
  CLI11_PARSE(app, argc, argv);
  auto scenario = npfkct::sim::LoadScenario(scenario_path);
  if (!scenario.ok()) {
    std::cerr << "npfkct-sim-robot: " << scenario.status().message() << "\n";
    return 2;
  }
  npfkct::sim::ApiRobot robot(*scenario, seed);
  if (photos) {
    std::cout << robot.TargetPhotosJson().dump() << std::endl;
    return 0;
  }
  std::string line;
  while (std::getline(std::cin, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const json action = json::parse(line, nullptr, false);
    const npfkct::sim::ExecutionOutcome outcome = robot.Execute(action);
    json out;
    out["outcome"] = {{"reward", outcome.reward},
                      {"terminal", outcome.terminal},
                      {"illegal", outcome.illegal},
                      {"detail", outcome.detail}};
    out["observation"] = raw ? robot.ObserveRaw(!outcome.illegal) : robot.Observe(!outcome.illegal);
    std::cout << out.dump() << std::endl;
  }
  return 0;
}
