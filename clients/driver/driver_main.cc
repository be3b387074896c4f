// npfkct-drive: a simulated robot that plays a scenario against a running npfkct-server over HTTP.
// The simulator executes the server's actions and posts back what the robot saw.
#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "npfkct/api/client_codec.h"
#include "npfkct/client/client.h"
#include "npfkct/sim/api_robot.h"
#include "npfkct/sim/scenario.h"

namespace {

using nlohmann::json;

struct Options {
  std::string server = "http://127.0.0.1:8080";
  std::string scenario;
  std::string planner = "npfkct";
  std::optional<std::string> model;  // absent: the server's default; "": none
  std::string api_key;
  double budget_ms = 1000;
  int64_t simulations = 0;
  uint64_t seed = 1;
  int max_steps = 0;
  bool keep = false;
  bool quiet = false;
  bool raw = false;
  double timeout_s = 120;
};

std::string Describe(const json& action) {
  const std::string type = action.value("type", "?");
  if (type != "MOVE") return type + " " + action.value("objectId", "?");
  const auto it = action.find("configuration");
  if (it == action.end() || !it->is_object()) return "MOVE ?";
  const json& c = *it;
  char buf[160];
  std::snprintf(buf, sizeof buf, "MOVE x=%.2f y=%.2f yaw=%.2f lift=%.2f pan=%.2f tilt=%.2f",
                c.value("x", 0.0), c.value("y", 0.0), c.value("yaw", 0.0), c.value("lift", 0.0),
                c.value("pan", 0.0), c.value("tilt", 0.0));
  return buf;
}

int Fail(const std::string& what, const npfkct::Status& status) {
  std::cerr << "npfkct-drive: " << what << ": " << status.ToString() << "\n";
  return 1;
}

// Plays the scenario in session `created` (the create call's reply); the exit status.
int Drive(const Options& o, const npfkct::sim::Scenario& scenario, npfkct::sim::ApiRobot* robot_ptr,
          npfkct::client::Client* api_ptr, const json& created, int max_steps) {
  npfkct::sim::ApiRobot& robot = *robot_ptr;
  npfkct::client::Client& api = *api_ptr;
  const std::string id = created.at("id").get<std::string>();
  if (!o.quiet) {
    const std::string model = created.at("planner").value("model", "");
    std::printf("session %s (%s%s) on %s\n", id.c_str(), o.planner.c_str(),
                o.planner != "npfkct" ? ""
                : model.empty()       ? ", uniform candidates"
                                      : (", model " + model).c_str(),
                scenario.name.c_str());
  }

  double discounted = 0.0, discount = 1.0;
  bool success = false;
  int steps = 0;
  for (int t = 0; t < max_steps; ++t) {
    auto planned = api.Plan(id, o.budget_ms, o.simulations);
    if (!planned.ok()) return Fail("planning", planned.status());
    const json& plan = *planned;
    const json& action = plan.at("action");
    const auto typed = npfkct::api::ParseAction(action.dump());
    if (!typed.ok()) return Fail("planning", typed.status());
    const npfkct::sim::ExecutionOutcome outcome = robot.Execute(*typed);
    discounted += discount * outcome.reward;
    discount *= scenario.params.discount;
    ++steps;
    npfkct::api::ObserveRequest request =
        o.raw ? robot.ObserveRaw(!outcome.illegal) : robot.Observe(!outcome.illegal);
    request.action_id = plan.at("actionId").get<std::string>();
    const auto body = npfkct::api::EncodeObserve(request);
    if (!body.ok()) return Fail("observing", body.status());
    auto observed = api.Observe(id, json::parse(*body));
    if (!observed.ok()) return Fail("observing", observed.status());
    if (!o.quiet) {
      std::printf("step %2d: %-62s %-38s sims %8lld  value %9.1f\n", t + 1,
                  Describe(action).c_str(), outcome.detail.c_str(),
                  // An integer, else 0 (get<int64_t> of a float past its range is undefined).
                  static_cast<long long>(plan.at("stats").at("simulations").is_number_integer()
                                             ? plan.at("stats").at("simulations").get<int64_t>()
                                             : 0),
                  plan.at("expectedValue").get<double>());
      std::fflush(stdout);
    }
    if (outcome.terminal) {
      success = true;
      break;
    }
  }
  std::printf("outcome: %s after %d steps, discounted reward %.1f\n",
              success ? "target removed" : "target not removed", steps, discounted);
  if (!o.keep) (void)api.DeleteSession(id);
  return success ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"npfkct-drive: plays a scenario's simulated robot against npfkct-server"};
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
  app.add_option("--simulations", o.simulations, "simulations per step (0: time only)");
  app.add_option("--seed", o.seed, "seed of the simulated world and of the session");
  app.add_option("--max-steps", o.max_steps, "step limit (default: the scenario's)");
  app.add_flag("--keep", o.keep, "keep the session on the server at the end");
  app.add_flag("--quiet", o.quiet, "print only the outcome");
  app.add_flag("--raw", o.raw,
               "send rendered RGB-D frames (point cloud + PNG) for the server's perception instead "
               "of the simulator's geometric detections");
  CLI11_PARSE(app, argc, argv);

  auto scenario = npfkct::sim::LoadScenario(o.scenario);
  if (!scenario.ok()) {
    std::cerr << "npfkct-drive: " << scenario.status().message() << "\n";
    return 2;
  }
  npfkct::sim::ApiRobot robot(*scenario, o.seed);
  const int max_steps = o.max_steps > 0 ? o.max_steps : scenario->params.max_steps;

  npfkct::client::Client api(o.server, o.api_key, o.timeout_s);
  npfkct::api::CreateSessionRequest create;
  create.display_name = "npfkct-drive " + scenario->name;
  create.world = scenario->Prior();
  create.planner.name = o.planner;
  if (o.model) {
    create.planner.model = *o.model;
    create.planner.model_given = true;
  }
  create.seed = o.seed;
  if (o.raw) create.target.photos = robot.TargetPhotos();
  auto session = api.CreateSession(json::parse(npfkct::api::EncodeCreateSession(create)));
  if (!session.ok()) return Fail("creating the session", session.status());
  // The server's replies are read with checked access: a reply that is not what the API
  // describes ends the run with an error naming it, not an abort.
  try {
    return Drive(o, *scenario, &robot, &api, *session, max_steps);
  } catch (const json::exception& e) {
    std::cerr << "npfkct-drive: the server's reply is not what the API describes: " << e.what()
              << "\n";
    return 1;
  }
}
