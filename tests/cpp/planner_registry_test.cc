// Adding a planner: toy_planner.h and one registry entry reach the benchmark and the server (its
// create-session schema, GET /v1/planners, plans with their summary) without any other file
// knowing the planner.
#include <gtest/gtest.h>

#include <string>

#include "object_search_bench.h"
#include "server_fixture.h"
#include "toy_planner.h"

namespace npfkct::server {
namespace {

object_search::PlannerRegistry WithToy() {
  object_search::PlannerRegistry planners = object_search::PlannerRegistry::BuiltIn();
  EXPECT_TRUE(planners.Add(toy::ToyEntry()).ok());
  return planners;
}

TEST(PlannerRegistryTest, AToyPlannerRunsInTheBenchmark) {
  const object_search::PlannerRegistry planners = WithToy();
  bench::SearchBenchConfig config;
  config.scenarios = {std::string(NPFKCT_SCENARIO_DIR) + "/loose1.json"};
  config.planners = {"toy"};
  config.registry = &planners;
  config.trials = 2;
  config.sims = 1;
  config.max_steps = 3;
  config.options = {"draws=50"};
  ::testing::internal::CaptureStdout();
  const int rc = bench::RunObjectSearchBench(config);
  const std::string out = ::testing::internal::GetCapturedStdout();
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("\"planner\": \"toy\""), std::string::npos) << out;
  EXPECT_NE(out.find("\"failed_trials\": 0"), std::string::npos) << out;
  // A bad option is refused naming it, before any trial.
  config.options = {"draws=0"};
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(bench::RunObjectSearchBench(config), 2);
  ::testing::internal::GetCapturedStdout();
  EXPECT_NE(::testing::internal::GetCapturedStderr().find("draws must be >= 1"), std::string::npos);
}

TEST_F(ServerTest, AToyPlannerIsServedWhenItsServerRegistersIt) {
  ServerOptions o;
  o.planners = WithToy();
  Start(o);
  const Reply list = Get("/v1/planners");
  ASSERT_EQ(list.status, 200) << list.raw;
  bool listed = false;
  for (const json& p : list.body["planners"]) {
    if (p["name"] == "toy") {
      listed = true;
      EXPECT_EQ(p["defaults"], json({{"draws", 100}}));
      EXPECT_FALSE(p["takesModel"].get<bool>());
    }
  }
  EXPECT_TRUE(listed) << list.raw;
  const Reply created = Post(
      "/v1/sessions",
      {{"world", WorldOf("loose1")}, {"planner", {{"name", "toy"}, {"options", {{"draws", 20}}}}}});
  ASSERT_EQ(created.status, 200) << created.raw;
  const std::string id = created.body["id"];
  const Reply plan = Post("/v1/sessions/" + id + ":plan", {{"budget", {{"simulations", 1}}}});
  ASSERT_EQ(plan.status, 200) << plan.raw;
  EXPECT_EQ(plan.body["summary"]["optionsUsed"], json({{"draws", 20}}));
  EXPECT_EQ(plan.body["action"]["type"], "MOVE");
  // Its own options are checked by its factory, and named.
  const Reply bad = Post(
      "/v1/sessions",
      {{"world", WorldOf("loose1")}, {"planner", {{"name", "toy"}, {"options", {{"draws", 0}}}}}});
  EXPECT_EQ(bad.status, 400) << bad.raw;
  EXPECT_NE(bad.raw.find("draws must be >= 1"), std::string::npos) << bad.raw;
}

TEST_F(ServerTest, AServerWithoutTheToyRefusesItByItsSchema) {
  Start();
  const Reply r =
      Post("/v1/sessions", {{"world", WorldOf("loose1")}, {"planner", {{"name", "toy"}}}});
  EXPECT_EQ(r.status, 400) << r.raw;
  EXPECT_EQ(r.body["error"]["details"][0]["fieldViolations"][0]["field"], "planner.name") << r.raw;
}

}  // namespace
}  // namespace npfkct::server
