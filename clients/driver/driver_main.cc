// npfkct-drive: a simulated robot that plays a scenario against a running npfkct-server over HTTP.
// The simulator executes the server's actions and posts back what the robot saw.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

#include "npfkct/api/client_codec.h"
#include "npfkct/client/client.h"
#include "npfkct/common/version.h"
#include "npfkct/sim/api_robot.h"
#include "npfkct/sim/scenario.h"

namespace {

namespace api = npfkct::api;

struct Options {
  std::string server = "http://127.0.0.1:8080";
  std::string scenario;
  std::string planner = "npfkct";
  std::optional<std::string> model;  // absent: the server's default; "": none
  std::string api_key;
  double budget_ms = 1000;
  double cpu_ms = 0;
  std::string world;  // a world file for the session in place of the scenario's prior map
  int64_t simulations = 0;
  uint64_t seed = 1;
  int max_steps = 0;
  bool keep = false;
  bool quiet = false;
  npfkct::sim::ApiRobot::Sensing sensing = npfkct::sim::ApiRobot::Sensing::kDetections;
  double timeout_s = 120;
};

std::string Describe(const api::ActionView& action) {
  if (action.type != api::ActionView::Type::kMove) {
    return std::string(api::ActionTypeName(action.type)) + " " + action.object_id;
  }
  const npfkct::object_search::RobotConfig& c = action.configuration;
  char buf[160];
  std::snprintf(buf, sizeof buf, "MOVE x=%.2f y=%.2f yaw=%.2f lift=%.2f pan=%.2f tilt=%.2f", c.x,
                c.y, c.yaw, c.lift, c.pan, c.tilt);
  return buf;
}

int Fail(const std::string& what, const npfkct::Status& status) {
  std::cerr << "npfkct-drive: " << what << ": " << status.ToString() << "\n";
  return 1;
}

// Plays the scenario in session `created` (the create call's reply); the exit status.
int Drive(const Options& o, const npfkct::sim::Scenario& scenario, npfkct::sim::ApiRobot* robot_ptr,
          npfkct::client::Client* api_ptr, const api::SessionView& created, int max_steps) {
  npfkct::sim::ApiRobot& robot = *robot_ptr;
  npfkct::client::Client& client = *api_ptr;
  const std::string& id = created.id;
  if (!o.quiet) {
    const std::string& model = created.planner.model;
    std::printf("session %s (%s%s) on %s\n", id.c_str(), o.planner.c_str(),
                o.planner != "npfkct" ? ""
                : model.empty()       ? ", uniform candidates"
                                      : (", model " + model).c_str(),
                scenario.name.c_str());
  }

  api::PlanRequest budget;
  if (o.budget_ms > 0 && o.cpu_ms <= 0) budget.time_ms = o.budget_ms;
  if (o.cpu_ms > 0) budget.cpu_ms = o.cpu_ms;
  if (o.simulations > 0) budget.simulations = o.simulations;
  double discounted = 0.0, discount = 1.0;
  bool success = false;
  int steps = 0;
  for (int t = 0; t < max_steps; ++t) {
    auto plan = client.Plan(id, budget);
    if (!plan.ok()) return Fail("planning", plan.status());
    const npfkct::sim::ExecutionOutcome outcome = robot.Execute(plan->action);
    discounted += discount * outcome.reward;
    discount *= scenario.params.discount;
    ++steps;
    api::ObserveRequest observation = robot.ObserveAs(o.sensing, !outcome.illegal);
    observation.action_id = plan->action_id;
    auto observed = client.Observe(id, observation);
    if (!observed.ok()) return Fail("observing", observed.status());
    if (!o.quiet) {
      std::printf("step %2d: %-62s %-38s sims %8lld  value %9.1f\n", t + 1,
                  Describe(plan->action).c_str(), outcome.detail.c_str(),
                  static_cast<long long>(plan->stats.simulations), plan->expected_value);
      std::fflush(stdout);
    }
    if (outcome.terminal) {
      success = true;
      break;
    }
  }
  std::printf("outcome: %s after %d steps, discounted reward %.1f\n",
              success ? "target removed" : "target not removed", steps, discounted);
  if (!o.keep) (void)client.DeleteSession(id);
  return success ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"npfkct-drive: plays a scenario's simulated robot against npfkct-server"};
  app.set_version_flag("--version", std::string("npfkct-drive ") + npfkct::kVersion);
  app.add_option("--server", o.server, "server URL");
  app.add_option("--scenario", o.scenario, "scenario file")->required();
  app.add_option("--planner", o.planner, "planner of the session");
  app.add_option("--model", o.model,
                 "neural filter model of the server for npfkct (planner.model, a file name in "
                 "the server's --model-dir, e.g. filter.pt; \"\" for none; default: the "
                 "server's default model)");
  app.add_option("--api-key", o.api_key, "bearer token");
  app.add_option("--timeout", o.timeout_s, "seconds a call to the server may take in all")
      ->check(CLI::Range(0.001, 1e6))
      ->check(CLI::Validator(
          [](std::string& v) {
            return std::isfinite(std::strtod(v.c_str(), nullptr)) ? std::string()
                                                                  : std::string("not a number");
          },
          "FINITE"));
  app.add_option("--budget-ms", o.budget_ms, "planning time per step");
  app.add_option("--cpu-ms", o.cpu_ms,
                 "CPU time of the planning thread per step, in place of --budget-ms");
  app.add_option("--world", o.world,
                 "a world file (the create request's world: a SLAM occupancy grid, traced "
                 "workspaces, ...) for the session in place of the scenario's prior map; the "
                 "scenario stays the truth the simulated robot sees");
  app.add_option("--simulations", o.simulations, "simulations per step (0: time only)");
  app.add_option("--seed", o.seed, "seed of the simulated world and of the session");
  app.add_option("--max-steps", o.max_steps, "step limit (default: the scenario's)");
  app.add_flag("--keep", o.keep, "keep the session on the server at the end");
  app.add_flag("--quiet", o.quiet, "print only the outcome");
  bool raw = false, boxes = false, boxes3d = false;
  app.add_flag("--raw", raw,
               "send rendered RGB-D frames (point cloud + PNG) for the server's perception instead "
               "of the simulator's geometric detections");
  app.add_flag("--boxes", boxes,
               "send rendered depth with a simulated YOLO-style detector's 2D boxes of the target "
               "(imageBoxes) instead of the simulator's geometric detections")
      ->excludes("--raw");
  app.add_flag("--boxes3d", boxes3d,
               "send the simulator's detections as 3D boxes with one score each (a 3D box "
               "detector's) instead of per-face scores")
      ->excludes("--raw")
      ->excludes("--boxes");
  CLI11_PARSE(app, argc, argv);
  using Sensing = npfkct::sim::ApiRobot::Sensing;
  o.sensing = raw       ? Sensing::kRaw
              : boxes   ? Sensing::kBoxes
              : boxes3d ? Sensing::kBoxes3d
                        : Sensing::kDetections;

