#include "npfkct/server/session.h"

#include <cmath>
#include <cstring>
#include <ctime>
#include <optional>
#include <random>

#include "npfkct/perception/perception.h"
#include "npfkct/server/codec.h"
#include "npfkct/server/filter_samplers.h"

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

// The raw sensor data of an observation as a perception frame; errors name the field.
StatusOr<perception::SensorFrame> FrameFromJson(const json& body,
                                                const object_search::RobotConfig& reported) {
  perception::SensorFrame frame;
  frame.reported = reported;
  const json& pc = body.at("pointCloud");
  if (!pc.is_object()) return InvalidArgumentError("pointCloud: expected an object");
  for (auto it = pc.begin(); it != pc.end(); ++it) {
    if (it.key() != "frame" && it.key() != "fields" && it.key() != "data") {
      return InvalidArgumentError("pointCloud." + it.key() + ": unknown field");
    }
  }
  const std::string where = pc.contains("frame") && pc.at("frame").is_string()
                                ? pc.at("frame").get<std::string>()
                                : std::string(pc.contains("frame") ? "?" : "camera");
  if (where != "camera" && where != "map") {
    return InvalidArgumentError(
        "pointCloud.frame: expected \"camera\" (optical frame: x right, "
        "y down, z forward) or \"map\"");
  }
  frame.cloud_in_map_frame = where == "map";
  if (pc.contains("fields") && !pc.at("fields").is_string()) {
    return InvalidArgumentError("pointCloud.fields: expected \"xyz\" or \"xyzrgb\"");
  }
  const std::string fields = pc.value("fields", std::string("xyz"));
  if (!pc.contains("data") || !pc.at("data").is_string()) {
    return InvalidArgumentError("pointCloud.data: missing or not a base64 string");
  }
  auto cloud = perception::DecodeCloud(pc.at("data").get<std::string>(), fields, "pointCloud");
  if (!cloud.ok()) return cloud.status();
  frame.cloud = *cloud;
  if (body.contains("camera")) {
    const json& c = body.at("camera");
    if (!c.is_object()) return InvalidArgumentError("camera: expected an object");
    for (auto it = c.begin(); it != c.end(); ++it) {
      static const std::set<std::string> kKeys = {"width", "height", "fx", "fy", "cx", "cy"};
      if (!kKeys.count(it.key()))
        return InvalidArgumentError("camera." + it.key() + ": unknown field");
      if (!it.value().is_number()) {
        return InvalidArgumentError("camera." + it.key() + ": expected a number");
      }
    }
    for (const char* key : {"width", "height"}) {
      if (c.contains(key) && !c.at(key).is_number_integer()) {
        return InvalidArgumentError(std::string("camera.") + key + ": expected an integer");
      }
    }
    auto& in = frame.intrinsics;
    if (c.contains("width"))
      in.width = static_cast<int>(std::clamp<int64_t>(c.at("width").get<int64_t>(), -1, 1 << 20));
    if (c.contains("height"))
      in.height = static_cast<int>(std::clamp<int64_t>(c.at("height").get<int64_t>(), -1, 1 << 20));
    in.fx = c.value("fx", in.fx);
    in.fy = c.value("fy", in.fy);
    in.cx = c.value("cx", in.cx);
    in.cy = c.value("cy", in.cy);
  }
  if (Status s = frame.intrinsics.Validate(); !s.ok()) return s;
  if (body.contains("image")) {
    const json& im = body.at("image");
    if (!im.is_object()) return InvalidArgumentError("image: expected an object");
    for (auto it = im.begin(); it != im.end(); ++it) {
      if (it.key() != "encoding" && it.key() != "data") {
        return InvalidArgumentError("image." + it.key() + ": unknown field");
      }
    }
    if (im.contains("encoding") && (!im.at("encoding").is_string() ||
                                    (im.at("encoding") != "png" && im.at("encoding") != "jpeg"))) {
      return InvalidArgumentError("image.encoding: expected \"png\" or \"jpeg\"");
    }
    if (!im.contains("data") || !im.at("data").is_string()) {
      return InvalidArgumentError("image.data: missing or not a base64 string");
    }
    auto decoded = perception::DecodeImage(im.at("data").get<std::string>(), "image");
    if (!decoded.ok()) return decoded.status();
    frame.image = *decoded;
  }
  if (body.contains("semanticScores")) {
    const json& scores = body.at("semanticScores");
    if (!scores.is_object() || scores.size() > 256) {
      return InvalidArgumentError("semanticScores: expected an object of at most 256 scores");
    }
    for (auto it = scores.begin(); it != scores.end(); ++it) {
      const json& v = it.value();
      if (!v.is_number() || !(v.get<double>() >= 0.0 && v.get<double>() <= 1.0)) {
        return InvalidArgumentError("semanticScores." + it.key() + ": expected a number in [0, 1]");
      }
      frame.semantic_scores[it.key()] = v.get<double>();
    }
  }
  return frame;
}

