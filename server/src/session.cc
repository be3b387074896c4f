#include "npfkct/server/session.h"

#include <cmath>
#include <ctime>
#include <random>

#include "npfkct/server/codec.h"

namespace npfkct::server {
namespace {

using object_search::World;

const char* StateName(Session::State s) {
  switch (s) {
    case Session::State::kReady:
      return "READY";
    case Session::State::kActionPending:
      return "ACTION_PENDING";
    case Session::State::kDone:
      return "DONE";
  }
  return "READY";
}

std::string RandomHex(int bytes) {
  static thread_local std::mt19937_64 gen(std::random_device{}());
  static const char* kHex = "0123456789abcdef";
  std::string out;
  for (int i = 0; i < bytes; ++i) {
    const uint64_t v = gen();
    out += kHex[v & 15];
    out += kHex[(v >> 4) & 15];
  }
  return out;
}

int64_t Millis(std::chrono::system_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
}

}  // namespace

std::string Rfc3339(std::chrono::system_clock::time_point t) {
  const int64_t ms = Millis(t);
  const std::time_t secs = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<int>(ms % 1000));
  return buf;
}

StatusOr<std::unique_ptr<Session>> Session::Create(std::string id, std::string display_name,
                                                   World world, PlannerSpec spec, uint64_t seed,
                                                   double ttl_seconds,
                                                   const SamplerFactory& samplers) {
  std::unique_ptr<Session> s(new Session());
  s->id_ = std::move(id);
  s->display_name_ = std::move(display_name);
  s->spec_ = std::move(spec);
  s->seed_ = seed;
  s->ttl_seconds_ = ttl_seconds;
  s->world_ = std::make_shared<World>(std::move(world));
  s->create_time_ = s->update_time_ = std::chrono::system_clock::now();
  s->last_used_ = std::chrono::steady_clock::now();
  if (Status st = s->Init(samplers); !st.ok()) return st;
  return s;
}

Status Session::Init(const SamplerFactory& samplers) {
  Reseed();
  model_ = std::make_unique<object_search::ObjectSearchModel>(
      std::make_shared<const World>(*world_));
  std::shared_ptr<CandidateSampler<object_search::State>> sampler;
  if (samplers) {
    auto made = samplers(spec_, *model_);
    if (!made.ok()) return made.status();
    sampler = *made;
  }
  auto planner = object_search::MakeSearchPlanner(spec_.name, *model_, spec_.options, sampler);
  if (!planner.ok()) {
    const std::string& m = planner.status().message();
    if (m.rfind("unknown planner", 0) == 0) {
      return InvalidArgumentError("planner.name: " + m);
    }
    return InvalidArgumentError("planner.options: " + m);
  }
  planner_ = std::move(planner).value();
  planner_->SetBelief(FreshBelief());
  return OkStatus();
}

void Session::Reseed() {
  // A function of the seed and the step only, so that a restored session continues identically.
  rng_.Seed(HashMix(seed_ ^ HashMix(static_cast<uint64_t>(actions_) + 0x51ed27)));
}

ParticleBelief<object_search::State> Session::FreshBelief() {
  return ParticleBelief<object_search::State>::FromInitial(*model_, spec_.particles, rng_);
}

double Session::IdleSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - last_used_).count();
}

void Session::Touch() { last_used_ = std::chrono::steady_clock::now(); }

json Session::Resource() const {
  json j;
  j["name"] = "sessions/" + id_;
  j["id"] = id_;
  if (!display_name_.empty()) j["displayName"] = display_name_;
  j["state"] = StateName(state_);
  j["createTime"] = Rfc3339(create_time_);
  j["updateTime"] = Rfc3339(update_time_);
  j["ttlSeconds"] = ttl_seconds_;
  j["planner"] = {{"name", spec_.name},
                  {"particles", spec_.particles},
                  {"options", spec_.options_json}};
  if (!spec_.model_path.empty()) j["planner"]["modelPath"] = spec_.model_path;
  j["seed"] = std::to_string(seed_);
  j["step"] = world_->steps;
  j["robot"] = ConfigToJson(world_->robot_config);
  j["objectCount"] = static_cast<int>(world_->objects.size()) - 1;
  if (state_ == State::kActionPending) {
    j["pendingAction"] = {{"actionId", pending_action_id_},
                          {"action", ActionToJson(pending_action_, *world_)}};
  }
  j["totalSimulations"] = total_simulations_;
  return j;
}

