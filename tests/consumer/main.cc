// Embeds the installed npfkct: plans the Tiger POMDP with POMCP (npfkct::solver), and, given a
// server URL, asks that server for its health and creates a session through the C++ client
// (npfkct::client). Prints one line per check; exits non-zero on the first failure.
#include <cstdio>
#include <fstream>
#include <string>

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
    std::fprintf(stderr, "health: %s\n", health.status().message().c_str());
    return 1;
  }
  std::printf("client: server %s\n", health->value("status", "").c_str());
  std::ifstream scenario(std::string(NPFKCT_DATA_DIR) + "/scenarios/loose1.json");
  const auto s = client::json::parse(scenario);
  client::json world;
  for (const char* k : {"robot", "room", "mapResolution", "furniture", "baseRegions",
                        "discretePoses", "start", "params"}) {
    if (s.contains(k)) world[k] = s[k];
  }
  auto session = c.CreateSession({{"world", world}, {"planner", {{"name", "npfkct"}}}});
  if (!session.ok()) {
    std::fprintf(stderr, "create: %s\n", session.status().message().c_str());
    return 1;
  }
  std::printf("client: session %s plans with model '%s'\n", session->value("id", "").c_str(),
              (*session)["planner"].value("model", "").c_str());
  return 0;
}
