// The typed requests, replies and records of the API. The API layer (api.h) turns request bodies
// into these and these into response bodies; nothing else in the server sees the wire.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/object_search/world.h"
#include "npfkct/perception/perception.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/planner.h"

namespace npfkct::api {

/// Milliseconds since the Unix epoch, as records keep times.
inline int64_t UnixMillis(std::chrono::system_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count();
}
/// The time `ms` milliseconds after the Unix epoch.
inline std::chrono::system_clock::time_point FromUnixMillis(int64_t ms) {
  return std::chrono::system_clock::time_point(std::chrono::milliseconds(ms));
}

using object_search::Box;
using object_search::RobotConfig;
using object_search::Vec2;
using object_search::World;

// ---------------------------------------------------------------------------------------------
// Requests

/// The prior map a robot is told at creation: the scenario-file format without its objects.
using WorldSpec = object_search::PriorMap;

/// Which planner a session uses and how.
struct PlannerSpec {
  std::string name = "npfkct";
  int particles = 300;
  /// A model file name inside the server's --model-dir (planner.model); empty: none.
  std::string model;
  /// Whether the request named planner.model (when it did not, a planner that takes a filter
  /// model gets the server's default model; "" asks for none).
  bool model_given = false;
  /// Whether the planner takes a filter model (its registry entry's takes_sampler).
  bool takes_model = false;
  /// Option overrides in the order given, keyed as the planners take them (snake_case,
  /// "search.max_depth"; the API layer converts the lowerCamelCase keys of the wire); booleans
  /// 0/1.
  std::vector<std::pair<std::string, double>> options;
  /// Which option values were booleans (for echoing them back as booleans).
  std::vector<bool> option_is_bool;
};

/// What the robot is told about the object it searches for.
struct TargetSpec {
  std::string description;
  /// Photos as sent (PNG or JPEG bytes, header-checked against the pixel limit).
  std::vector<std::string> photos;
};

/// POST /v1/sessions.
struct CreateSessionRequest {
  std::string display_name;
  WorldSpec world;
  TargetSpec target;
  PlannerSpec planner;
  std::optional<uint64_t> seed;
  std::optional<double> ttl_seconds;
};

/// POST /v1/sessions/{id}:plan: the budget as asked (absent fields: not asked for).
struct PlanRequest {
  std::optional<double> time_ms;
  std::optional<double> cpu_ms;
  std::optional<int64_t> simulations;
};

/// POST /v1/sessions/{id}:observe.
struct ObserveRequest {
  std::string action_id;
  bool succeeded = true;
  /// Where the robot ended (required after a successful MOVE).
  std::optional<RobotConfig> robot_state;
  /// Detections from the caller's own perception.
  std::vector<object_search::ObjectDetection> detections;
  /// Raw sensor data for the session's perception instead (its `reported` pose is filled in by
  /// the session: robot_state, or where the robot is).
  std::optional<perception::SensorFrame> frame;
};

/// GET /v1/sessions.
struct ListRequest {
  int page_size = 50;
  std::string page_token;
};

/// GET /v1/sessions/{id}/belief.
enum class BeliefFormat { kJson, kPng };

// ---------------------------------------------------------------------------------------------
// Replies

enum class SessionState { kReady, kActionPending, kDone };

/// An action in API form: a MOVE to a configuration, or a declare/remove on an object.
struct ActionView {
  enum class Type { kMove, kDeclareTarget, kDeclareObstacle, kRemove };
  Type type = Type::kMove;
  RobotConfig configuration;      ///< MOVE
  std::string object_id;          ///< declare/remove
  std::optional<Box> object_box;  ///< declare/remove: where the robot last saw the object
};

/// The session resource "sessions/{id}".
struct SessionView {
  std::string id;
  std::string display_name;
  SessionState state = SessionState::kReady;
  std::chrono::system_clock::time_point create_time, update_time;
  double ttl_seconds = 0.0;
  PlannerSpec planner;
  uint64_t seed = 0;
  std::string target_description;
  int photo_count = 0;
  std::optional<int> perception_tracks;
  int step = 0;
  RobotConfig robot;
  int object_count = 0;
  std::optional<std::pair<std::string, ActionView>> pending;  ///< (actionId, action)
  int64_t total_simulations = 0;
  double planning_seconds_used = 0.0;
};

/// What a plan was asked for and what it used (Ceres style: given and used side by side).
struct PlanSummary {
  /// The budget as the request asked for it (absent fields: not asked for).
  Budget budget_given;
  /// The planner's options as the session was created with them (planner.options).
  std::vector<std::pair<std::string, double>> options_given;
  /// Every option as the planner ran with it: its registry defaults with the overrides applied
  /// (SetOption keys).
  std::vector<std::pair<std::string, double>> options_used;
  /// What the search resolved itself from the options and the belief (kCT's w2, c_r, value
  /// scale, ...).
  std::vector<std::pair<std::string, double>> resolved;
};

/// The :plan reply: the action, its value, the search statistics, and the budget as used.
struct PlanReply {
  std::string action_id;
  ActionView action;
  double expected_value = 0.0;
  SearchStats stats;
  CandidateStats candidates;
  /// The budget the planner ran under (defaults and caps applied).
  Budget budget;
  PlanSummary summary;
  SessionView session;
};

/// One planner of GET /v1/planners.
struct PlannerView {
  std::string name;
  std::string summary;
  /// Whether it plans with a filter model (planner.model; the server's default when absent).
  bool takes_model = false;
  /// Every option with its default (SetOption keys; filter.* for a planner that takes a model).
  std::vector<std::pair<std::string, double>> defaults;
};

/// The :observe reply.
struct ObserveReply {
  bool done = false;
  double reward = 0.0;
  /// What the session's perception made of raw sensor data.
  std::optional<perception::PerceptionResult> perception;
  SessionView session;
};

/// GET /healthz: whether the server serves, and its session store's state.
struct HealthView {
  /// "memory", "directory" or "postgresql".
  std::string store_backend = "memory";
  bool store_ok = true;
  /// Why the store is unavailable.
  std::string store_message;
  /// Sessions held in memory.
  int sessions_held = 0;
  /// The server's release (npfkct::kVersion); empty in a reply from a server that has none.
  std::string version;
};

/// One step of a session's history: the plan that chose the action and, once observed, what
/// followed it (what the web console's step table shows).
struct StepRecord {
  /// What followed the action (its :observe).
  struct Outcome {
    bool succeeded = true;
    double reward = 0.0;
    int detections = 0;   ///< Objects seen.
    int new_objects = 0;  ///< Objects seen for the first time.
    bool raw = false;     ///< Raw sensor data went through the session's perception.
    bool done = false;    ///< The target was removed.
    int64_t time_ms = 0;  ///< When it was observed (Unix ms).
    /// The robot's state after the action, as observed (absent in steps of older snapshots).
    std::optional<object_search::RobotConfig> robot;
  };
  int step = 0;  ///< 1 for the first action.
  std::string action_id;
  ActionView action;
  double expected_value = 0.0;
  SearchStats stats;
  CandidateStats candidates;
  int64_t plan_time_ms = 0;  ///< When the plan finished (Unix ms).
  std::optional<Outcome> outcome;
};

/// Steps a session keeps in its history (the oldest are dropped first).
inline constexpr int kMaxHistorySteps = 500;

// ---------------------------------------------------------------------------------------------
// Records

/// Everything that restores a session: what a SessionStore keeps.
struct SessionRecord {
  std::string id;
  std::string display_name;
  PlannerSpec planner;
  uint64_t seed = 0;
  double ttl_seconds = 3600.0;
  SessionState state = SessionState::kReady;
  int64_t actions = 0;
  int64_t total_simulations = 0;
  double planning_seconds_used = 0.0;
  int64_t create_time_ms = 0;
  int64_t update_time_ms = 0;
  std::string last_action_id;
  std::string pending_action_id;
  HybridAction pending_action;
  World world;
  TargetSpec target;
  /// Perception's object tracks (present once raw data arrived).
  std::optional<std::pair<int, std::vector<perception::TrackState>>> perception;
  /// The last kMaxHistorySteps steps.
  std::vector<StepRecord> history;
};

}  // namespace npfkct::api
