// The real server on a loopback port, driven by an HTTP client.
#include "npfkct/server/server.h"

#include <gtest/gtest.h>
#include <httplib.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "npfkct/server/models.h"
#include "server_fixture.h"

namespace npfkct::server {
namespace {

// An observation that reports what the robot saw after a move: one box with two faces.
json Observation(const std::string& action_id, double tilt = 0.4) {
  return {{"actionId", action_id},
          {"robotState",
           {{"x", 0.3}, {"y", 0.0}, {"yaw", 0.0}, {"lift", 0.2}, {"pan", 0.0}, {"tilt", tilt}}},
          {"detections",
           {{{"id", "box-1"},
             {"box", {{"center", {1.4, 0.1, 0.82}}, {"size", {0.12, 0.12, 0.14}}}},
             {"moveability", 0.9},
             {"faces", {{{"corner", 0}, {"score", 0.2}}, {{"corner", 2}, {"score", 0.15}}}}}}}};
}

TEST_F(ServerTest, HealthAndMetrics) {
  Start();
  EXPECT_EQ(Get("/healthz").body["status"], "SERVING");
  Create();
  Reply m = Get("/metrics");
  EXPECT_EQ(m.status, 200);
  EXPECT_NE(m.raw.find("npfkct_sessions 1"), std::string::npos);
  EXPECT_NE(m.raw.find("npfkct_http_requests_total{method=\"POST\",route=\"/v1/sessions\","
                       "code=\"200\"} 1"),
            std::string::npos);
  EXPECT_NE(m.raw.find("# TYPE npfkct_plan_overhead_seconds histogram"), std::string::npos);
}

TEST_F(ServerTest, PlanObserveCycleWithPreconditions) {
  Start();
  const std::string id = Create();
  ASSERT_EQ(id.size(), 32u);
  const std::string base = "/v1/sessions/" + id;
  Reply s = Get(base);
  EXPECT_EQ(s.body["name"], "sessions/" + id);
  EXPECT_EQ(s.body["state"], "READY");

  // Observing before planning is a failed precondition.
  Reply early = Post(base + ":observe", Observation("a0-000000"));
  EXPECT_EQ(early.status, 400);
  EXPECT_EQ(early.body["error"]["status"], "FAILED_PRECONDITION");

  Reply plan = Post(base + ":plan", {{"budget", {{"simulations", 400}}}});
  ASSERT_EQ(plan.status, 200) << plan.raw;
  const std::string action_id = plan.body["actionId"];
  EXPECT_EQ(plan.body["stats"]["simulations"], 400);
  EXPECT_EQ(plan.body["action"]["type"], "MOVE");
  EXPECT_TRUE(plan.body["action"]["configuration"].contains("tilt"));
  EXPECT_EQ(plan.body["session"]["state"], "ACTION_PENDING");

  // Planning again while the action is pending, and a stale id, are failed preconditions.
  Reply again = Post(base + ":plan", {{"budget", {{"simulations", 10}}}});
  EXPECT_EQ(again.status, 400);
  EXPECT_EQ(again.body["error"]["status"], "FAILED_PRECONDITION");
  Reply stale = Post(base + ":observe", Observation("a9-ffffff"));
  EXPECT_EQ(stale.body["error"]["status"], "FAILED_PRECONDITION");
  EXPECT_NE(stale.body["error"]["message"].get<std::string>().find(action_id), std::string::npos);

  // A bad observation changes nothing: the action stays pending.
  json bad = Observation(action_id);
  bad["detections"][0]["faces"][0]["corner"] = 11;
  Reply rejected = Post(base + ":observe", bad);
  EXPECT_EQ(rejected.status, 400);
  EXPECT_EQ(rejected.body["error"]["details"][0]["fieldViolations"][0]["field"],
            "detections[0].faces[0].corner");
  EXPECT_EQ(Get(base).body["state"], "ACTION_PENDING");

  Reply obs = Post(base + ":observe", Observation(action_id));
  ASSERT_EQ(obs.status, 200) << obs.raw;
  EXPECT_EQ(obs.body["done"], false);
  EXPECT_EQ(obs.body["session"]["state"], "READY");
  EXPECT_EQ(obs.body["session"]["objectCount"], 1);
  EXPECT_EQ(obs.body["session"]["step"], 1);
  // The same observation again is rejected (double observation).
  Reply twice = Post(base + ":observe", Observation(action_id));
  EXPECT_EQ(twice.body["error"]["status"], "FAILED_PRECONDITION");
  EXPECT_NE(twice.body["error"]["message"].get<std::string>().find("already observed"),
            std::string::npos);

  Reply belief = Get(base + "/belief");
  ASSERT_EQ(belief.status, 200);
  EXPECT_EQ(belief.body["objects"][0]["id"], "box-1");
  EXPECT_LT(belief.body["objects"][0]["faceLogOdds"][0].get<double>(), -1.0);
  EXPECT_EQ(belief.body["grid"]["workspaces"].size(), 1u);
  auto png = client_->Get((base + "/belief?format=png").c_str());
  ASSERT_TRUE(png);
  EXPECT_EQ(png->get_header_value("Content-Type"), "image/png");
  EXPECT_EQ(png->body.substr(1, 3), "PNG");

  Reply list = Get("/v1/sessions");
  EXPECT_EQ(list.body["sessions"].size(), 1u);
  EXPECT_EQ(Delete(base).status, 200);
  EXPECT_EQ(Get(base).status, 404);
  EXPECT_EQ(Delete(base).status, 404);
}

TEST_F(ServerTest, BadInputGetsClearErrorsNamingTheField) {
  Start();
  struct Case {
    json body;
    std::string field;
  };
  json world = WorldOf("loose1");
  json broken_world = world;
  broken_world["furniture"][0]["size"] = json::array({1, 2});
  const std::vector<Case> cases = {
      {{{"world", broken_world}}, "world.furniture[0].size"},
      {{{"world", world}, {"planner", {{"name", "magic"}}}}, "planner.name"},
      {{{"world", world}, {"planner", {{"options", {{"k", 1}}}}}}, "planner.options"},
      {{{"world", world}, {"planner", {{"options", {{"notAnOption", 1}}}}}}, "planner.options"},
      // Only kCT plans on several threads: refused at creation, not at every plan after it.
      {{{"world", world}, {"planner", {{"name", "advt"}, {"options", {{"search.threads", 2}}}}}},
       "planner.options.search.threads"},
      {{{"world", world},
        {"planner", {{"name", "pomcp-joint"}, {"options", {{"search.threads", 4}}}}}},
       "planner.options.search.threads"},
      {{{"world", world}, {"planner", {{"particles", 0}}}}, "planner.particles"},
      {{{"world", world}, {"seed", -3}}, "seed"},
      {{{"world", world}, {"ttlSeconds", 1e12}}, "ttlSeconds"},
      {{{"world", world}, {"colour", "red"}}, "colour"},
      {json::object(), "world"},
  };
  for (const Case& c : cases) {
    Reply r = Post("/v1/sessions", c.body);
    EXPECT_EQ(r.status, 400) << c.body.dump();
    EXPECT_EQ(r.body["error"]["status"], "INVALID_ARGUMENT");
    const std::string message = r.body["error"]["message"];
    EXPECT_EQ(message.rfind(c.field, 0), 0u) << message;
  }
  const std::string id = Create();
  const std::string base = "/v1/sessions/" + id;
  Reply budget = Post(base + ":plan", {{"budget", {{"timeMs", -5}}}});
  EXPECT_EQ(budget.body["error"]["details"][0]["fieldViolations"][0]["field"], "budget.timeMs");
  EXPECT_EQ(Post(base + ":plan", {{"budget", {{"timeMs", 1e9}}}}).status, 400);
  EXPECT_EQ(Post(base + ":plan", {{"budget", {{"simulations", 1.5}}}}).status, 400);
  EXPECT_EQ(PostRaw(base + ":plan", "{\"budget\": ").body["error"]["message"],
            "body: not valid JSON");
  EXPECT_EQ(PostRaw(base + ":plan", std::string(200, '[') + std::string(200, ']')).status, 400);
  EXPECT_EQ(PostRaw(base + ":plan", "[1, 2]").status, 400);
  EXPECT_EQ(Post("/v1/sessions/0123456789abcdef0123456789abcdef:plan", json::object()).status, 404);
  EXPECT_EQ(Post("/v1/sessions/../etc:plan", json::object()).status, 404);
  Reply unknown_route = Get("/v2/whatever");
  EXPECT_EQ(unknown_route.status, 404);
  EXPECT_EQ(unknown_route.body["error"]["status"], "NOT_FOUND");
  // The session is intact after all that.
  EXPECT_EQ(Post(base + ":plan", {{"budget", {{"simulations", 50}}}}).status, 200);
}

TEST(ModelRegistryTest, AModelDroppedFromTheCacheIsReusedWhileSessionsHoldIt) {
  // With --max-models 1, sessions alternating two models each loaded a copy of their own
  // (+430 MiB for 160 sessions).
  const std::string dir = ::testing::TempDir() + "/npfkct_models_lru_" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  for (const char* name : {"/a.pt", "/b.pt"}) {
    std::filesystem::copy_file(NPFKCT_FILTER_MODEL, dir + name,
                               std::filesystem::copy_options::overwrite_existing);
  }
  auto models = ModelRegistry::Open(dir, 1);
  auto a = models->Get("a.pt");
  auto b = models->Get("b.pt");  // drops a from the cache; the caller still holds it
  auto again = models->Get("a.pt");
  ASSERT_TRUE(a.ok() && b.ok() && again.ok());
  EXPECT_EQ(a->get(), again->get());
  auto b_again = models->Get("b.pt");
  ASSERT_TRUE(b_again.ok());
  EXPECT_EQ(b->get(), b_again->get());
  std::filesystem::remove_all(dir);
}

TEST_F(ServerTest, FilterModelsAreNamedNeverPathsAndLoadedAtCreation) {
  // A model folder of our own: the shipped model under two names, and a corrupt one.
  const std::string dir = ::testing::TempDir() + "/npfkct_models_" + std::to_string(getpid());
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(NPFKCT_FILTER_MODEL, dir + "/filter.pt",
                             std::filesystem::copy_options::overwrite_existing);
  std::ofstream(dir + "/corrupt.pt") << "not a model";
  ServerOptions o;
  o.model_dir = dir;
  Start(o);
  const json world = WorldOf("loose1");
  // Unknown names, corrupt files and anything path-like fail the creation naming planner.model;
  // no session is left and nothing outside the folder is ever opened.
  for (const std::string& name :
       {std::string("nonexistent.pt"), std::string("corrupt.pt"), std::string("/etc/passwd"),
        std::string("../model/filter.pt"), std::string(".hidden.pt"), dir + "/filter.pt"}) {
    Reply r = Post("/v1/sessions",
                   {{"world", world}, {"planner", {{"name", "npfkct"}, {"model", name}}}});
    EXPECT_EQ(r.status, 400) << name << ": " << r.raw;
    EXPECT_EQ(r.body["error"]["status"], "INVALID_ARGUMENT");
    EXPECT_EQ(r.body["error"]["details"][0]["fieldViolations"][0]["field"], "planner.model")
        << r.raw;
  }
  // Whether a file exists outside the folder cannot be probed: the same answer either way.
  Reply passwd = Post("/v1/sessions", {{"world", world}, {"planner", {{"model", "passwd"}}}});
  Reply missing = Post("/v1/sessions", {{"world", world}, {"planner", {{"model", "nosuch"}}}});
  for (const auto& [reply, name] : {std::pair{passwd, "passwd"}, std::pair{missing, "nosuch"}}) {
    EXPECT_EQ(reply.body["error"]["message"],
              "planner.model: no model '" + std::string(name) +
                  "' on this server (models: corrupt.pt, filter.pt)");
  }
  // The old field is gone: planner.modelPath is an unknown field.
  Reply old = Post("/v1/sessions", {{"world", world}, {"planner", {{"modelPath", "/tmp/x.pt"}}}});
  EXPECT_EQ(old.body["error"]["details"][0]["fieldViolations"][0]["field"], "planner.modelPath");
  Reply other = Post("/v1/sessions",
                     {{"world", world}, {"planner", {{"name", "pomcp"}, {"model", "filter.pt"}}}});
  EXPECT_EQ(other.status, 400);
  // Net_sam's options: checked and named; they need a model.
  const std::vector<std::pair<json, std::string>> bad_options = {
      {{{"filter.explore", 1.5}}, "planner.options.filter.explore"},
      {{{"filter.candidates", 2.5}}, "planner.options.filter.candidates"},
      {{{"filter.magic", 1}}, "planner.options.filter.magic"},
      {{{"filter.candidates", 1e8}}, "planner.options.filter.candidates"},
  };
  for (const auto& [options, field] : bad_options) {
    Reply r =
        Post("/v1/sessions",
             {{"world", world},
              {"planner", {{"name", "npfkct"}, {"model", "filter.pt"}, {"options", options}}}});
    EXPECT_EQ(r.status, 400) << r.raw;
    EXPECT_EQ(r.body["error"]["details"][0]["fieldViolations"][0]["field"], field) << r.raw;
  }
  // "model": "" asks for no model (uniform candidates): the filter's options are then refused.
  Reply no_model = Post(
      "/v1/sessions",
      {{"world", world},
       {"planner", {{"name", "npfkct"}, {"model", ""}, {"options", {{"filter.explore", 0.5}}}}}});
  EXPECT_EQ(no_model.status, 400) << no_model.raw;
  EXPECT_EQ(Get("/v1/sessions").body["sessions"].size(), 0u);
  // Naming none, an npfkct session gets the server's default model (the shipped filter.pt).
  Reply by_default = Post(
      "/v1/sessions", {{"world", world},
                       {"planner", {{"name", "npfkct"}, {"options", {{"filter.explore", 0.5}}}}}});
  ASSERT_EQ(by_default.status, 200) << by_default.raw;
  EXPECT_EQ(by_default.body["planner"]["model"], "filter.pt");
  Reply uniform =
      Post("/v1/sessions", {{"world", world}, {"planner", {{"name", "npfkct"}, {"model", ""}}}});
  ASSERT_EQ(uniform.status, 200) << uniform.raw;
  EXPECT_EQ(uniform.body["planner"]["model"], "");
  for (const Reply* r : {&by_default, &uniform}) {
    EXPECT_EQ(Delete("/v1/sessions/" + r->body["id"].get<std::string>()).status, 200);
  }
  // The model by name: the plan's candidate statistics show the filter at work.
  const std::string id = Create({{"planner",
                                  {{"name", "npfkct"},
                                   {"particles", 100},
                                   {"model", "filter.pt"},
                                   {"options", {{"filter.minKeep", 8}, {"k", 3}}}}}});
  ASSERT_FALSE(id.empty());
  Reply plan = Post("/v1/sessions/" + id + ":plan", {{"budget", {{"simulations", 200}}}});
  ASSERT_EQ(plan.status, 200) << plan.raw;
  const json& candidates = plan.body["stats"]["candidates"];
  EXPECT_GT(candidates["sampled"].get<int>(), candidates["accepted"].get<int>()) << plan.raw;
  EXPECT_GT(candidates["accepted"].get<int>(), 0);
  EXPECT_EQ(Get("/v1/sessions/" + id).body["planner"]["model"], "filter.pt");
  std::filesystem::remove_all(dir);
}

TEST_F(ServerTest, OversizedBodiesAreRejectedAsJson) {
  ServerOptions o;
  o.max_body_bytes = 4096;
  Start(o);
  Reply r = PostRaw("/v1/sessions", "{\"displayName\": \"" + std::string(10000, 'x') + "\"}");
  EXPECT_EQ(r.status, 413);
  EXPECT_EQ(r.body["error"]["status"], "RESOURCE_EXHAUSTED");
}

TEST_F(ServerTest, BearerAuthentication) {
  ServerOptions o;
  o.api_key = "s3cret";
  Start(o);
  Reply anonymous = Post("/v1/sessions", {{"world", WorldOf("loose1")}});
  EXPECT_EQ(anonymous.status, 401);
  EXPECT_EQ(anonymous.body["error"]["status"], "UNAUTHENTICATED");
  EXPECT_EQ(Get("/v1/sessions", {{"Authorization", "Bearer wrong"}}).status, 401);
  Reply ok =
      Post("/v1/sessions", {{"world", WorldOf("loose1")}}, {{"Authorization", "Bearer s3cret"}});
  EXPECT_EQ(ok.status, 200);
  EXPECT_EQ(Get("/healthz").status, 200);  // health checks stay open
}

TEST_F(ServerTest, IdleSessionsExpire) {
  Start();
  const std::string id = Create({{"ttlSeconds", 0.5}});
  EXPECT_EQ(Get("/v1/sessions/" + id).status, 200);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  EXPECT_EQ(Get("/v1/sessions/" + id).status, 404);
  EXPECT_NE(Get("/metrics").raw.find("npfkct_sessions_expired_total 1"), std::string::npos);
}

TEST_F(ServerTest, SessionsSurviveARestartWithTheSameBelief) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("npfkct-state-" + std::to_string(getpid())))
          .string();
  std::filesystem::remove_all(dir);
  ServerOptions o;
  o.state_dir = dir;
  Start(o);
  const std::string id = Create();
  const std::string base = "/v1/sessions/" + id;
  Reply plan = Post(base + ":plan", {{"budget", {{"simulations", 200}}}});
  ASSERT_EQ(plan.status, 200);
  ASSERT_EQ(Post(base + ":observe", Observation(plan.body["actionId"])).status, 200);
  Reply plan2 = Post(base + ":plan", {{"budget", {{"simulations", 200}}}});
  ASSERT_EQ(plan2.status, 200);
  const json belief = Get(base + "/belief").body;
  server_->Stop();

