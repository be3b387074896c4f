#include "npfkct/server/session.h"

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <set>

#include "npfkct/api/wire.h"
#include "npfkct/perception/perception.h"

namespace npfkct::server {
namespace {

using object_search::World;

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

Status Busy() {
  return Status(StatusCode::kAborted,
                "another request is working on this session; retry when it has finished");
}

// A copy whose save failed: the stored session, loaded again, is the one to work on (this copy
// may hold planning time already moved on to it).
Status Stale() {
  return Status(StatusCode::kAborted, "the session changed meanwhile; read it and try again");
}

// The bytes the allocator has handed out and not had back, over every arena.
int64_t HeapInUse() {
  const struct mallinfo2 m = mallinfo2();
  return static_cast<int64_t>(m.uordblks + m.hblkhd);
}

bool HeapPastBound(const SessionLimits& limits) { return HeapInUse() > limits.max_heap_bytes; }

Status HeapBoundError(const SessionLimits& limits, const std::string& what) {
  return ResourceExhaustedError("the server's heap is past its bound (--max-heap-mb " +
                                std::to_string(limits.max_heap_bytes >> 20) +
                                "): delete sessions or " + what + " later");
}

}  // namespace

Status CheckHeap(const SessionLimits& limits, const std::string& what) {
  return HeapPastBound(limits) ? HeapBoundError(limits, what) : OkStatus();
}

void ReleaseFreedMemory() {
  // Resident memory that the allocator holds free: the process's resident bytes less the heap in
  // use, above the least seen (what the process holds outside the heap). Trimmed chunks that a
  // later tree reused and freed again count again.
  static std::mutex mutex;
  static int64_t least = std::numeric_limits<int64_t>::max();
  constexpr int64_t kWorthIt = int64_t{64} << 20;
  std::lock_guard<std::mutex> lock(mutex);
  auto resident_not_in_use = [] {
    long pages = 0, resident = 0;
    if (FILE* f = std::fopen("/proc/self/statm", "r")) {
      if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
      std::fclose(f);
    }
    return static_cast<int64_t>(resident) * ::sysconf(_SC_PAGESIZE) - HeapInUse();
  };
  const int64_t now = resident_not_in_use();
  least = std::min(least, now);
  if (now < least + kWorthIt) return;
  malloc_trim(0);
  least = std::min(least, resident_not_in_use());
}

Session::~Session() = default;

StatusOr<std::unique_ptr<Session>> Session::Create(SessionConfig config, World world,
                                                   const SamplerFactory& samplers,
                                                   const object_search::PlannerRegistry& planners,
                                                   SessionLimits limits) {
  std::unique_ptr<Session> s(new Session());
  s->id_ = std::move(config.id);
  s->display_name_ = std::move(config.display_name);
  s->spec_ = std::move(config.planner);
  s->target_ = std::move(config.target);
  s->seed_ = config.seed;
  s->ttl_seconds_ = config.ttl_seconds;
  s->limits_ = limits;
  s->world_ = std::make_shared<const World>(std::move(world));
  s->create_time_ = s->update_time_ = std::chrono::system_clock::now();
  s->last_used_ = std::chrono::steady_clock::now();
  if (Status st = s->Init(samplers, planners); !st.ok()) return st;
  return s;
}

namespace {

// "only the npfkct planner uses a filter model", naming the planners of `planners` that take one.
std::string OnlyTheseTakeAModel(const object_search::PlannerRegistry& planners) {
  std::vector<std::string> names;
  for (const auto& e : planners.entries()) {
    if (e.takes_sampler) names.push_back(e.name);
  }
  if (names.empty()) return "no planner of this server uses a filter model";
  std::string list;
  for (size_t i = 0; i < names.size(); ++i) {
    list += (i == 0 ? "" : i + 1 == names.size() ? " and " : ", ") + names[i];
  }
  return "only the " + list + (names.size() == 1 ? " planner uses" : " planners use") +
         " a filter model";
}

}  // namespace

Status Session::Init(const SamplerFactory& samplers,
                     const object_search::PlannerRegistry& planners) {
  Reseed();
  model_ = std::make_unique<object_search::ObjectSearchModel>(world_);
  const object_search::PlannerEntry* entry = planners.Find(spec_.name);
  if (entry == nullptr || entry->needs_truth) {
    return InvalidFieldError("planner.name", "no planner '" + spec_.name + "' on this server");
  }
  spec_.takes_model = entry->takes_sampler;
  if (!spec_.model.empty() && !entry->takes_sampler) {
    return InvalidFieldError("planner.model", OnlyTheseTakeAModel(planners));
  }
  std::shared_ptr<CandidateSampler<object_search::State>> sampler;
  if (samplers) {
    auto made = samplers(spec_, *model_);
    if (!made.ok()) return made.status();
    sampler = *made;
  }
  // Net_sam's "filter.*" options went to the sampler factory; the planner gets the rest, each
  // tried alone first so that a bad one is named.
  object_search::OptionList options;
  for (const auto& [key, value] : spec_.options) {
    if (IsFilterOption(key)) continue;
    auto alone = planners.Make(spec_.name, {model_.get(), {{key, value}}, nullptr, nullptr});
    if (!alone.ok()) return InvalidFieldError("planner.options." + key, alone.status().message());
    options.emplace_back(key, value);
  }
  auto planner = planners.Make(spec_.name, {model_.get(), options, sampler, nullptr});
  if (!planner.ok()) return InvalidFieldError("planner.options", planner.status().message());
  planner_ = std::move(planner).value();
  planner_->SetBelief(FreshBelief());
  return OkStatus();
}

void Session::Reseed() {
  // A function of the seed and the step only, so that a restored session rebuilds the belief it
  // had. (Its next plan starts a fresh search tree: the subtree kept between steps is not saved.)
  rng_.Seed(HashMix(seed_ ^ HashMix(static_cast<uint64_t>(actions_) + 0x51ed27)));
}

ParticleBelief<object_search::State> Session::FreshBelief() {
  return ParticleBelief<object_search::State>::FromInitial(*model_, spec_.particles, rng_);
}

void Session::Touch() {
  std::lock_guard<std::mutex> lock(state_mutex_);
  last_used_ = std::chrono::steady_clock::now();
}

double Session::IdleSeconds() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (in_use_) return 0.0;
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - last_used_).count();
}

