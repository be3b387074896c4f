// How a session is restored from its record, recorded and shown: the parts of Session that
// turn its state into the API layer's types and back (session.cc has the state machine).
#include <algorithm>
#include <utility>

#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/perception/perception.h"
#include "npfkct/server/session.h"

namespace npfkct::server {
namespace {

using object_search::World;

}  // namespace

StatusOr<std::unique_ptr<Session>> Session::Restore(api::SessionRecord r, int64_t version,
                                                    const SamplerFactory& samplers,
                                                    const object_search::PlannerRegistry& planners,
                                                    SessionLimits limits) {
  std::unique_ptr<Session> s(new Session());
  s->id_ = std::move(r.id);
  s->display_name_ = std::move(r.display_name);
  s->spec_ = std::move(r.planner);
  s->target_ = std::move(r.target);
  s->seed_ = r.seed;
  s->ttl_seconds_ = r.ttl_seconds;
  s->limits_ = limits;
  s->create_time_ = api::FromUnixMillis(r.create_time_ms);
  s->update_time_ = api::FromUnixMillis(r.update_time_ms);
  s->last_used_ = std::chrono::steady_clock::now();
  s->world_ = std::make_shared<const World>(std::move(r.world));
  s->state_ = r.state;
  s->actions_ = r.actions;
  s->total_simulations_ = r.total_simulations;
  s->planning_seconds_ = r.planning_seconds_used;
  s->last_action_id_ = std::move(r.last_action_id);
  s->pending_action_id_ = std::move(r.pending_action_id);
  s->pending_action_ = std::move(r.pending_action);
  s->history_ = std::move(r.history);
  s->version_ = version;
  if (Status st = s->Init(samplers, planners); !st.ok()) return st;
  if (r.perception) {
    if (perception::PriorMapPoints(*s->world_, {}) > limits.max_perception_map_points) {
      return Status(StatusCode::kDataLoss, "snapshot: perception tracks for a world too large");
    }
    if (!perception::CheckTracks(r.perception->second, r.perception->first, *s->world_).ok()) {
      return Status(StatusCode::kDataLoss, "snapshot: perception tracks");
    }
    s->perception_tracks_ = static_cast<int>(r.perception->second.size());
    s->stored_tracks_ = std::move(r.perception);
  }
  return s;
}

api::ActionView Session::ActionViewOf(const HybridAction& a, const World& w) {
  api::ActionView v;
  if (a.kind == object_search::kMoveKind) {
    v.type = api::ActionView::Type::kMove;
    v.configuration = object_search::ObjectSearchModel::ConfigOf(a.x);
    return v;
  }
  static constexpr api::ActionView::Type kTypes[] = {api::ActionView::Type::kDeclareTarget,
                                                     api::ActionView::Type::kDeclareObstacle,
                                                     api::ActionView::Type::kRemove};
  v.type = kTypes[object_search::KindOffset(a.kind)];
  const int i = object_search::KindObject(a.kind);
  if (i >= 0 && i < static_cast<int>(w.objects.size())) v.object_id = w.objects[i].key;
  // Where the object is, as the robot last saw it: what it needs to act on it.
  if (i > 0 && i < static_cast<int>(w.objects.size())) v.object_box = w.objects[i].box;
  return v;
}

api::SessionView Session::ViewLocked() const {
  api::SessionView v;
  v.id = id_;
  v.display_name = display_name_;
  v.state = state_;
  v.create_time = create_time_;
  v.update_time = update_time_;
  v.ttl_seconds = ttl_seconds_;
  v.planner = spec_;
  v.seed = seed_;
  v.target_description = target_.description;
  v.photo_count = static_cast<int>(target_.photos.size());
  if (perception_tracks_ >= 0) v.perception_tracks = perception_tracks_;
  v.step = world_->steps;
  v.robot = world_->robot_config;
  v.object_count = static_cast<int>(world_->objects.size()) - 1;
  if (state_ == api::SessionState::kActionPending) {
    v.pending = std::make_pair(pending_action_id_, ActionViewOf(pending_action_, *world_));
  }
  v.total_simulations = total_simulations_;
  v.planning_seconds_used = planning_seconds_;
  return v;
}

api::SessionView Session::ViewOf(const api::SessionRecord& r) {
  api::SessionView v;
  v.id = r.id;
  v.display_name = r.display_name;
  v.state = r.state;
  v.create_time = api::FromUnixMillis(r.create_time_ms);
  v.update_time = api::FromUnixMillis(r.update_time_ms);
  v.ttl_seconds = r.ttl_seconds;
  v.planner = r.planner;
  v.seed = r.seed;
  v.target_description = r.target.description;
  v.photo_count = static_cast<int>(r.target.photos.size());
  if (r.perception) v.perception_tracks = static_cast<int>(r.perception->second.size());
  v.step = r.world.steps;
  v.robot = r.world.robot_config;
  v.object_count = static_cast<int>(r.world.objects.size()) - 1;
  if (r.state == api::SessionState::kActionPending) {
    v.pending = std::make_pair(r.pending_action_id, ActionViewOf(r.pending_action, r.world));
  }
  v.total_simulations = r.total_simulations;
  v.planning_seconds_used = r.planning_seconds_used;
  return v;
}

void Session::KeepUsage(Session& replaced) {
  if (&replaced == this) return;
  double seconds = 0.0;
  int64_t simulations = 0;
  {
    std::lock_guard<std::mutex> lock(replaced.state_mutex_);
    seconds = std::exchange(replaced.unsaved_seconds_, 0.0);
    simulations = std::exchange(replaced.unsaved_simulations_, 0);
  }
  std::lock_guard<std::mutex> lock(state_mutex_);
  planning_seconds_ += seconds;
  total_simulations_ += simulations;
  unsaved_seconds_ += seconds;
  unsaved_simulations_ += simulations;
}

std::string SummaryOf(const api::SessionRecord& record) {
  return api::EncodeSessionSummary(Session::ViewOf(record));
}

api::SessionView Session::View() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return ViewLocked();
}

std::shared_ptr<const World> Session::Belief() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return world_;
}

std::vector<api::StepRecord> Session::Steps() const {
  std::lock_guard<std::mutex> lock(state_mutex_);
  return history_;
}

api::SessionRecord Session::RecordLocked(double* unsaved_seconds,
                                         int64_t* unsaved_simulations) const {
  api::SessionRecord r;
  r.id = id_;
  r.display_name = display_name_;
  r.planner = spec_;
  r.seed = seed_;
  r.ttl_seconds = ttl_seconds_;
  r.target = target_;
  r.create_time_ms = api::UnixMillis(create_time_);
  std::lock_guard<std::mutex> lock(state_mutex_);
  r.state = state_;
  r.actions = actions_;
  r.total_simulations = total_simulations_;
  r.planning_seconds_used = planning_seconds_;
  *unsaved_seconds = unsaved_seconds_;
  *unsaved_simulations = unsaved_simulations_;
  r.update_time_ms = api::UnixMillis(update_time_);
  r.last_action_id = last_action_id_;
  r.pending_action_id = pending_action_id_;
  r.pending_action = pending_action_;
  r.world = *world_;
  r.history = history_;
  if (perception_) {
    int next_id = 0;
    auto tracks = perception_->SaveTracks(&next_id);
    r.perception = std::make_pair(next_id, std::move(tracks));
  } else {
    r.perception = stored_tracks_;
  }
  return r;
}

}  // namespace npfkct::server
