// Session records as snapshot bytes.
#include <algorithm>
#include <chrono>
#include <cstring>

#include "json_util.h"
#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/object_search/model.h"
#include "step_codec.h"
#include "world_codec.h"

namespace npfkct::api {
namespace {

using internal::json;

// Version 3: the target's photos kept apart (a server that knows version 2 only refuses such a
// record instead of reading, and then saving, a session without photos).
constexpr int kRecordVersion = 2;
constexpr int kRecordVersionPhotosApart = 3;
constexpr int kPhotosVersion = 1;
constexpr int kSummaryVersion = 1;

const char* StateName(SessionState s) {
  return s == SessionState::kDone            ? "DONE"
         : s == SessionState::kActionPending ? "ACTION_PENDING"
                                             : "READY";
}

std::string FloatsBase64(const std::vector<float>& v) {
  std::string bytes(v.size() * sizeof(float), '\0');
  if (!v.empty()) std::memcpy(bytes.data(), v.data(), bytes.size());
  return Base64Encode(bytes);
}

Status Lost(const std::string& what) { return Status(StatusCode::kDataLoss, "snapshot: " + what); }

json PlannerJson(const PlannerSpec& p) {
  json options = json::array();
  for (size_t i = 0; i < p.options.size(); ++i) {
    options.push_back({{"key", CamelCase(p.options[i].first)},
                       {"value", p.options[i].second},
                       {"bool", i < p.option_is_bool.size() && p.option_is_bool[i]}});
  }
  return {{"name", p.name},
          {"particles", p.particles},
          {"model", p.model},
          {"takesModel", p.takes_model},
          {"options", options}};
}

Status ReadPlanner(const json& j, const Limits& limits, PlannerSpec* out) {
  const json p = j.value("planner", json::object());
  out->name = internal::String(p, "name", "npfkct");
  out->particles = static_cast<int>(internal::Integer(p, "particles", 300));
  if (out->particles < 1 || out->particles > limits.max_particles) return Lost("planner particles");
  out->model = internal::String(p, "model");
  if (!out->model.empty() && !IsModelName(out->model)) return Lost("planner model");
  // Records written before "takesModel" was kept: npfkct was the one planner that took a model.
  out->takes_model =
      p.contains("takesModel") ? internal::Bool(p, "takesModel") : out->name == "npfkct";
  if (p.contains("options")) {
    const json& options = p.at("options");
    if (!options.is_array() || static_cast<int64_t>(options.size()) > limits.max_planner_options) {
      return Lost("planner options");
    }
    for (const json& o : options) {
      const std::string key = internal::String(o, "key");
      const double value = internal::Number(o, "value", std::nan(""));
      if (key.empty() || key.size() > 64) return Lost("planner option");
      // A record edited on disk or in the store must not restore what no request could set.
      if (Status s = internal::CheckPlannerOption(key, value, limits); !s.ok()) {
        return Lost(s.message());
      }
      out->options.emplace_back(SnakeCase(key), value);
      out->option_is_bool.push_back(internal::Bool(o, "bool"));
    }
  }
  return OkStatus();
}

StatusOr<uint64_t> ReadSeed(const json& j) {
  const std::string seed = internal::String(j, "seed", "0");
  if (seed.empty() || seed.size() > 20 ||
      seed.find_first_not_of("0123456789") != std::string::npos) {
    return Lost("seed");
  }
  return std::strtoull(seed.c_str(), nullptr, 10);
}

SessionState ReadState(const json& j) {
  const std::string state = internal::String(j, "state", "READY");
  return state == "DONE"             ? SessionState::kDone
         : state == "ACTION_PENDING" ? SessionState::kActionPending
                                     : SessionState::kReady;
}

// Each photo of a JSON array of base64 strings, checked as a request's photos are.
Status ReadPhotos(const json& photos, const Limits& limits, std::vector<std::string>* out) {
  if (!photos.is_array() || static_cast<int64_t>(photos.size()) > limits.max_photos) {
    return Lost("target photos");
  }
  for (const json& photo : photos) {
    if (!photo.is_string()) return Lost("target photo");
    auto bytes = Base64Decode(photo.get<std::string>(), "photo");
    if (!bytes.ok()) return Lost("target photo");
    auto info = ProbeImage(*bytes, "photo");
    if (!info.ok() || info->width * info->height > limits.max_photo_pixels) {
      return Lost("target photo");
    }
    out->push_back(std::move(bytes).value());
  }
  return OkStatus();
}

json PhotosJson(const std::vector<std::string>& photos) {
  json out = json::array();
  for (const std::string& p : photos) out.push_back(Base64Encode(p));
  return out;
}

}  // namespace

std::string EncodePhotos(const std::vector<std::string>& photos) {
  return internal::Dump(json{{"version", kPhotosVersion}, {"photos", PhotosJson(photos)}});
}

StatusOr<std::vector<std::string>> DecodePhotos(std::string_view bytes, const Limits& limits) {
  auto parsed = internal::ParseBody(bytes, limits.max_json_depth, limits.max_photos + 16, false);
  if (!parsed.ok()) return Lost(parsed.status().message());
  const json& j = *parsed;
  if (!j.is_object() || internal::Integer(j, "version") != kPhotosVersion ||
      !j.contains("photos")) {
    return Lost("not a photos record");
  }
  std::vector<std::string> photos;
  if (Status s = ReadPhotos(j.at("photos"), limits, &photos); !s.ok()) return s;
  return photos;
}

std::string EncodeRecord(const SessionRecord& r, std::string_view photos_digest) {
  json j;
  j["version"] = photos_digest.empty() ? kRecordVersion : kRecordVersionPhotosApart;
  j["id"] = r.id;
  j["displayName"] = r.display_name;
  j["planner"] = PlannerJson(r.planner);
  j["seed"] = std::to_string(r.seed);
  j["ttlSeconds"] = r.ttl_seconds;
  j["state"] = StateName(r.state);
  j["actions"] = r.actions;
  j["totalSimulations"] = r.total_simulations;
  j["planningSecondsUsed"] = r.planning_seconds_used;
  j["createTimeMs"] = r.create_time_ms;
  j["updateTimeMs"] = r.update_time_ms;
  j["lastActionId"] = r.last_action_id;
  if (r.state == SessionState::kActionPending) {
    j["pendingActionId"] = r.pending_action_id;
    j["pendingAction"] = {
        {"kind", r.pending_action.kind},
        {"x", std::vector<double>(r.pending_action.x.data(),
                                  r.pending_action.x.data() + r.pending_action.x.size())}};
  }
  j["world"] = internal::WorldJson(r.world);
  j["target"] = {{"description", r.target.description}};
  if (photos_digest.empty()) {
    j["target"]["photos"] = PhotosJson(r.target.photos);
  } else {
    j["target"]["photosKeptApart"] = std::string(photos_digest);
  }
  if (r.perception) {
    json tracks = json::array();
    for (const perception::TrackState& t : r.perception->second) {
      tracks.push_back({{"id", t.id}, {"surface", t.surface}, {"points", FloatsBase64(t.points)}});
    }
    j["perception"] = {{"nextId", r.perception->first}, {"tracks", tracks}};
  }
  if (!r.history.empty()) {
    json history = json::array();
    for (const StepRecord& step : r.history) history.push_back(internal::StepJson(step, true));
    j["history"] = history;
  }
  return internal::Dump(j);
}

namespace {

// The pending action of a record whose state is ACTION_PENDING (its kind is checked against the
// world once that is read).
Status ReadPendingAction(const json& j, SessionRecord* r) {
  r->pending_action_id = internal::String(j, "pendingActionId");
  const json pa = j.value("pendingAction", json::object());
  if (r->pending_action_id.empty() || !pa.contains("x") || !pa.at("x").is_array() ||
      pa.at("x").size() > static_cast<size_t>(kMaxActionDim)) {
    return Lost("pending action");
  }
  r->pending_action.kind = static_cast<int>(internal::Integer(pa, "kind", -1));
  r->pending_action.x = ActionVec(static_cast<Eigen::Index>(pa.at("x").size()));
  for (size_t i = 0; i < pa.at("x").size(); ++i) {
    if (!pa.at("x")[i].is_number()) return Lost("pending action");
    r->pending_action.x[static_cast<Eigen::Index>(i)] = pa.at("x")[i].get<double>();
  }
  return OkStatus();
}

// A session's perception tracks (its "perception" object), each within the limits.
Status ReadTracks(const json& pj, const Limits& limits, SessionRecord* r) {
  if (!pj.is_object() || !pj.contains("tracks") || !pj.at("tracks").is_array() ||
      static_cast<int64_t>(pj.at("tracks").size()) > 4 * limits.max_objects) {
    return Lost("perception");
  }
  std::vector<perception::TrackState> tracks;
  for (const json& tj : pj.at("tracks")) {
    if (!tj.is_object() || !tj.contains("points") || !tj.at("points").is_string()) {
      return Lost("perception track");
    }
    perception::TrackState t;
    t.id = internal::Utf8Prefix(internal::String(tj, "id"), limits.max_id_length);
    t.surface = static_cast<int>(internal::Integer(tj, "surface", -1));
    auto bytes = Base64Decode(tj.at("points").get<std::string>(), "points",
                              static_cast<size_t>(limits.max_points) * 12);
    if (!bytes.ok() || bytes->size() % (3 * sizeof(float)) != 0) return Lost("track points");
    t.points.resize(bytes->size() / sizeof(float));
    if (!t.points.empty()) std::memcpy(t.points.data(), bytes->data(), bytes->size());
    for (float v : t.points) {
      if (!std::isfinite(v) || std::abs(v) > limits.max_coordinate) return Lost("track points");
    }
    tracks.push_back(std::move(t));
  }
  const int64_t next_id = internal::Integer(pj, "nextId");
  if (next_id < 0 || next_id > 1'000'000'000) return Lost("perception next id");
  r->perception = std::make_pair(static_cast<int>(next_id), std::move(tracks));
  return OkStatus();
}

}  // namespace

StatusOr<SessionRecord> DecodeRecord(std::string_view bytes, const Limits& limits,
                                     std::string* photos_digest) {
  if (photos_digest != nullptr) photos_digest->clear();
  // A snapshot holds a world (grid cells, occupancy runs) and perception tracks, so it may hold
  // more JSON values than a request; still bounded.
  Limits record_limits = limits;
  record_limits.max_json_values = limits.max_grid_cells + limits.max_map_cells + 100'000;
  auto parsed =
      internal::ParseBody(bytes, limits.max_json_depth, record_limits.max_json_values, false);
  if (!parsed.ok()) return Lost(parsed.status().message());
  const json& j = *parsed;
  const int64_t version = internal::Integer(j, "version");
  if (version != kRecordVersion && version != kRecordVersionPhotosApart) {
    return Lost("unknown version");
  }
  SessionRecord r;
  r.id = internal::String(j, "id");
  if (!IsSessionId(r.id)) return Lost("bad id");
  r.display_name =
      internal::Utf8Prefix(internal::String(j, "displayName"), limits.max_display_name);
  if (Status s = ReadPlanner(j, limits, &r.planner); !s.ok()) return s;
  auto seed = ReadSeed(j);
  if (!seed.ok()) return seed.status();
  r.seed = *seed;
  r.ttl_seconds = internal::Number(j, "ttlSeconds", 3600.0);
  if (!(r.ttl_seconds > 0.0 && r.ttl_seconds <= kMaxTtlSeconds)) return Lost("ttlSeconds");
  r.state = ReadState(j);
  r.actions = std::max<int64_t>(0, internal::Integer(j, "actions"));
  r.total_simulations = std::max<int64_t>(0, internal::Integer(j, "totalSimulations"));
  r.planning_seconds_used = std::max(0.0, internal::Number(j, "planningSecondsUsed"));
  r.create_time_ms = internal::Integer(j, "createTimeMs");
  r.update_time_ms = internal::Integer(j, "updateTimeMs");
  r.last_action_id =
      internal::Utf8Prefix(internal::String(j, "lastActionId"), limits.max_id_length);
  if (r.state == SessionState::kActionPending) {
    if (Status s = ReadPendingAction(j, &r); !s.ok()) return s;
  }
  if (!j.contains("world")) return Lost("missing world");
  auto world = internal::WorldFromJson(j.at("world"), limits);
  if (!world.ok()) return world.status();
  r.world = std::move(world).value();
  if (r.state == SessionState::kActionPending) {
    const int kind = r.pending_action.kind;
    const int max_kind = 1 + 3 * static_cast<int>(r.world.objects.size());
    if (kind < 0 || kind >= max_kind ||
        (kind == object_search::kMoveKind && r.pending_action.x.size() != 6)) {
      return Lost("pending action kind");
    }
  }
  if (j.contains("target")) {
    const json& t = j.at("target");
    r.target.description =
        internal::Utf8Prefix(internal::String(t, "description"), limits.max_description);
    if (version == kRecordVersion) {
      if (t.contains("photos")) {
        if (Status s = ReadPhotos(t.at("photos"), limits, &r.target.photos); !s.ok()) return s;
      }
    } else {
      const std::string digest = internal::String(t, "photosKeptApart");
      if (photos_digest == nullptr || digest.empty() || digest.size() > 64) {
        return Lost("target photos kept apart");
      }
      *photos_digest = digest;
    }
  }
  if (j.contains("perception")) {
    if (Status s = ReadTracks(j.at("perception"), limits, &r); !s.ok()) return s;
  }
  if (j.contains("history")) {
    const json& h = j.at("history");
    if (!h.is_array() || h.size() > static_cast<size_t>(kMaxHistorySteps)) return Lost("history");
    for (const json& step : h) {
      StepRecord s;
      if (!internal::ReadStep(step, &s)) return Lost("history step");
      r.history.push_back(std::move(s));
    }
  }
  return r;
}

std::string EncodeSessionSummary(const SessionView& v) {
  json j;
  j["version"] = kSummaryVersion;
  j["id"] = v.id;
  j["displayName"] = v.display_name;
  j["state"] = StateName(v.state);
  j["createTimeMs"] = UnixMillis(v.create_time);
  j["updateTimeMs"] = UnixMillis(v.update_time);
  j["ttlSeconds"] = v.ttl_seconds;
  j["planner"] = PlannerJson(v.planner);
  j["seed"] = std::to_string(v.seed);
  j["targetDescription"] = v.target_description;
  j["photoCount"] = v.photo_count;
  if (v.perception_tracks) j["perceptionTracks"] = *v.perception_tracks;
  j["step"] = v.step;
  j["robot"] = internal::ConfigJson(v.robot);
  j["objectCount"] = v.object_count;
  if (v.pending) {
    j["pendingActionId"] = v.pending->first;
    j["pendingAction"] = internal::ActionJson(v.pending->second);
  }
  j["totalSimulations"] = v.total_simulations;
  j["planningSecondsUsed"] = v.planning_seconds_used;
  return internal::Dump(j);
}

StatusOr<SessionView> DecodeSessionSummary(std::string_view bytes, const Limits& limits) {
  if (bytes.size() > kMaxSummaryBytes) return Lost("summary too long");
  auto parsed = internal::ParseBody(bytes, limits.max_json_depth, limits.max_json_values, false);
  if (!parsed.ok()) return Lost(parsed.status().message());
  const json& j = *parsed;
  if (internal::Integer(j, "version") != kSummaryVersion) return Lost("unknown summary version");
  SessionView v;
  v.id = internal::String(j, "id");
  if (!IsSessionId(v.id)) return Lost("bad id");
  v.display_name =
      internal::Utf8Prefix(internal::String(j, "displayName"), limits.max_display_name);
  v.state = ReadState(j);
  v.create_time = FromUnixMillis(internal::Integer(j, "createTimeMs"));
  v.update_time = FromUnixMillis(internal::Integer(j, "updateTimeMs"));
  v.ttl_seconds = internal::Number(j, "ttlSeconds", 3600.0);
  if (Status s = ReadPlanner(j, limits, &v.planner); !s.ok()) return s;
  auto seed = ReadSeed(j);
  if (!seed.ok()) return seed.status();
  v.seed = *seed;
  v.target_description =
      internal::Utf8Prefix(internal::String(j, "targetDescription"), limits.max_description);
  v.photo_count = static_cast<int>(
      std::clamp<int64_t>(internal::Integer(j, "photoCount"), 0, limits.max_photos));
  if (j.contains("perceptionTracks")) {
    v.perception_tracks =
        static_cast<int>(std::clamp<int64_t>(internal::Integer(j, "perceptionTracks"), 0, 1 << 20));
  }
  v.step = static_cast<int>(std::clamp<int64_t>(internal::Integer(j, "step"), 0, 1'000'000'000));
  v.robot = internal::ReadConfig(j.value("robot", json::object()));
  v.object_count = static_cast<int>(
      std::clamp<int64_t>(internal::Integer(j, "objectCount"), 0, limits.max_objects));
  if (j.contains("pendingAction")) {
    ActionView a;
    if (!internal::ReadAction(j.at("pendingAction"), &a)) return Lost("pending action");
    v.pending = std::make_pair(
        internal::Utf8Prefix(internal::String(j, "pendingActionId"), limits.max_id_length), a);
  }
  v.total_simulations = std::max<int64_t>(0, internal::Integer(j, "totalSimulations"));
  v.planning_seconds_used = std::max(0.0, internal::Number(j, "planningSecondsUsed"));
  return v;
}

}  // namespace npfkct::api