void Session::Cancel() {
  cancel_ = true;
  std::lock_guard<std::mutex> lock(running_mutex_);
  if (running_ != nullptr) running_->Terminate();
}

StatusOr<Budget> Session::ClaimForPlan(const Budget& asked) {
  std::lock_guard<std::mutex> lock(state_mutex_);
  if (state_ == api::SessionState::kDone) {
    return FailedPreconditionError("the target was removed: session " + id_ + " is done");
  }
  if (state_ == api::SessionState::kActionPending) {
    return FailedPreconditionError("action " + pending_action_id_ +
                                   " is pending: POST :observe with its outcome first");
  }
  const double left_ms = 1000.0 * (limits_.max_plan_seconds - planning_seconds_);
  if (left_ms < 10.0) {  // a few milliseconds plan nothing
    return FieldError(StatusCode::kResourceExhausted, "budget",
                      "this session has spent its " +
                          std::to_string(static_cast<int64_t>(limits_.max_plan_seconds)) +
                          " s of planning");
  }
  Budget budget = asked;
  budget.time_ms = budget.time_ms > 0.0 ? std::min(budget.time_ms, left_ms) : left_ms;
  in_use_ = true;
  return budget;
}

void Session::Release() {
  std::lock_guard<std::mutex> lock(state_mutex_);
  in_use_ = false;
  last_used_ = std::chrono::steady_clock::now();
}