json Session::Snapshot() const {
  json j;
  j["version"] = 1;
  j["id"] = id_;
  j["displayName"] = display_name_;
  j["planner"] = {{"name", spec_.name},
                  {"particles", spec_.particles},
                  {"options", spec_.options_json},
                  {"modelPath", spec_.model_path}};
  j["seed"] = std::to_string(seed_);
  j["ttlSeconds"] = ttl_seconds_;
  j["state"] = StateName(state_);
  j["actions"] = actions_;
  j["totalSimulations"] = total_simulations_;
  j["createTimeMs"] = Millis(create_time_);
  j["updateTimeMs"] = Millis(update_time_);
  j["lastActionId"] = last_action_id_;
  if (state_ == State::kActionPending) {
    j["pendingActionId"] = pending_action_id_;
    j["pendingAction"] = {{"kind", pending_action_.kind},
                          {"x", std::vector<double>(pending_action_.x.data(),
                                                    pending_action_.x.data() +
                                                        pending_action_.x.size())}};
  }
  j["world"] = WorldToJson(*world_);
  return j;
}

StatusOr<std::unique_ptr<Session>> Session::Restore(const json& j,
                                                    const SamplerFactory& samplers) {
  auto bad = [](const std::string& what) {
    return Status(StatusCode::kDataLoss, "snapshot: " + what);
  };
  if (!j.is_object() || j.value("version", 0) != 1) return bad("unknown version");
  if (!j.contains("id") || !j.at("id").is_string() || !j.contains("world") ||
      !j.contains("planner") || !j.at("planner").is_object()) {
    return bad("missing fields");
  }
  auto world = WorldFromJson(j.at("world"));
  if (!world.ok()) return world.status();
  std::unique_ptr<Session> s(new Session());
  s->id_ = j.at("id").get<std::string>();
  s->display_name_ = j.value("displayName", std::string());
  const json& p = j.at("planner");
  s->spec_.name = p.value("name", std::string("npfkct"));
  s->spec_.particles = p.value("particles", 300);
  s->spec_.model_path = p.value("modelPath", std::string());
  s->spec_.options_json = p.value("options", json::object());
  for (auto it = s->spec_.options_json.begin(); it != s->spec_.options_json.end(); ++it) {
    if (it.value().is_number()) {
      s->spec_.options.emplace_back(SnakeCase(it.key()), it.value().get<double>());
    } else if (it.value().is_boolean()) {
      s->spec_.options.emplace_back(SnakeCase(it.key()), it.value().get<bool>() ? 1.0 : 0.0);
    }
  }
  try {
    s->seed_ = std::stoull(j.value("seed", std::string("0")));
  } catch (...) {
    return bad("seed");
  }
  s->ttl_seconds_ = j.value("ttlSeconds", 3600.0);
  s->actions_ = j.value("actions", int64_t{0});
  s->total_simulations_ = j.value("totalSimulations", int64_t{0});
  s->create_time_ = std::chrono::system_clock::time_point(
      std::chrono::milliseconds(j.value("createTimeMs", int64_t{0})));
  s->update_time_ = std::chrono::system_clock::time_point(
      std::chrono::milliseconds(j.value("updateTimeMs", int64_t{0})));
  s->last_action_id_ = j.value("lastActionId", std::string());
  s->last_used_ = std::chrono::steady_clock::now();
  s->world_ = std::make_shared<World>(std::move(world).value());
  const std::string state = j.value("state", std::string("READY"));
  if (Status st = s->Init(samplers); !st.ok()) return st;
  if (state == "DONE") s->state_ = State::kDone;
  if (state == "ACTION_PENDING") {
    if (!j.contains("pendingAction") || !j.at("pendingAction").is_object()) {
      return bad("pending action");
    }
    const json& pa = j.at("pendingAction");
    s->pending_action_.kind = pa.value("kind", 0);
    const std::vector<double> x = pa.value("x", std::vector<double>());
    if (x.size() > static_cast<size_t>(kMaxActionDim)) return bad("pending action");
    s->pending_action_.x = ActionVec(static_cast<Eigen::Index>(x.size()));
    for (size_t i = 0; i < x.size(); ++i) s->pending_action_.x[i] = x[i];
    s->pending_action_id_ = j.value("pendingActionId", std::string());
    s->state_ = State::kActionPending;
  }
  return s;
}

StatusOr<json> Session::Plan(const Budget& budget) {
  if (state_ == State::kDone) {
    return FailedPreconditionError("the target was removed: session " + id_ + " is done");
  }
  if (state_ == State::kActionPending) {
    return FailedPreconditionError("action " + pending_action_id_ +
                                   " is pending: POST :observe with its outcome first");
  }
  Decision<HybridAction> d = planner_->Plan(budget, rng_);
  if (!d.status.ok()) {
    if (d.status.code() == StatusCode::kInvalidArgument) {
      return InvalidArgumentError("budget: " + d.status.message());
    }
    return d.status;
  }
  total_simulations_ += d.stats.simulations;
  last_planning_ms_ = d.stats.elapsed_ms;
  ++actions_;
  pending_action_ = d.action;
  char id[64];
  std::snprintf(id, sizeof id, "a%lld-%s", static_cast<long long>(actions_), RandomHex(6).c_str());
  pending_action_id_ = id;
  state_ = State::kActionPending;
  update_time_ = std::chrono::system_clock::now();
  json out;
  out["actionId"] = pending_action_id_;
  out["action"] = ActionToJson(d.action, *world_);
  out["expectedValue"] = d.value;
  out["stats"] = {{"simulations", d.stats.simulations},
                  {"elapsedMs", d.stats.elapsed_ms},
                  {"teardownMs", d.stats.teardown_ms},
                  {"treeNodes", d.stats.tree_nodes},
                  {"maxDepth", d.stats.max_depth},
                  {"rootActions", d.stats.root_actions},
                  {"rootVisits", d.stats.root_visits},
                  {"reusedVisits", d.stats.reused_visits},
                  {"refinements", d.stats.refinements}};
  const CandidateStats cs = planner_->candidate_stats();
  if (cs.sampled > 0) {
    out["stats"]["candidates"] = {
        {"sampled", cs.sampled}, {"accepted", cs.accepted}, {"elapsedMs", cs.elapsed_ms}};
  }
  out["session"] = Resource();
  return out;
}