  Start(o);
  EXPECT_EQ(server_->restored_sessions(), 1);
  EXPECT_EQ(Get(base + "/belief").body, belief);
  Reply s = Get(base);
  EXPECT_EQ(s.body["state"], "ACTION_PENDING");
  EXPECT_EQ(s.body["pendingAction"]["actionId"], plan2.body["actionId"]);
  // The pending action can be observed after the restart, and planning goes on.
  ASSERT_EQ(Post(base + ":observe", Observation(plan2.body["actionId"], 0.3)).status, 200);
  EXPECT_EQ(Post(base + ":plan", {{"budget", {{"simulations", 100}}}}).status, 200);
  EXPECT_EQ(Delete(base).status, 200);
  EXPECT_FALSE(std::filesystem::exists(dir + "/" + id + ".snap"));
  std::filesystem::remove_all(dir);
}

TEST_F(ServerTest, SessionsPlanInParallelAndDeletesDoNotCorruptThem) {
  ServerOptions o;
  o.threads = 6;
  o.plan_slots = 3;
  Start(o);
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) ids.push_back(Create());
  // Three plans of 600 ms on three sessions overlap in time.
  std::vector<std::pair<double, double>> spans(3);
  std::vector<std::thread> threads;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < 3; ++i) {
    threads.emplace_back([&, i] {
      httplib::Client c("127.0.0.1", server_->port());
      c.set_read_timeout(30, 0);
      const double begin =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      auto r = c.Post(("/v1/sessions/" + ids[i] + ":plan").c_str(),
                      json{{"budget", {{"timeMs", 600}}}}.dump(), "application/json");
      const double end =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      EXPECT_TRUE(r && r->status == 200);
      spans[i] = {begin, end};
    });
  }
  for (auto& t : threads) t.join();
  double latest_start = 0, earliest_end = 1e9;
  for (const auto& [b, e] : spans) {
    latest_start = std::max(latest_start, b);
    earliest_end = std::min(earliest_end, e);
  }
  EXPECT_LT(latest_start, earliest_end);  // all three were planning at the same time

  // Deleting a session while it plans: the plan is aborted, the delete succeeds.
  const std::string victim = Create();
  std::thread planner([&] {
    httplib::Client c("127.0.0.1", server_->port());
    c.set_read_timeout(30, 0);
    auto r = c.Post(("/v1/sessions/" + victim + ":plan").c_str(),
                    json{{"budget", {{"timeMs", 800}}}}.dump(), "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 409);
    EXPECT_EQ(json::parse(r->body)["error"]["status"], "ABORTED");
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(Delete("/v1/sessions/" + victim).status, 200);
  planner.join();
  EXPECT_EQ(Get("/v1/sessions/" + victim).status, 404);
  for (const auto& id : ids) EXPECT_EQ(Get("/v1/sessions/" + id).body["state"], "ACTION_PENDING");
}

double SecondsSince(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// A plan request on its own connection, in the background: status and when it ended.
struct BackgroundPlan {
  std::thread thread;
  int status = 0;
  json body;
  std::chrono::steady_clock::time_point end;
  std::atomic<bool> done{false};  // its reply arrived
  BackgroundPlan(int port, const std::string& id, const json& budget) {
    thread = std::thread([this, port, id, budget] {
      httplib::Client c("127.0.0.1", port);
      c.set_read_timeout(90, 0);
      auto r = c.Post(("/v1/sessions/" + id + ":plan").c_str(), json{{"budget", budget}}.dump(),
                      "application/json");
      end = std::chrono::steady_clock::now();
      if (r) {
        status = r->status;
        body = json::parse(r->body, nullptr, false);
      }
      done = true;
    });
  }
  void Join() { thread.join(); }
};

// Timing bounds are far from the plan's 30 s: a loaded machine still meets them (the latency
// itself is a benchmark's business).
TEST_F(ServerTest, DeleteStopsARunningThirtySecondPlan) {
  Start();
  const std::string id = Create();
  BackgroundPlan plan(server_->port(), id, {{"timeMs", 30000}});
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const auto t0 = std::chrono::steady_clock::now();
  Reply deleted = Delete("/v1/sessions/" + id);
  const double delete_seconds = SecondsSince(t0);
  plan.Join();
  const double plan_end = std::chrono::duration<double>(plan.end - t0).count();
  EXPECT_EQ(deleted.status, 200);
  EXPECT_LT(delete_seconds, 5.0);
  EXPECT_LT(plan_end, 5.0) << "the plan went on after the DELETE";
  EXPECT_EQ(plan.status, 409);
  EXPECT_EQ(plan.body["error"]["status"], "ABORTED");
  EXPECT_EQ(Get("/v1/sessions/" + id).status, 404);
  // Its planning slot is free again.
  EXPECT_NE(Get("/metrics").raw.find("npfkct_planning_slots_busy 0"), std::string::npos);
}

TEST_F(ServerTest, AClientThatHangsUpCancelsItsPlan) {
  ServerOptions o;
  o.plan_slots = 1;
  Start(o);
  // With two search threads the workers poll the hang-up too (from threads that are not the
  // handler's).
  for (int threads : {1, 2}) {
    SCOPED_TRACE(threads);
    const std::string id = Create(
        {{"planner",
          {{"name", "npfkct"}, {"particles", 100}, {"options", {{"search.threads", threads}}}}}});
    {
      httplib::Client c("127.0.0.1", server_->port());
      c.set_read_timeout(0, 300'000);  // gives up after 0.3 s and closes the connection
      auto r = c.Post(("/v1/sessions/" + id + ":plan").c_str(),
                      json{{"budget", {{"timeMs", 30000}}}}.dump(), "application/json");
      EXPECT_FALSE(r);
    }
    // The plan stops at the hang-up, long before its budget: the slot is free, nothing pending.
    const auto t0 = std::chrono::steady_clock::now();
    bool free = false;
    while (!free && SecondsSince(t0) < 10.0) {  // far below the plan's 30 s
      free = Get("/metrics").raw.find("npfkct_planning_slots_busy 0") != std::string::npos;
      if (!free) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    EXPECT_TRUE(free);
    EXPECT_EQ(Get("/v1/sessions/" + id).body["state"], "READY");
    Reply again = Post("/v1/sessions/" + id + ":plan", {{"budget", {{"simulations", 20}}}});
    EXPECT_EQ(again.status, 200) << again.raw;
  }
}

TEST_F(ServerTest, ATtlShorterThanAPlanDoesNotReapTheSessionUnderIt) {
  Start();
  const std::string id = Create({{"ttlSeconds", 0.3}});
  Reply plan = Post("/v1/sessions/" + id + ":plan", {{"budget", {{"timeMs", 1500}}}});
  EXPECT_EQ(plan.status, 200) << plan.raw;
  EXPECT_EQ(Get("/v1/sessions/" + id).body["state"], "ACTION_PENDING");
  // Idle past its TTL after the plan: reaped.
  std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  EXPECT_EQ(Get("/v1/sessions/" + id).status, 404);
}

TEST_F(ServerTest, BusyPlanningSlotsQueueThenRefuseAndNeverDelayHealthOrReads) {
  ServerOptions o;
  o.plan_slots = 1;
  o.plan_queue = 1;
  Start(o);
  const std::string a = Create(), b = Create(), c = Create();
  // Checks are causal, not timed: every answer below comes while this 30 s plan still runs, so
  // none waited for it (a loaded machine cannot make them fail).
  BackgroundPlan running(server_->port(), a, {{"timeMs", 30000}});
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  BackgroundPlan queued(server_->port(), b, {{"timeMs", 100}});
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // The slot and the queue are taken: the next plan is refused at once, with Retry-After.
  httplib::Client client("127.0.0.1", server_->port());
  auto refused = client.Post(("/v1/sessions/" + c + ":plan").c_str(),
                             json{{"budget", {{"timeMs", 100}}}}.dump(), "application/json");
  ASSERT_TRUE(refused);
  EXPECT_FALSE(running.done);
  EXPECT_EQ(refused->status, 429);
  EXPECT_EQ(refused->get_header_value("Retry-After"), "1");
  EXPECT_EQ(json::parse(refused->body)["error"]["status"], "RESOURCE_EXHAUSTED");
  // Health, metrics, listing and reading a planning session answer at once meanwhile.
  const std::string session = "/v1/sessions/" + a;
  for (const std::string& path : std::vector<std::string>{"/healthz", "/metrics", "/v1/sessions",
                                                          session, session + "/belief"}) {
    EXPECT_EQ(Get(path).status, 200) << path;
    EXPECT_FALSE(running.done) << path;
  }
  // A second request on the planning session is refused, not queued behind the plan.
  Reply busy = Post("/v1/sessions/" + a + ":observe", Observation("a1-000000"));
  EXPECT_EQ(busy.status, 409);
  EXPECT_EQ(busy.body["error"]["status"], "ABORTED");
  EXPECT_FALSE(running.done);
  // Deleting the planning session frees the slot for the queued plan.
  EXPECT_EQ(Delete(session).status, 200);
  running.Join();
  queued.Join();
  EXPECT_EQ(running.status, 409);
  EXPECT_EQ(queued.status, 200);
}

TEST_F(ServerTest, ThePlanReplyReportsTheBudgetAsUsedAndSessionsHaveAPlanningBudget) {
  ServerOptions o;
  o.limits.max_plan_ms = 5000;
  o.limits.max_session_plan_seconds = 2.0;
  Start(o);
  const std::string id = Create();
  const std::string base = "/v1/sessions/" + id;
  Reply sims = Post(base + ":plan", {{"budget", {{"simulations", 50}}}});
  ASSERT_EQ(sims.status, 200) << sims.raw;
  // A simulation budget alone still ran under a wall-clock cap: here what is left of the
  // session's 2 s (less than the 5 s maximum per request).
  EXPECT_EQ(sims.body["budget"]["simulations"], 50);
  EXPECT_LE(sims.body["budget"]["timeMs"].get<double>(), 2000.0);
  EXPECT_GT(sims.body["budget"]["timeMs"].get<double>(), 1500.0);
  EXPECT_EQ(sims.body["stats"]["simulations"], 50);
  ASSERT_EQ(Post(base + ":observe", Observation(sims.body["actionId"])).status, 200);
  Reply cpu = Post(base + ":plan", {{"budget", {{"cpuMs", 200}}}});
  ASSERT_EQ(cpu.status, 200) << cpu.raw;
  EXPECT_EQ(cpu.body["budget"]["cpuMs"].get<double>(), 200.0);
  EXPECT_LE(cpu.body["stats"]["cpuMs"].get<double>(), 260.0);
  ASSERT_EQ(Post(base + ":observe", Observation(cpu.body["actionId"], 0.3)).status, 200);
  // Over the server's maximum per request: refused, naming the field.
  Reply over = Post(base + ":plan", {{"budget", {{"timeMs", 6000}}}});
  EXPECT_EQ(over.status, 400);
  EXPECT_EQ(over.body["error"]["details"][0]["fieldViolations"][0]["field"], "budget.timeMs");
  // Plans of 700 ms until the session's 2 s are spent: each capped by what is left, then 429.
  Reply spent;
  for (int i = 0; i < 6; ++i) {
    const double used = Get(base).body["planningSecondsUsed"].get<double>();
    spent = Post(base + ":plan", {{"budget", {{"timeMs", 700}}}});
    if (spent.status != 200) break;
    EXPECT_LE(spent.body["budget"]["timeMs"].get<double>(),
              std::min(700.0, 1000.0 * (2.0 - used)) + 1e-6);
    ASSERT_EQ(Post(base + ":observe", Observation(spent.body["actionId"], 0.2 + 0.01 * i)).status,
              200);
  }
  EXPECT_EQ(spent.status, 429) << spent.raw;
  EXPECT_EQ(spent.body["error"]["details"][0]["fieldViolations"][0]["field"], "budget");
  EXPECT_GE(Get(base).body["planningSecondsUsed"].get<double>(), 1.99);
}

}  // namespace
}  // namespace npfkct::server