Decision<HybridAction> Session::Search(const Budget& budget,
                                       const std::function<bool()>& client_gone, bool* cancelled) {
  // Constructed here, in the planning thread: a CPU budget reads this thread's clock. Past the
  // heap bound the search ends early and its best action stands.
  TerminationCondition stop(
      budget, [&] { return cancel_.load() || (client_gone && client_gone()); }, 2.0);
  stop.StopAtLimit([this] { return HeapPastBound(limits_); });
  {
    std::lock_guard<std::mutex> lock(running_mutex_);
    running_ = &stop;
  }
  if (cancel_) stop.Terminate();
  Decision<HybridAction> d = planner_->Plan(stop, rng_);
  {
    std::lock_guard<std::mutex> lock(running_mutex_);
    running_ = nullptr;
  }
  *cancelled = stop.cancelled();
  if (!*cancelled && stop.limit_reached() && d.status.ok() && d.stats.simulations == 0) {
    d.status = HeapBoundError(limits_, "plan");
  }
  bool deleted = false;
  if (*cancelled) {
    std::lock_guard<std::mutex> persist(persist_mutex_);
    deleted = deleted_;
  }
  if (stop.limit_reached() || deleted) {
    // At the heap bound the tree holds the heap past it: kept, it would refuse this session's
    // own observation (and everyone's plans) until the session is deleted; the next plan
    // starts a fresh tree. A deleted session's tree would stay resident until the last
    // request holding the session lets go of it, after the DELETE gave memory back.
    planner_->DropTree();
    ReleaseFreedMemory();
  }
  return d;
}

api::PlanReply Session::PendLocked(const Decision<HybridAction>& d, const Budget& budget) {
  ++actions_;
  pending_action_ = d.action;
  char id[64];
  std::snprintf(id, sizeof id, "a%lld-%s", static_cast<long long>(actions_), RandomHex(3).c_str());
  pending_action_id_ = id;
  state_ = api::SessionState::kActionPending;
  update_time_ = std::chrono::system_clock::now();
  api::PlanReply reply;
  reply.action_id = pending_action_id_;
  reply.action = ActionViewOf(d.action, *world_);
  reply.expected_value = d.value;
  reply.stats = d.stats;
  reply.candidates = planner_->candidate_stats();
  reply.budget = budget;
  reply.summary.options_given = spec_.options;
  reply.summary.options_used = planner_->OptionsUsed();
  reply.summary.resolved = planner_->ResolvedByLastPlan();
  history_.push_back({static_cast<int>(actions_), reply.action_id, reply.action, d.value, d.stats,
                      reply.candidates, api::UnixMillis(std::chrono::system_clock::now()),
                      std::nullopt});
  if (history_.size() > static_cast<size_t>(api::kMaxHistorySteps)) {
    history_.erase(history_.begin());
  }
  return reply;
}

StatusOr<api::PlanReply> Session::Plan(const Budget& asked,
                                       const std::function<bool()>& client_gone,
                                       SessionStore* store, const Admit& admit) {
  std::unique_lock<std::mutex> op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return Busy();
  if (stale_) return Stale();
  StatusOr<Budget> budget = ClaimForPlan(asked);
  if (!budget.ok()) return budget.status();
  SlotHold slots;
  if (admit) {
    auto held =
        admit([&] { return cancel_.load() || (client_gone && client_gone()); }, SearchThreads());
    if (!held.ok()) {
      Release();
      if (held.status().code() != StatusCode::kCancelled) return held.status();
      return WhyCancelled();
    }
    slots = std::move(held).value();
  }
  bool cancelled = false;
  const Decision<HybridAction> d = Search(*budget, client_gone, &cancelled);
  std::unique_lock<std::mutex> state(state_mutex_);
  in_use_ = false;
  last_used_ = std::chrono::steady_clock::now();
  planning_seconds_ += d.stats.elapsed_ms / 1000.0;
  total_simulations_ += d.stats.simulations;
  unsaved_seconds_ += d.stats.elapsed_ms / 1000.0;
  unsaved_simulations_ += d.stats.simulations;
  if (cancelled || !d.status.ok()) {
    // The planning was spent: stored, so that a restart or another replica counts it (a client
    // that hangs up on every plan would otherwise plan past --max-session-plan-seconds).
    const bool spent = d.stats.elapsed_ms > 0.0 || d.stats.simulations > 0;
    state.unlock();
    if (spent) (void)SaveUnderOp(store);
    if (cancelled || d.status.code() == StatusCode::kCancelled) return WhyCancelled();
    return d.status;
  }
  api::PlanReply reply = PendLocked(d, *budget);
  state.unlock();
  if (Status s = SaveUnderOp(store); !s.ok()) return s;
  reply.session = View();
  return reply;
}