StatusOr<json> Session::Observe(const json& body) {
  if (!body.is_object()) return InvalidArgumentError("body: expected a JSON object");
  static const std::set<std::string> kKnown = {"actionId",   "succeeded", "robotState",
                                                "detections", "pointCloud", "image"};
  for (auto it = body.begin(); it != body.end(); ++it) {
    if (!kKnown.count(it.key())) return InvalidArgumentError(it.key() + ": unknown field");
  }
  if (!body.contains("actionId") || !body.at("actionId").is_string()) {
    return InvalidArgumentError("actionId: missing or not a string");
  }
  const std::string action_id = body.at("actionId").get<std::string>();
  if (state_ != State::kActionPending) {
    if (action_id == last_action_id_ && !action_id.empty()) {
      return FailedPreconditionError("actionId: " + action_id + " was already observed");
    }
    return FailedPreconditionError("actionId: no action is pending (POST :plan first)");
  }
  if (action_id != pending_action_id_) {
    return FailedPreconditionError("actionId: '" + action_id + "' is stale or unknown; the " +
                                   "pending action is " + pending_action_id_);
  }
  bool succeeded = true;
  if (body.contains("succeeded")) {
    if (!body.at("succeeded").is_boolean()) {
      return InvalidArgumentError("succeeded: expected true or false");
    }
    succeeded = body.at("succeeded").get<bool>();
  }
  const bool is_move = pending_action_.kind == object_search::kMoveKind;
  if ((body.contains("pointCloud") || body.contains("image")) && !body.contains("detections")) {
    return Status(StatusCode::kUnimplemented,
                  "raw point clouds and images need the perception pipeline, which this server "
                  "does not run yet: send detections");
  }
  auto obs = ObservationFromJson(body, *world_, is_move && succeeded);
  if (!obs.ok()) return obs.status();

  // Apply to a copy and swap on success: a rejected observation changes nothing.
  World next = *world_;
  bool done = false;
  double reward = 0.0;
  const auto& p = next.params;
  if (!is_move) {
    const int object = object_search::KindObject(pending_action_.kind);
    const int offset = object_search::KindOffset(pending_action_.kind);
    if (succeeded) {
      if (offset == 2 && next.objects[object].status == object_search::kDeclaredTarget) {
        done = true;
        reward = p.r_max;
      } else {
        reward = offset == 0 ? p.r_ct : offset == 1 ? p.r_co : 2.0 * p.r_min;
      }
      if (Status s = object_search::ApplyDiscreteOutcome(&next, object, offset, true); !s.ok()) {
        return s;
      }
    } else {
      reward = p.r_ill;
    }
  } else {
    reward = succeeded ? p.r_min : p.r_ill;
  }
  std::vector<int> detected;
  bool new_objects = false;
  for (const auto& det : obs->objects) {
    const int index = next.FindObject(det.key);
    new_objects |= index < 0;
    detected.push_back(index);
  }
  const object_search::Observation key = model_->RealObservationKey(detected);
  if (Status s = object_search::ApplyRealObservation(&next, *obs); !s.ok()) {
    return InvalidArgumentError(s.message().rfind("objects[", 0) == 0
                                    ? "detections" + s.message().substr(7)
                                    : s.message());
  }
  *world_ = std::move(next);
  model_->SetWorld(std::make_shared<const World>(*world_));
  planner_->OnWorldChanged();
  total_reward_estimate_ += reward;
  last_action_id_ = pending_action_id_;
  pending_action_id_.clear();
  state_ = done ? State::kDone : State::kReady;
  Reseed();
  if (!done) {
    auto belief = FreshBelief();
    if (new_objects) {
      planner_->SetBelief(std::move(belief));
    } else {
      planner_->AdvanceTo(pending_action_, key, std::move(belief));
    }
  }
  update_time_ = std::chrono::system_clock::now();
  json out;
  out["done"] = done;
  out["reward"] = reward;
  out["session"] = Resource();
  return out;
}

json Session::Belief() const { return BeliefToJson(*world_); }

}  // namespace npfkct::server
