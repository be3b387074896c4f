// A planning session: one robot's search, as a typed state machine (READY -> ACTION_PENDING ->
// READY ... -> DONE) over its knowledge (World), belief tree and perception. It locks itself:
// Plan and Observe run one at a time (a second one meanwhile is ABORTED, never queued behind a
// plan), while View, Belief and Record read a consistent state at any time without waiting for
// a running plan. It never sees JSON: requests and replies are the API layer's types.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "npfkct/api/types.h"
#include "npfkct/object_search/model.h"
#include "npfkct/object_search/planner_registry.h"
#include "npfkct/perception/perception.h"
#include "npfkct/server/models.h"
#include "npfkct/server/session_store.h"
#include "npfkct/solver/planner.h"

namespace npfkct::server {

/// What a session is created with, besides its world.
struct SessionConfig {
  std::string id;
  std::string display_name;
  api::PlannerSpec planner;
  api::TargetSpec target;
  uint64_t seed = 0;
  double ttl_seconds = 3600.0;
};

/// Limits a session applies to its own work.
struct SessionLimits {
  /// Planning a session may spend over its life (wall-clock seconds).
  double max_plan_seconds = 3600.0;
  /// Heap in use (bytes) past which a running plan stops with its best action so far, and
  /// plans, observations and new sessions are refused (RESOURCE_EXHAUSTED).
  int64_t max_heap_bytes = int64_t{4096} << 20;
  /// Points of the prior map one frame can make perception build (perception::PriorMapPoints);
  /// denser worlds cannot take raw data.
  int64_t max_perception_map_points = 4'000'000;
  /// Pixels of a target photo (checked again from the header when perception decodes them).
  int64_t max_photo_pixels = 4'194'304;
};

/// RESOURCE_EXHAUSTED naming --max-heap-mb when the heap in use (the bytes glibc's allocator has
/// handed out; not a sanitizer build's allocator) is past `limits`' bound, for work that would
/// grow it (`what`: "plan", "observe", "create a session").
Status CheckHeap(const SessionLimits& limits, const std::string& what);

/// Gives memory the allocator holds free back to the system (malloc_trim) once more than 64 MiB
/// of it is resident: a freed tree stays resident in the arena of the thread that grew it, and
/// the next plan, on another thread, grows another arena.
void ReleaseFreedMemory();

/// A session. Thread-safe.
class Session {
 public:
  /// A new session over `world` with planner `config.planner.name` of `planners` (which must
  /// outlive it): INVALID_ARGUMENT naming planner.name, planner.model or planner.options.<key>
  /// (keys as the planners take them) for a planner that cannot be made.
  static StatusOr<std::unique_ptr<Session>> Create(SessionConfig config, object_search::World world,
                                                   const SamplerFactory& samplers,
                                                   const object_search::PlannerRegistry& planners,
                                                   SessionLimits limits);
  /// A session from its record (the tree is rebuilt by the next plan).
  static StatusOr<std::unique_ptr<Session>> Restore(api::SessionRecord record, int64_t version,
                                                    const SamplerFactory& samplers,
                                                    const object_search::PlannerRegistry& planners,
                                                    SessionLimits limits);
  ~Session();

  const std::string& id() const { return id_; }
  /// The version of the session's record in the store (0 before the first save).
  int64_t version() const;
  /// Whether a save failed after the session changed: the stored record, not this copy, holds
  /// what was acknowledged, and the session must be loaded again.
  bool stale() const { return stale_.load(); }
  /// Whether a request (plan or observe) works on the session now.
  bool busy() const;
  /// Whether this copy planned more than the store holds (saved by SaveIfIdle, or moved on by
  /// KeepUsage): such a copy is not dropped from memory.
  bool has_unsaved_usage() const;
  /// Forgets the unsaved planning time (it could not be stored).
  void DropUnsavedUsage();
  /// Stops this copy's running plan because another replica saved a newer version: its save
  /// could only fail, and the copy is no longer the one requests see (its plan answers ABORTED).
  void Supersede();