StatusOr<Session::Pending> Session::CheckObservation(const api::ObserveRequest& req) const {
  Pending p;
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    if (state_ != api::SessionState::kActionPending) {
      if (req.action_id == last_action_id_ && !req.action_id.empty()) {
        return FieldError(StatusCode::kFailedPrecondition, "action_id",
                          req.action_id + " was already observed");
      }
      return FieldError(StatusCode::kFailedPrecondition, "action_id",
                        "no action is pending (POST :plan first)");
    }
    if (req.action_id != pending_action_id_) {
      return FieldError(StatusCode::kFailedPrecondition, "action_id",
                        "'" + req.action_id + "' is stale or unknown; the pending action is " +
                            pending_action_id_);
    }
    p.world = world_;
    p.action = pending_action_;
  }
  if (p.is_move() && req.succeeded && !req.robot_state) {
    return InvalidFieldError("robot_state", "missing (required after a MOVE)");
  }
  for (size_t i = 0; i < req.detections.size(); ++i) {
    if (req.detections[i].key == p.world->objects[0].key) {
      return InvalidFieldError("detections[" + std::to_string(i) + "].id", "reserved id");
    }
  }
  return p;
}

Status Session::EnsurePerception(const World& world) {
  if (perception_) return OkStatus();
  const int64_t points = perception::PriorMapPoints(world, {});
  if (points > limits_.max_perception_map_points) {
    return FieldError(StatusCode::kFailedPrecondition, "point_cloud",
                      "one frame could make perception map " + std::to_string(points) +
                          " points of this world around the camera, more than " +
                          std::to_string(limits_.max_perception_map_points) +
                          " (less or smaller furniture); send detections instead");
  }
  perception::TargetModel target;
  for (size_t i = 0; i < target_.photos.size(); ++i) {
    auto image = api::DecodeImage(target_.photos[i], limits_.max_photo_pixels,
                                  "target.photos[" + std::to_string(i) + "]");
    if (!image.ok()) return image.status();
    target.photos.push_back(*image);
  }
  perception_ = std::make_unique<perception::Perception>(world, std::move(target),
                                                         perception::PerceptionOptions{});
  if (stored_tracks_) {
    // Checked when the record was restored.
    if (Status st = perception_->RestoreTracks(stored_tracks_->second, stored_tracks_->first);
        !st.ok()) {
      perception_.reset();
      return Status(StatusCode::kDataLoss, "snapshot: " + st.message());
    }
    stored_tracks_.reset();
  }
  return OkStatus();
}

StatusOr<perception::PerceptionResult> Session::Perceive(perception::SensorFrame frame,
                                                         const Pending& p, bool succeeded,
                                                         object_search::RealObservation* obs,
                                                         SavedTracks* saved) {
  if (Status s = EnsurePerception(*p.world); !s.ok()) return s;
  saved->tracks = perception_->SaveTracks(&saved->next_id);
  if (!p.is_move() && succeeded &&
      object_search::KindOffset(p.action.kind) == object_search::kRemoveOffset) {
    // The object left the scene.
    perception_->DropTrack(p.world->objects[object_search::KindObject(p.action.kind)].key);
  }
  frame.reported = obs->achieved;
  auto result = perception_->Process(frame);
  if (!result.ok()) {
    (void)perception_->RestoreTracks(saved->tracks, saved->next_id);
    return result.status();
  }
  obs->achieved = result->observation.achieved;
  obs->objects = result->observation.objects;
  return result;
}