std::string FloatsToBase64(const std::vector<float>& v) {
  std::string bytes(v.size() * sizeof(float), '\0');
  if (!v.empty()) std::memcpy(bytes.data(), v.data(), bytes.size());
  return perception::Base64Encode(bytes);
}

StatusOr<std::vector<float>> FloatsFromBase64(const std::string& text) {
  auto bytes = perception::Base64Decode(text);
  if (!bytes.ok() || bytes->size() % sizeof(float) != 0) {
    return Status(StatusCode::kDataLoss, "snapshot: bad float array");
  }
  std::vector<float> v(bytes->size() / sizeof(float));
  if (!v.empty()) std::memcpy(v.data(), bytes->data(), bytes->size());
  return v;
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

Status TargetSpec::Validate() const {
  if (description.size() > 2000) {
    return InvalidArgumentError("target.description: at most 2000 characters");
  }
  if (photos.size() > 16) return InvalidArgumentError("target.photos: at most 16 photos");
  for (size_t i = 0; i < photos.size(); ++i) {
    const std::string field = "target.photos[" + std::to_string(i) + "]";
    auto image = perception::DecodeImage(photos[i], field);
    if (!image.ok()) {
      // DecodeImage names "<field>.data"; photos are plain strings.
      std::string m = image.status().message();
      if (m.rfind(field + ".data", 0) == 0) m = field + m.substr(field.size() + 5);
      return InvalidArgumentError(m);
    }
    if (image->cols < 16 || image->rows < 16) {
      return InvalidArgumentError(field + ": at least 16 x 16 pixels");
    }
  }
  return OkStatus();
}

Session::~Session() = default;

StatusOr<std::unique_ptr<Session>> Session::Create(std::string id, std::string display_name,
                                                   World world, PlannerSpec spec, TargetSpec target,
                                                   uint64_t seed, double ttl_seconds,
                                                   const SamplerFactory& samplers) {
  if (Status st = target.Validate(); !st.ok()) return st;
  std::unique_ptr<Session> s(new Session());
  s->target_ = std::move(target);
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
  model_ =
      std::make_unique<object_search::ObjectSearchModel>(std::make_shared<const World>(*world_));
  std::shared_ptr<CandidateSampler<object_search::State>> sampler;
  if (samplers) {
    auto made = samplers(spec_, *model_);
    if (!made.ok()) return made.status();
    sampler = *made;
  }
  // Net_sam's "filter.*" options went to the sampler factory; the planner gets the rest.
  std::vector<std::pair<std::string, double>> planner_options;
  for (const auto& kv : spec_.options) {
    if (!IsFilterOption(kv.first)) planner_options.push_back(kv);
  }
  auto planner = object_search::MakeSearchPlanner(spec_.name, *model_, planner_options, sampler);
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

perception::Perception& Session::Perceiver() {
  if (!perception_) {
    perception::TargetModel target;
    for (const std::string& photo : target_.photos) {
      auto image = perception::DecodeImage(photo, "target.photos");
      if (image.ok()) target.photos.push_back(*image);  // validated at creation
    }
    perception_ = std::make_unique<perception::Perception>(*world_, std::move(target),
                                                           perception::PerceptionOptions{});
  }
  return *perception_;
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
  j["planner"] = {
      {"name", spec_.name}, {"particles", spec_.particles}, {"options", spec_.options_json}};
  if (!spec_.model_path.empty()) j["planner"]["modelPath"] = spec_.model_path;
  j["seed"] = std::to_string(seed_);
  j["target"] = {{"description", target_.description},
                 {"photoCount", static_cast<int>(target_.photos.size())}};
  if (perception_) j["perceptionTracks"] = perception_->tracks();
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
    j["pendingAction"] = {
        {"kind", pending_action_.kind},
        {"x", std::vector<double>(pending_action_.x.data(),
                                  pending_action_.x.data() + pending_action_.x.size())}};
  }
  j["world"] = WorldToJson(*world_);
  j["target"] = {{"description", target_.description}, {"photos", target_.photos}};
  if (perception_) {
    int next_id = 0;
    json tracks = json::array();
    for (const perception::TrackState& t : perception_->SaveTracks(&next_id)) {
      tracks.push_back(
          {{"id", t.id}, {"surface", t.surface}, {"points", FloatsToBase64(t.points)}});
    }
    j["perception"] = {{"nextId", next_id}, {"tracks", tracks}};
  }
  return j;
}

StatusOr<std::unique_ptr<Session>> Session::Restore(const json& j, const SamplerFactory& samplers) {
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
  if (j.contains("target")) {
    const json& t = j.at("target");
    if (!t.is_object()) return bad("target");
    s->target_.description = t.value("description", std::string());
    if (t.contains("photos")) {
      if (!t.at("photos").is_array()) return bad("target photos");
      for (const json& photo : t.at("photos")) {
        if (!photo.is_string()) return bad("target photos");
        s->target_.photos.push_back(photo.get<std::string>());
      }
    }
    if (!s->target_.Validate().ok()) return bad("target photos");
  }
  if (j.contains("perception")) {
    const json& pj = j.at("perception");
    if (!pj.is_object() || !pj.contains("tracks") || !pj.at("tracks").is_array()) {
      return bad("perception");
    }
    std::vector<perception::TrackState> tracks;
    for (const json& tj : pj.at("tracks")) {
      if (!tj.is_object() || !tj.contains("points") || !tj.at("points").is_string()) {
        return bad("perception track");
      }
      perception::TrackState t;
      t.id = tj.value("id", std::string());
      t.surface = tj.value("surface", -1);
      auto points = FloatsFromBase64(tj.at("points").get<std::string>());
      if (!points.ok()) return points.status();
      t.points = std::move(points).value();
      tracks.push_back(std::move(t));
    }
    if (!s->Perceiver().RestoreTracks(tracks, pj.value("nextId", 0)).ok()) {
      return bad("perception tracks");
    }
  }
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
  out["stats"] = {{"simulations", d.stats.simulations}, {"elapsedMs", d.stats.elapsed_ms},
                  {"teardownMs", d.stats.teardown_ms},  {"treeNodes", d.stats.tree_nodes},
                  {"maxDepth", d.stats.max_depth},      {"rootActions", d.stats.root_actions},
                  {"rootVisits", d.stats.root_visits},  {"reusedVisits", d.stats.reused_visits},
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
  static const std::set<std::string> kKnown = {"actionId",   "succeeded",     "robotState",
                                               "detections", "pointCloud",    "image",
                                               "camera",     "semanticScores"};
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
  const bool raw = body.contains("pointCloud") || body.contains("image");
  if (raw && body.contains("detections")) {
    return InvalidArgumentError(
        "detections: send either detections or raw sensor data (pointCloud, image), not both");
  }
  if (body.contains("image") && !body.contains("pointCloud")) {
    return InvalidArgumentError(
        "pointCloud: missing; an image is used with the point cloud taken with it");
  }
  for (const char* key : {"camera", "semanticScores"}) {
    if (body.contains(key) && !raw) {
      return InvalidArgumentError(std::string(key) + ": only used with a pointCloud");
    }
  }
  auto obs = ObservationFromJson(body, *world_, is_move && succeeded);
  if (!obs.ok()) return obs.status();
  std::optional<perception::SensorFrame> frame;
  if (raw) {
    auto parsed = FrameFromJson(body, obs->achieved);
    if (!parsed.ok()) return parsed.status();
    frame = std::move(parsed).value();
  }

  // Apply to a copy and swap on success: a rejected observation changes nothing.
  World next = *world_;
  bool done = false;
  double reward = 0.0;
  const auto& p = next.params;
  using object_search::ActionOutcome;
  ActionOutcome outcome = succeeded ? ActionOutcome::kMoved : ActionOutcome::kIllegal;
  if (!is_move && succeeded) {
    const int object = object_search::KindObject(pending_action_.kind);
    const int offset = object_search::KindOffset(pending_action_.kind);
    outcome = object_search::SuccessfulOutcome(offset, next.objects[object].status);
    done = outcome == ActionOutcome::kRemovedTarget;
    if (Status s = object_search::ApplyDiscreteOutcome(&next, object, offset, true); !s.ok()) {
      return s;
    }
  }
  reward = object_search::RewardOf(p, outcome);
  // Raw data: the perception pipeline turns the frame into the corrected pose and detections.
  // Its tracks are restored if anything below fails, so a rejected observation changes nothing.
  std::vector<perception::TrackState> saved_tracks;
  int saved_next_id = 0;
  std::optional<perception::PerceptionResult> perceived;
  if (frame) {
    perception::Perception& perceiver = Perceiver();
    saved_tracks = perceiver.SaveTracks(&saved_next_id);
    if (!is_move && succeeded &&
        object_search::KindOffset(pending_action_.kind) ==
            object_search::kRemoveOffset) {  // the object left the scene
      perceiver.DropTrack(world_->objects[object_search::KindObject(pending_action_.kind)].key);
    }
    auto result = perceiver.Process(*frame);
    if (!result.ok()) {
      (void)perceiver.RestoreTracks(saved_tracks, saved_next_id);
      return result.status();
    }
    obs->achieved = result->observation.achieved;
    obs->objects = result->observation.objects;
    perceived = std::move(result).value();
  }
  auto rollback = [&] {
    if (frame) (void)perception_->RestoreTracks(saved_tracks, saved_next_id);
  };
  std::vector<int> detected;
  bool new_objects = false;
  for (const auto& det : obs->objects) {
    const int index = next.FindObject(det.key);
    new_objects |= index < 0;
    detected.push_back(index);
  }
  const object_search::Observation key = model_->RealObservationKey(detected);
  if (Status s = object_search::ApplyRealObservation(&next, *obs); !s.ok()) {
    rollback();
    return Status(s.code(), s.message().rfind("objects[", 0) == 0
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
  if (perceived) {
    const perception::PerceptionResult& r = *perceived;
    json objects = json::array();
    for (const auto& d : r.observation.objects) {
      json faces = json::array();
      for (const auto& f : d.faces) faces.push_back({{"corner", f.corner}, {"score", f.score}});
      objects.push_back({{"id", d.key},
                         {"box", BoxToJson(d.box)},
                         {"moveability", d.moveability},
                         {"faces", faces}});
    }
    out["perception"] = {
        {"robotState", ConfigToJson(r.observation.achieved)},
        {"registration",
         std::isfinite(r.fitness) ? (r.used_ransac ? "RANSAC_ICP" : "ICP") : "SKIPPED"},
        {"fitness", std::isfinite(r.fitness) ? json(r.fitness) : json(nullptr)},
        {"clusters", r.clusters},
        {"detections", objects},
        {"timingsMs",
         {{"registration", r.timings.registration},
          {"segmentation", r.timings.segmentation},
          {"association", r.timings.association},
          {"detection", r.timings.detection},
          {"total", r.timings.total}}}};
  }
  out["session"] = Resource();
  return out;
}

json Session::Belief() const { return BeliefToJson(*world_); }

}  // namespace npfkct::server
