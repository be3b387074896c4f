// A planning session: one robot's search, with its knowledge (World), its belief and belief tree,
// and the action it is executing. The server's only type-erased layer over the planners.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/object_search/model.h"
#include "npfkct/object_search/search_planner.h"
#include "npfkct/server/api_error.h"
#include "npfkct/solver/candidates.h"
#include "npfkct/solver/planner.h"

namespace npfkct::perception {
class Perception;
}  // namespace npfkct::perception

namespace npfkct::server {

using nlohmann::json;

/// What the robot is told about the object it searches for.
struct TargetSpec {
  std::string description;
  /// Photos of the target (base64 PNG or JPEG), matched against camera images by perception.
  std::vector<std::string> photos;

  /// Decodes every photo; INVALID_ARGUMENT naming `target.photos[i]` on a bad one.
  Status Validate() const;
};

/// Which planner a session uses and how.
struct PlannerSpec {
  std::string name = "npfkct";
  int particles = 300;
  /// Option overrides as (snake_case key, value), as given by the client (camelCase converted).
  std::vector<std::pair<std::string, double>> options;
  /// The client's option keys as sent, for echoing back.
  json options_json = json::object();
  /// Neural filter model file (NPF-kCT).
  std::string model_path;
};

/// Supplies NPF-kCT's candidate sampler for a session (the neural filter when one is loaded).
using SamplerFactory =
    std::function<StatusOr<std::shared_ptr<CandidateSampler<object_search::State>>>(
        const PlannerSpec& spec, const object_search::ObjectSearchModel& model)>;

/// A session. Every method must be called with mutex() held.
class Session {
 public:
  enum class State { kReady, kActionPending, kDone };

  /// A new session over `world`. Fails on a bad planner name or options.
  static StatusOr<std::unique_ptr<Session>> Create(std::string id, std::string display_name,
                                                   object_search::World world, PlannerSpec spec,
                                                   TargetSpec target, uint64_t seed,
                                                   double ttl_seconds,
                                                   const SamplerFactory& samplers);
  /// A session restored from Snapshot() output (the tree is rebuilt by the next plan).
  static StatusOr<std::unique_ptr<Session>> Restore(const json& snapshot,
                                                    const SamplerFactory& samplers);

  ~Session();

  const std::string& id() const { return id_; }
  std::mutex& mutex() const { return mutex_; }
  State state() const { return state_; }

  /// Everything needed to restore the session.
  json Snapshot() const;
  /// The API resource "sessions/{id}".
  json Resource() const;
  /// Plans within `budget`; the action becomes pending. FAILED_PRECONDITION while an action is
  /// pending or after the target was removed.
  StatusOr<json> Plan(const Budget& budget);
  /// Applies the observation that followed the pending action (validated in full before anything
  /// changes). FAILED_PRECONDITION for a missing, stale or repeated actionId. Raw `pointCloud` (and
  /// `image`) go through the session's perception pipeline, created on first use.
  StatusOr<json> Observe(const json& body);
  /// The belief as JSON.
  json Belief() const;
  /// The knowledge the belief is sampled from.
  const object_search::World& world() const { return *world_; }

  /// Seconds since the last request touched the session.
  double IdleSeconds() const;
  double ttl_seconds() const { return ttl_seconds_; }
  /// Marks the session used now.
  void Touch();
  /// Simulations run by this session's planner so far.
  int64_t total_simulations() const { return total_simulations_; }
  /// Wall time of the last Plan() spent in the planner.
  double last_planning_ms() const { return last_planning_ms_; }

 private:
  Session() = default;
  Status Init(const SamplerFactory& samplers);
  /// The perception pipeline, built from the world's map and the target photos on first use.
  perception::Perception& Perceiver();
  void Reseed();
  ParticleBelief<object_search::State> FreshBelief();

  std::string id_;
  std::string display_name_;
  PlannerSpec spec_;
  TargetSpec target_;
  std::unique_ptr<perception::Perception> perception_;
  uint64_t seed_ = 0;
  double ttl_seconds_ = 3600.0;
  Rng rng_;
  std::shared_ptr<object_search::World> world_;
  std::unique_ptr<object_search::ObjectSearchModel> model_;
  std::unique_ptr<object_search::SearchPlanner> planner_;
  State state_ = State::kReady;
  HybridAction pending_action_;
  std::string pending_action_id_;
  std::string last_action_id_;
  int64_t actions_ = 0;
  int64_t total_simulations_ = 0;
  double last_planning_ms_ = 0.0;
  double total_reward_estimate_ = 0.0;
  std::chrono::system_clock::time_point create_time_, update_time_;
  std::chrono::steady_clock::time_point last_used_;
  mutable std::mutex mutex_;
};

/// RFC 3339 UTC time with milliseconds.
std::string Rfc3339(std::chrono::system_clock::time_point t);

}  // namespace npfkct::server