StatusOr<api::ObserveReply> Session::Observe(api::ObserveRequest req, SessionStore* store) {
  std::unique_lock<std::mutex> op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return Busy();
  if (stale_) return Stale();
  // An observation grows every particle by the objects it adds.
  if (Status heap = CheckHeap(limits_, "observe"); !heap.ok()) return heap;
  StatusOr<Pending> pending = CheckObservation(req);
  if (!pending.ok()) return pending.status();
  const Pending& p = *pending;
  object_search::RealObservation obs;
  obs.achieved = req.robot_state.value_or(p.world->robot_config);
  obs.objects = std::move(req.detections);

  // Apply to a copy and swap on success: a rejected observation changes nothing.
  World next = *p.world;
  bool done = false;
  using object_search::ActionOutcome;
  ActionOutcome outcome = req.succeeded ? ActionOutcome::kMoved : ActionOutcome::kIllegal;
  if (!p.is_move()) {
    const int object = object_search::KindObject(p.action.kind);
    const int offset = object_search::KindOffset(p.action.kind);
    if (req.succeeded) {
      outcome = object_search::SuccessfulOutcome(offset, next.objects[object].status);
      done = outcome == ActionOutcome::kRemovedTarget;
    }
    // A removal the robot could not make leaves the object unremovable in the belief.
    if (Status s = object_search::ApplyDiscreteOutcome(&next, object, offset, req.succeeded);
        !s.ok()) {
      return s;
    }
  }
  const double reward = object_search::RewardOf(next.params, outcome);
  // Raw data: perception turns the frame into the corrected pose and detections. Its tracks are
  // restored if anything below fails.
  SavedTracks saved;
  std::optional<perception::PerceptionResult> perceived;
  if (req.frame) {
    auto result = Perceive(std::move(*req.frame), p, req.succeeded, &obs, &saved);
    if (!result.ok()) return result.status();
    perceived = std::move(result).value();
  }
  const bool raw = perceived.has_value();
  auto fail = [&](Status s) {
    if (raw) (void)perception_->RestoreTracks(saved.tracks, saved.next_id);
    return s;
  };
  std::vector<int> detected;
  std::set<std::string> fresh;
  for (const auto& det : obs.objects) {
    const int index = next.FindObject(det.key);
    if (index < 0) fresh.insert(det.key);
    detected.push_back(index);
  }
  const char* field = raw ? "point_cloud" : "detections";
  if (next.objects.size() + fresh.size() > object_search::kMaxObjects) {
    return fail(InvalidFieldError(field, "the session would know more than " +
                                             std::to_string(object_search::kMaxKnownObjects) +
                                             " objects"));
  }
  const object_search::Observation key = model_->RealObservationKey(detected);
  if (Status s = object_search::ApplyRealObservation(&next, obs); !s.ok()) {
    return fail(InvalidFieldError(field, s.message()));
  }
  const api::StepRecord::Outcome step{req.succeeded,
                                      reward,
                                      static_cast<int>(obs.objects.size()),
                                      static_cast<int>(fresh.size()),
                                      raw,
                                      done,
                                      api::UnixMillis(std::chrono::system_clock::now()),
                                      next.robot_config};
  Advance(std::make_shared<const World>(std::move(next)), p.action, key, !fresh.empty(), step);
  if (Status s = SaveUnderOp(store); !s.ok()) return s;
  api::ObserveReply reply;
  reply.done = done;
  reply.reward = reward;
  reply.perception = std::move(perceived);
  reply.session = View();
  return reply;
}

void Session::Advance(std::shared_ptr<const World> updated, const HybridAction& action,
                      const object_search::Observation& key, bool new_objects,
                      const api::StepRecord::Outcome& step) {
  model_->SetWorld(updated);
  planner_->OnWorldChanged();
  {
    std::lock_guard<std::mutex> lock(state_mutex_);
    world_ = updated;
    last_action_id_ = pending_action_id_;
    pending_action_id_.clear();
    state_ = step.done ? api::SessionState::kDone : api::SessionState::kReady;
    update_time_ = std::chrono::system_clock::now();
    last_used_ = std::chrono::steady_clock::now();
    if (perception_) perception_tracks_ = perception_->tracks();
    if (!history_.empty() && history_.back().action_id == last_action_id_) {
      history_.back().outcome = step;
    }
  }
  Reseed();
  if (step.done) {
    // Nothing more is planned in a finished episode: its tree (megabytes) goes now, not when the
    // session is deleted or expires.
    planner_->DropTree();
    ReleaseFreedMemory();
    return;
  }
  auto belief = FreshBelief();
  if (new_objects) {
    planner_->SetBelief(std::move(belief));
  } else {
    planner_->AdvanceTo(action, key, std::move(belief));
  }
}