  /// Holds a planning slot until destroyed (the server's admission ticket).
  using SlotHold = std::shared_ptr<const void>;
  /// Waits for `threads` planning slots, giving up when `give_up` returns true (the caller polls
  /// it); a hold, or why none (RESOURCE_EXHAUSTED: the queue is full; CANCELLED: gave up).
  using Admit =
      std::function<StatusOr<SlotHold>(const std::function<bool()>& give_up, int threads)>;

  /// Plans within `budget` (its time capped by what is left of the session's planning budget),
  /// stopping early when Cancel() is called or `client_gone` returns true (polled every few
  /// milliseconds). The session is claimed first (a second request meanwhile is ABORTED at once)
  /// and in use, never idle, while `admit` (when given) waits for its planning slots; a deleted
  /// session or a client that left stops the wait. The action becomes pending and the session is
  /// saved to `store` before the reply. FAILED_PRECONDITION while an action is pending or after
  /// the target was removed; ABORTED while another request works on the session or when it was
  /// deleted meanwhile; CANCELLED when cancelled; RESOURCE_EXHAUSTED when its planning budget is
  /// spent or no slot is free and the queue is full.
  StatusOr<api::PlanReply> Plan(const Budget& budget, const std::function<bool()>& client_gone,
                                SessionStore* store, const Admit& admit = {});
  /// Applies the observation that followed the pending action (all or nothing: a rejected
  /// observation changes nothing) and saves the session. FAILED_PRECONDITION for a missing,
  /// stale or repeated action_id; raw sensor data go through the session's perception. Errors
  /// name the request's fields in snake_case (action_id, robot_state, point_cloud, detections).
  StatusOr<api::ObserveReply> Observe(api::ObserveRequest request, SessionStore* store);
  /// The API resource.
  api::SessionView View() const;
  /// The knowledge the belief is sampled from, as of now (immutable; later requests replace it).
  std::shared_ptr<const object_search::World> Belief() const;
  /// The steps so far (the last api::kMaxHistorySteps), oldest first.
  std::vector<api::StepRecord> Steps() const;
  /// Threads each of its plans searches on (search.threads): the planning slots a plan takes.
  int SearchThreads() const { return planner_->SearchThreads(); }
  /// Moves to this copy the planning time and simulations `replaced` (an earlier copy of this
  /// session, e.g. one whose save failed or lost a race) spent and did not save: reloading a
  /// session from the store never gives back planning budget that was spent.
  void KeepUsage(Session& replaced);

  /// The API resource of a stored record (a session this server does not hold).
  static api::SessionView ViewOf(const api::SessionRecord& record);

  /// Saves the session to `store` unless it was deleted (for creation).
  Status Save(SessionStore* store);
  /// Saves the session unless it was deleted or a request works on it (that request saves it).
  Status SaveIfIdle(SessionStore* store);
  /// Stops a running plan at its next check, marks the session deleted and removes its stored
  /// copy (none when `store` is null: it was removed already), under the same lock as every
  /// save: a deleted session is never written again.
  Status Delete(SessionStore* store);
  /// Expires the session when it is idle past its TTL and no request works on it: deletes it
  /// (as Delete) and returns true.
  bool ExpireIfIdle(SessionStore* store);
  /// Stops a running plan at its next check (server shutdown).
  void Cancel();

  /// Marks the session used now (its TTL counts from here).
  void Touch();
  /// Seconds since a request last used the session (0 while one does).
  double IdleSeconds() const;
  double ttl_seconds() const { return ttl_seconds_; }

 private:
  Session() = default;
  Status Init(const SamplerFactory& samplers, const object_search::PlannerRegistry& planners);
  void Reseed();
  ParticleBelief<object_search::State> FreshBelief();
  // The record to save; `unsaved_seconds` and `unsaved_simulations` get the usage in it that no
  // save has stored yet (read together with it).
  api::SessionRecord RecordLocked(double* unsaved_seconds, int64_t* unsaved_simulations) const;
  api::SessionView ViewLocked() const;
  static api::ActionView ActionViewOf(const HybridAction& a, const object_search::World& w);
  Status SaveUnderOp(SessionStore* store);

