// The session state machine on its own, without HTTP: plan, observe, cancel, delete, restore, and
// every error it answers, named in the domain's spelling (the API layer maps them to the wire).
#include "npfkct/server/session.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>

#include "npfkct/api/api.h"
#include "npfkct/server/session_store.h"

namespace npfkct::server {
namespace {

using object_search::World;

// One table in a 6 x 6 m room, the robot beside it.
World TableWorld() {
  api::WorldSpec spec;
  spec.furniture.push_back({"table", api::Box{{1.5, 0, 0.4}, 0.0, {0.8, 1.2, 0.8}}, true});
  spec.base_regions.push_back({{0.2, -0.6}, {0.6, 0.6}});
  return api::BuildWorld(spec, api::Limits()).value();
}

SessionConfig Config(const std::string& planner = "kct", object_search::OptionList options = {}) {
  SessionConfig c;
  c.id = "0123456789abcdef0123456789abcdef";
  c.planner.name = planner;
  c.planner.particles = 50;
  c.planner.options = std::move(options);
  c.seed = 11;
  return c;
}

std::unique_ptr<Session> Make(SessionConfig config = Config(),
                              SessionLimits limits = SessionLimits()) {
  auto s = Session::Create(std::move(config), TableWorld(), SamplerFactory(),
                           object_search::PlannerRegistry::BuiltIn(), limits);
  EXPECT_TRUE(s.ok()) << s.status().ToString();
  return std::move(s).value();
}

const FieldViolation& Violation(const Status& s) {
  static const FieldViolation none;
  return s.field_violations().empty() ? none : s.field_violations()[0];
}

// The observation of a MOVE that saw nothing, from where the robot was sent.
api::ObserveRequest SawNothing(const api::PlanReply& plan) {
  api::ObserveRequest o;
  o.action_id = plan.action_id;
  o.robot_state = plan.action.configuration;
  return o;
}

// A directory store of its own per test (the memory store keeps nothing to restore from).
class SessionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("npfkct-session-" + std::to_string(getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    auto store = DirectoryStore::Open(dir_.string(), api::Limits(), 64 << 20);
    ASSERT_TRUE(store.ok()) << store.status().ToString();
    store_ = std::move(store).value();
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
  std::unique_ptr<SessionStore> store_;
};

TEST_F(SessionTest, PlanPendsAnActionAndObserveAnswersIt) {
  auto s = Make();
  ASSERT_TRUE(s->Save(store_.get()).ok());
  auto plan = s->Plan(Budget::Simulations(100), {}, store_.get());
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->action.type, api::ActionView::Type::kMove);  // nothing is known: look
  EXPECT_EQ(s->View().state, api::SessionState::kActionPending);
  EXPECT_EQ(s->View().pending->first, plan->action_id);
  // A second plan while the action is pending is refused, and changes nothing.
  auto again = s->Plan(Budget::Simulations(100), {}, store_.get());
  EXPECT_EQ(again.status().code(), StatusCode::kFailedPrecondition);
  auto observed = s->Observe(SawNothing(*plan), store_.get());
  ASSERT_TRUE(observed.ok()) << observed.status().ToString();
  EXPECT_FALSE(observed->done);
  EXPECT_EQ(observed->reward, -1.0);  // R_min: a step
  EXPECT_EQ(s->View().state, api::SessionState::kReady);
  EXPECT_EQ(s->View().step, 1);
  ASSERT_EQ(s->Steps().size(), 1u);
  EXPECT_TRUE(s->Steps()[0].outcome.has_value());
  // The same observation again: already observed.
  auto twice = s->Observe(SawNothing(*plan), store_.get());
  EXPECT_EQ(twice.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(Violation(twice.status()).field, "action_id");
  EXPECT_NE(twice.status().message().find("already observed"), std::string::npos);
}

TEST_F(SessionTest, ObservationErrorsNameTheirFieldAndChangeNothing) {
  auto s = Make();
  ASSERT_TRUE(s->Save(store_.get()).ok());
  // Nothing pending yet.
  api::ObserveRequest early;
  early.action_id = "a1-000000";
  auto none = s->Observe(early, store_.get());
  EXPECT_EQ(none.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(Violation(none.status()).field, "action_id");
  auto plan = s->Plan(Budget::Simulations(50), {}, store_.get());
  ASSERT_TRUE(plan.ok());
  // A stale id names the pending one.
  api::ObserveRequest stale = SawNothing(*plan);
  stale.action_id = "a9-ffffff";
  auto refused = s->Observe(stale, store_.get());
  EXPECT_EQ(Violation(refused.status()).field, "action_id");
  EXPECT_NE(refused.status().message().find(plan->action_id), std::string::npos);
  // After a MOVE the robot must say where it ended.
  api::ObserveRequest lost = SawNothing(*plan);
  lost.robot_state.reset();
  auto no_state = s->Observe(lost, store_.get());
  EXPECT_EQ(no_state.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(Violation(no_state.status()).field, "robot_state");
  // The guessed target's id is reserved.
  api::ObserveRequest reserved = SawNothing(*plan);
  object_search::ObjectDetection d;
  d.key = s->Belief()->objects[0].key;
  d.box = api::Box{{1.5, 0, 0.9}, 0.0, {0.1, 0.1, 0.1}};
  reserved.detections.push_back(d);
  auto taken = s->Observe(reserved, store_.get());
  EXPECT_EQ(Violation(taken.status()).field, "detections[0].id");
  // More objects than a session may know: refused whole.
  api::ObserveRequest crowd = SawNothing(*plan);
  for (int i = 0; i < object_search::kMaxObjects + 1; ++i) {
    object_search::ObjectDetection o;
    o.key = "box-" + std::to_string(i);
    o.box =
        api::Box{{1.2 + 0.01 * (i % 50), -0.4 + 0.016 * (i / 50), 0.85}, 0.0, {0.05, 0.05, 0.1}};
    crowd.detections.push_back(o);
  }
  auto crowded = s->Observe(crowd, store_.get());
  EXPECT_EQ(crowded.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(Violation(crowded.status()).field, "detections");
  // None of these changed the session: the action is still pending and nothing is known.
  EXPECT_EQ(s->View().state, api::SessionState::kActionPending);
  EXPECT_EQ(s->View().object_count, 0);
  EXPECT_TRUE(s->Observe(SawNothing(*plan), store_.get()).ok());
}

TEST_F(SessionTest, CreateNamesTheOptionOrModelItCannotUse) {
  auto bad = Session::Create(Config("kct", {{"search.max_depth", 0}}), TableWorld(),
                             SamplerFactory(), object_search::PlannerRegistry::BuiltIn(), {});
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(Violation(bad.status()).field, "planner.options.search.max_depth");
  SessionConfig with_model = Config("kct");
  with_model.planner.model = "filter.pt";
  auto model = Session::Create(with_model, TableWorld(), SamplerFactory(),
                               object_search::PlannerRegistry::BuiltIn(), {});
  ASSERT_FALSE(model.ok());
  EXPECT_EQ(Violation(model.status()).field, "planner.model");
  EXPECT_NE(model.status().message().find("only the npfkct planner"), std::string::npos);
  auto oracle = Session::Create(Config("oracle"), TableWorld(), SamplerFactory(),
                                object_search::PlannerRegistry::BuiltIn(), {});
  ASSERT_FALSE(oracle.ok());
  EXPECT_EQ(Violation(oracle.status()).field, "planner.name");
}

TEST_F(SessionTest, APlanReportsTheOptionsGivenAndUsed) {
  auto s = Make(Config("kct", {{"search.max_depth", 7}}));
  auto plan = s->Plan(Budget::Simulations(30), {}, store_.get());
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->summary.options_given, (object_search::OptionList{{"search.max_depth", 7}}));
  bool depth_used = false;
  for (const auto& [key, value] : plan->summary.options_used) {
    if (key == "search.max_depth") depth_used = value == 7;
  }
  EXPECT_TRUE(depth_used);
  EXPECT_FALSE(plan->summary.resolved.empty());  // kCT resolves w2, c_r, ...
  EXPECT_EQ(plan->budget.max_simulations, 30);
  EXPECT_GT(plan->budget.time_ms, 0.0);  // capped by the session's planning time
}

TEST_F(SessionTest, ASessionThatSpentItsPlanningTimeIsRefused) {
  SessionLimits limits;
  limits.max_plan_seconds = 0.005;  // less than a plan's least
  auto s = Make(Config(), limits);
  auto plan = s->Plan(Budget::Simulations(10), {}, store_.get());
  EXPECT_EQ(plan.status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(Violation(plan.status()).field, "budget");
}

TEST_F(SessionTest, CancelStopsARunningPlanAndDeleteAbortsIt) {
  for (bool del : {false, true}) {
    SCOPED_TRACE(del ? "delete" : "cancel");
    SessionConfig config = Config();
    config.id[0] = del ? 'd' : 'c';
    auto s = Make(config);
    ASSERT_TRUE(s->Save(store_.get()).ok());
    std::atomic<bool> started{false};
    StatusOr<api::PlanReply> plan = Status(StatusCode::kUnknown, "not run");
    std::thread planner([&] {
      plan = s->Plan(Budget::Time(30000), {}, store_.get(),
                     [&](const std::function<bool()>&, int) -> StatusOr<Session::SlotHold> {
                       started = true;
                       return Session::SlotHold();
                     });
    });
    while (!started) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    // A second request meanwhile is refused, not queued behind the plan.
    auto busy = s->Plan(Budget::Simulations(10), {}, store_.get());
    EXPECT_EQ(busy.status().code(), StatusCode::kAborted);
    if (del) {
      EXPECT_TRUE(s->Delete(store_.get()).ok());
    } else {
      s->Cancel();
    }
    planner.join();  // long before the 30 s: the plan stopped
    EXPECT_EQ(plan.status().code(), del ? StatusCode::kAborted : StatusCode::kCancelled);
    EXPECT_EQ(s->View().state, api::SessionState::kReady);
    EXPECT_EQ(store_->Load(s->id()).ok(), !del);
  }
}

TEST_F(SessionTest, ARestoredSessionGoesOnWhereItStopped) {
  auto s = Make(Config("kct", {{"search.max_depth", 6}}));
  ASSERT_TRUE(s->Save(store_.get()).ok());
  auto plan = s->Plan(Budget::Simulations(50), {}, store_.get());
  ASSERT_TRUE(plan.ok());
  auto loaded = store_->Load(s->id());
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  auto restored = Session::Restore(std::move(loaded->record), loaded->version, SamplerFactory(),
                                   object_search::PlannerRegistry::BuiltIn(), SessionLimits());
  ASSERT_TRUE(restored.ok()) << restored.status().ToString();
  Session& r = **restored;
  EXPECT_EQ(r.View().state, api::SessionState::kActionPending);
  EXPECT_EQ(r.View().pending->first, plan->action_id);
  EXPECT_EQ(r.View().planner.options, s->View().planner.options);
  EXPECT_TRUE(r.View().planner.takes_model == s->View().planner.takes_model);
  // The restored copy takes the observation of the action planned before.
  auto observed = r.Observe(SawNothing(*plan), store_.get());
  ASSERT_TRUE(observed.ok()) << observed.status().ToString();
  EXPECT_EQ(r.View().step, 1);
  EXPECT_TRUE(r.Plan(Budget::Simulations(50), {}, store_.get()).ok());
  // The first copy's save now fails: the store holds a newer version.
  EXPECT_FALSE(s->Observe(SawNothing(*plan), store_.get()).ok());
  EXPECT_TRUE(s->stale());
}

// A REMOVE the robot reports it could not make: the object stays in the belief as unremovable
// (also after a restore), and the session does not send the robot back to the same removal.
TEST_F(SessionTest, ARemovalTheRobotCouldNotMakeIsNotPlannedAgain) {
  auto s = Make();
  ASSERT_TRUE(s->Save(store_.get()).ok());
  // A box on the table whose every face looks like the target: declare it, then remove it.
  object_search::ObjectDetection box;
  box.key = "mug";
  box.box = api::Box{{1.25, 0, 0.85}, 0.0, {0.1, 0.1, 0.1}};
  for (int k = 0; k < 8; ++k) box.faces.push_back({k, 0.99});
  api::PlanReply plan;
  for (int step = 0; step < 8; ++step) {
    auto planned = s->Plan(Budget::Simulations(300), {}, store_.get());
    ASSERT_TRUE(planned.ok()) << planned.status().ToString();
    plan = *planned;
    if (plan.action.type == api::ActionView::Type::kRemove) break;
    api::ObserveRequest o = SawNothing(plan);
    if (plan.action.type != api::ActionView::Type::kMove) o.robot_state.reset();
    o.detections.push_back(box);
    ASSERT_TRUE(s->Observe(o, store_.get()).ok());
  }
  ASSERT_EQ(plan.action.type, api::ActionView::Type::kRemove) << "the target was never removed";
  EXPECT_EQ(plan.action.object_id, "mug");
  api::ObserveRequest failed;
  failed.action_id = plan.action_id;
  failed.succeeded = false;
  auto observed = s->Observe(failed, store_.get());
  ASSERT_TRUE(observed.ok()) << observed.status().ToString();
  EXPECT_FALSE(observed->done);
  EXPECT_EQ(observed->reward, -1000.0);  // R_ill
  const int mug = s->Belief()->FindObject("mug");
  ASSERT_GT(mug, 0);
  EXPECT_TRUE(s->Belief()->objects[mug].removal_failed);
  EXPECT_EQ(s->Belief()->objects[mug].status, object_search::kDeclaredTarget);
  // The restored session knows it too, and neither plans the removal again.
  auto loaded = store_->Load(s->id());
  ASSERT_TRUE(loaded.ok()) << loaded.status().ToString();
  auto restored = Session::Restore(std::move(loaded->record), loaded->version, SamplerFactory(),
                                   object_search::PlannerRegistry::BuiltIn(), SessionLimits());
  ASSERT_TRUE(restored.ok()) << restored.status().ToString();
  EXPECT_TRUE((*restored)->Belief()->objects[mug].removal_failed);
  auto next = (*restored)->Plan(Budget::Simulations(300), {}, store_.get());
  ASSERT_TRUE(next.ok()) << next.status().ToString();
  EXPECT_NE(next->action.type, api::ActionView::Type::kRemove);
}

}  // namespace
}  // namespace npfkct::server