  auto scenario = npfkct::sim::LoadScenario(o.scenario);
  if (!scenario.ok()) {
    std::cerr << "npfkct-drive: " << scenario.status().message() << "\n";
    return 2;
  }
  npfkct::sim::ApiRobot robot(*scenario, o.seed);
  const int max_steps = o.max_steps > 0 ? o.max_steps : scenario->params.max_steps;

  npfkct::client::Client client(o.server, o.api_key, o.timeout_s);
  api::CreateSessionRequest create;
  create.display_name = "npfkct-drive " + scenario->name;
  create.world = scenario->Prior();
  if (!o.world.empty()) {
    std::ifstream in(o.world);
    std::stringstream text;
    text << in.rdbuf();
    auto world = api::ParseWorldSpec(text.str());
    if (!in || !world.ok()) {
      std::cerr << "npfkct-drive: " << o.world << ": "
                << (in ? world.status().message() : "cannot read it") << "\n";
      return 2;
    }
    create.world = std::move(world).value();
  }
  create.planner.name = o.planner;
  if (o.model) {
    create.planner.model = *o.model;
    create.planner.model_given = true;
  }
  create.seed = o.seed;
  if (o.sensing == Sensing::kRaw) create.target.photos = robot.TargetPhotos();
  // A reply that is not what the API describes ends the run with an error naming its field.
  auto session = client.CreateSession(create);
  if (!session.ok()) return Fail("creating the session", session.status());
  return Drive(o, *scenario, &robot, &client, *session, max_steps);
}
