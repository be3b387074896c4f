// Embeds the installed npfkct: plans the Tiger POMDP with POMCP (npfkct::solver), and, given a
// server URL, asks that server for its health, creates a session on the world of a scenario file
// (read by the API layer, npfkct::api) and plans a step through the typed C++ client
// (npfkct::client). Prints one line per check; exits non-zero on the first failure.
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "npfkct/api/client_codec.h"
#include "npfkct/client/client.h"
#include "npfkct/solver/models/tiger.h"
#include "npfkct/solver/pomcp.h"

int main(int argc, char** argv) {
  using namespace npfkct;
  const models::Tiger tiger(0.85, 0.95, models::Tiger::Rollout::kListen);
  PomcpOptions options;
  options.search.num_particles = 2000;
  Pomcp<models::Tiger> planner(tiger, options);
  Rng rng(4);
  planner.Reset(rng);
  const auto first = planner.Plan(Budget::Simulations(20000), rng);
  if (!first.status.ok() || first.action != models::Tiger::kListen) {
    std::fprintf(stderr, "tiger: expected to listen first\n");
    return 1;
  }
  std::printf("solver: tiger listens first (value %.1f)\n", first.value);
  if (argc < 2) return 0;

  client::Client c(argv[1]);
  auto health = c.Health();
  if (!health.ok()) {
    std::fprintf(stderr, "health: %s\n", health.status().ToString().c_str());
    return 1;
  }
  std::printf("client: server %s\n", health->store_ok ? "SERVING" : "NOT_SERVING");
  // The world part of a scenario file, read as the server reads a create request's world.
  std::ifstream scenario(std::string(NPFKCT_DATA_DIR) + "/scenarios/loose1.json");
  std::stringstream text;
  text << scenario.rdbuf();
  auto world = api::ParseWorldSpec(text.str());
  if (!world.ok()) {
    std::fprintf(stderr, "world: %s\n", world.status().ToString().c_str());
    return 1;
  }
  api::CreateSessionRequest create;
  create.world = *world;
  create.planner.name = "npfkct";
  auto session = c.CreateSession(create);
  if (!session.ok()) {
    std::fprintf(stderr, "create: %s\n", session.status().ToString().c_str());
    return 1;
  }
  std::printf("client: session %s plans with model '%s'\n", session->id.c_str(),
              session->planner.model.c_str());
  auto plan = c.Plan(session->id, {.simulations = 200});
  if (!plan.ok()) {
    std::fprintf(stderr, "plan: %s\n", plan.status().ToString().c_str());
    return 1;
  }
  std::printf("client: planned %s after %lld simulations\n", api::ActionTypeName(plan->action.type),
              static_cast<long long>(plan->stats.simulations));
  if (Status deleted = c.DeleteSession(session->id); !deleted.ok()) {
    std::fprintf(stderr, "delete: %s\n", deleted.ToString().c_str());
    return 1;
  }
  return 0;
}