Status Session::SaveUnderOp(SessionStore* store) {
  // The caller holds op_mutex_ (or owns the session alone): perception and the planner are still.
  double seconds = 0.0;
  int64_t simulations = 0;
  const api::SessionRecord record = RecordLocked(&seconds, &simulations);
  std::lock_guard<std::mutex> lock(persist_mutex_);
  if (deleted_) return Status(StatusCode::kAborted, "the session was deleted meanwhile");
  // A copy whose save failed may hold usage KeepUsage moved on to a newer copy: it is never
  // saved again (the request gets 409; the session is loaded again from the store).
  if (stale_) return Stale();
  auto version = store->Save(record, version_);
  if (!version.ok()) {
    stale_ = true;  // this copy is ahead of what was acknowledged
    return version.status();
  }
  version_ = *version;
  // What KeepUsage added since the record was taken stays unsaved.
  std::lock_guard<std::mutex> state(state_mutex_);
  unsaved_seconds_ = std::max(0.0, unsaved_seconds_ - seconds);
  unsaved_simulations_ = std::max<int64_t>(0, unsaved_simulations_ - simulations);
  return OkStatus();
}

Status Session::WhyCancelled() const {
  std::lock_guard<std::mutex> persist(persist_mutex_);
  if (deleted_) return Status(StatusCode::kAborted, "the session was deleted while planning");
  if (superseded_) {
    return Status(StatusCode::kAborted,
                  "another request saved the session while this plan ran; read it and plan again");
  }
  return CancelledError(cancel_ ? "the server is stopping" : "the client closed the connection");
}

Status Session::Save(SessionStore* store) {
  std::lock_guard<std::mutex> op(op_mutex_);
  return SaveUnderOp(store);
}

Status Session::SaveIfIdle(SessionStore* store) {
  std::unique_lock<std::mutex> op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock()) return FailedPreconditionError("a request works on the session");
  return SaveUnderOp(store);
}

Status Session::Delete(SessionStore* store) {
  {
    // The snapshot first: a session whose snapshot could not be removed lives on (it would come
    // back at the next start), and the caller may retry.
    std::lock_guard<std::mutex> lock(persist_mutex_);
    if (!deleted_) {
      if (Status s = store ? store->Delete(id_) : OkStatus(); !s.ok()) return s;
      deleted_ = true;
    }
  }
  Cancel();
  return OkStatus();
}

int64_t Session::version() const {
  std::lock_guard<std::mutex> lock(persist_mutex_);
  return version_;
}

bool Session::busy() const {
  std::unique_lock<std::mutex> op(op_mutex_, std::try_to_lock);
  return !op.owns_lock();
}

bool Session::has_unsaved_usage() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return unsaved_seconds_ > 1e-9 || unsaved_simulations_ > 0;
}

void Session::DropUnsavedUsage() {
  std::lock_guard<std::mutex> lock(state_mutex_);
  unsaved_seconds_ = 0.0;
  unsaved_simulations_ = 0;
}

void Session::Supersede() {
  superseded_ = true;
  Cancel();
}

bool Session::ExpireIfIdle(SessionStore* store) {
  std::unique_lock<std::mutex> op(op_mutex_, std::try_to_lock);
  if (!op.owns_lock() || IdleSeconds() <= ttl_seconds_) return false;
  // A snapshot that cannot be removed keeps the session (tried again at the next round).
  return Delete(store).ok();
}

}  // namespace npfkct::server