  // ---- Plan's stages ----
  // Claims the session for a plan (in use, not idle): the budget capped by what is left of the
  // session's planning time; FAILED_PRECONDITION or RESOURCE_EXHAUSTED when it cannot plan.
  StatusOr<Budget> ClaimForPlan(const Budget& asked);
  // Ends a claim that planned nothing.
  void Release();
  // Runs the planner under a condition Cancel() and `client_gone` stop (and the heap bound).
  Decision<HybridAction> Search(const Budget& budget, const std::function<bool()>& client_gone,
                                bool* cancelled);
  // Makes `d`'s action the pending one and records the step (state_mutex_ held).
  api::PlanReply PendLocked(const Decision<HybridAction>& d, const Budget& budget);

  // ---- Observe's stages ----
  // The pending action an observation answers, and the world it was planned in.
  struct Pending {
    std::shared_ptr<const object_search::World> world;
    HybridAction action;
    bool is_move() const { return action.kind == object_search::kMoveKind; }
  };
  // Perception's tracks as they were before a frame, to restore when the observation fails.
  struct SavedTracks {
    std::vector<perception::TrackState> tracks;
    int next_id = 0;
  };
  // The checks of an observation against the pending action (action_id, robot_state, ids).
  StatusOr<Pending> CheckObservation(const api::ObserveRequest& req) const;
  // The session's perception, built on the first raw frame (prior map, target photos, tracks
  // of a restored record).
  Status EnsurePerception(const object_search::World& world);
  // A raw frame through perception: the corrected pose and the detections into `obs`.
  StatusOr<perception::PerceptionResult> Perceive(perception::SensorFrame frame, const Pending& p,
                                                  bool succeeded,
                                                  object_search::RealObservation* obs,
                                                  SavedTracks* saved);
  // Installs the observed world and the step's outcome, and moves the planner to its subtree
  // (a fresh belief, and a fresh tree when objects were seen for the first time).
  void Advance(std::shared_ptr<const object_search::World> updated, const HybridAction& action,
               const object_search::Observation& key, bool new_objects,
               const api::StepRecord::Outcome& step);
  // Why a plan that was cancelled ends: ABORTED when the session was deleted, else CANCELLED
  // (the server stops, or the client left).
  Status WhyCancelled() const;

  // Fixed at creation.
  std::string id_;
  std::string display_name_;
  api::PlannerSpec spec_;
  api::TargetSpec target_;
  uint64_t seed_ = 0;
  double ttl_seconds_ = 3600.0;
  SessionLimits limits_;
  std::chrono::system_clock::time_point create_time_;

  // Owned by the request working on the session (op_mutex_).
  mutable std::mutex op_mutex_;
  Rng rng_;
  std::unique_ptr<object_search::ObjectSearchModel> model_;
  std::unique_ptr<object_search::SearchPlanner> planner_;
  std::unique_ptr<perception::Perception> perception_;
  // Perception tracks of a restored record, kept as they are until a raw frame needs the
  // perception: building it maps the whole room (seconds in a large one), which a restart or a
  // fleet replica's load of the session does not pay for.
  std::optional<std::pair<int, std::vector<perception::TrackState>>> stored_tracks_;

  // The state readers see (state_mutex_).
  mutable std::mutex state_mutex_;
  std::shared_ptr<const object_search::World> world_;
  api::SessionState state_ = api::SessionState::kReady;
  HybridAction pending_action_;
  std::string pending_action_id_;
  std::string last_action_id_;
  int64_t actions_ = 0;
  int64_t total_simulations_ = 0;
  double planning_seconds_ = 0.0;
  // What planning_seconds_ and total_simulations_ hold that no save has stored yet.
  double unsaved_seconds_ = 0.0;
  int64_t unsaved_simulations_ = 0;
  int perception_tracks_ = -1;  // -1: no raw data yet
  std::vector<api::StepRecord> history_;
  std::chrono::system_clock::time_point update_time_;
  std::chrono::steady_clock::time_point last_used_;
  bool in_use_ = false;

  // Persistence (persist_mutex_): the stored version and whether the session was deleted.
  mutable std::mutex persist_mutex_;
  int64_t version_ = 0;
  bool deleted_ = false;
  std::atomic<bool> stale_{false};

  // Cancellation of a running plan.
  std::atomic<bool> cancel_{false};
  std::atomic<bool> superseded_{false};
  std::mutex running_mutex_;
  const TerminationCondition* running_ = nullptr;
};

}  // namespace npfkct::server
