#include "registry.h"

#include <spdlog/spdlog.h>

namespace npfkct::server {

Registry::Registry(const ServerOptions& options, Metrics* metrics)
    : options_(options), metrics_(metrics) {
  session_limits_.max_plan_seconds = options.limits.max_session_plan_seconds;
  session_limits_.max_perception_map_points = options.limits.max_perception_map_points;
  session_limits_.max_photo_pixels = options.limits.max_photo_pixels;
}

Registry::~Registry() { StopReaper(); }

StatusOr<int> Registry::Open(const SamplerFactory& samplers) {
  if (options_.state_dir.empty()) {
    store_ = MakeMemoryStore();
    return 0;
  }
  auto store =
      DirectoryStore::Open(options_.state_dir, options_.limits, options_.max_snapshot_bytes);
  if (!store.ok()) return store.status();
  store_ = std::move(store).value();
  // Entries that do not restore do not count against --max-sessions; the listing itself is
  // bounded so that a directory full of junk cannot stall the start.
  const size_t max = static_cast<size_t>(options_.max_sessions);
  auto ids = store_->List(16 * max + 1024);
  if (!ids.ok()) return ids.status();
  int restored = 0;
  for (const std::string& id : *ids) {
    if (static_cast<size_t>(restored) >= max) {
      spdlog::warn(
          "the state directory holds more than --max-sessions={} sessions; the rest "
          "stay on disk, not restored",
          max);
      break;
    }
    auto loaded = store_->Load(id);
    if (!loaded.ok()) {
      spdlog::warn("skipping snapshot {}: {}", id, loaded.status().ToString());
      continue;
    }
    auto session =
        Session::Restore(std::move(loaded->record), loaded->version, samplers, session_limits_);
    if (!session.ok()) {
      spdlog::warn("skipping snapshot {}: {}", id, session.status().ToString());
      continue;
    }
    sessions_[id] = std::move(session).value();
    ++restored;
  }
  metrics_->SetSessions(static_cast<int>(sessions_.size()));
  return restored;
}

std::shared_ptr<Session> Registry::Find(const std::string& id) const {
  std::shared_lock lock(mutex_);
  auto it = sessions_.find(id);
  return it == sessions_.end() ? nullptr : it->second;
}

std::vector<std::shared_ptr<Session>> Registry::Page(const std::string& token, int size,
                                                     std::string* next) const {
  std::vector<std::shared_ptr<Session>> page;
  std::shared_lock lock(mutex_);
  auto it = sessions_.upper_bound(token);
  for (; it != sessions_.end() && static_cast<int>(page.size()) < size; ++it) {
    page.push_back(it->second);
  }
  if (it != sessions_.end() && !page.empty()) *next = page.back()->id();
  return page;
}

int Registry::size() const {
  std::shared_lock lock(mutex_);
  return static_cast<int>(sessions_.size());
}

Status Registry::FullError() const {
  return ResourceExhaustedError("sessions: the server holds its maximum of " +
                                std::to_string(options_.max_sessions) +
                                " sessions (--max-sessions); delete one or retry later");
}

StatusOr<std::shared_ptr<Session>> Registry::Add(std::unique_ptr<Session> created) {
  std::shared_ptr<Session> session = std::move(created);
  if (size() >= options_.max_sessions) return FullError();
  if (Status s = session->Save(store_.get()); !s.ok()) return s;
  std::unique_lock lock(mutex_);
  if (static_cast<int>(sessions_.size()) >= options_.max_sessions) {
    lock.unlock();
    (void)session->Delete(store_.get());
    return FullError();
  }
  sessions_[session->id()] = session;
  metrics_->SetSessions(static_cast<int>(sessions_.size()));
  return session;
}

Status Registry::Remove(const std::shared_ptr<Session>& session) {
  {
    std::unique_lock lock(mutex_);
    auto it = sessions_.find(session->id());
    if (it == sessions_.end() || it->second != session) {
      return NotFoundError("sessions/" + session->id() + " not found");
    }
    sessions_.erase(it);
    metrics_->SetSessions(static_cast<int>(sessions_.size()));
  }
  // Cancels a running plan and removes the snapshot under the session's persistence lock.
  return session->Delete(store_.get());
}

void Registry::CancelAll() {
  std::shared_lock lock(mutex_);
  for (const auto& [id, s] : sessions_) s->Cancel();
}

void Registry::Reap() {
  std::vector<std::shared_ptr<Session>> all;
  {
    std::shared_lock lock(mutex_);
    for (const auto& [id, s] : sessions_) all.push_back(s);
  }
  for (const auto& s : all) {
    if (s->IdleSeconds() <= s->ttl_seconds()) continue;
    // Expires only when no request works on it: a plan longer than the TTL keeps it alive.
    if (!s->ExpireIfIdle(store_.get())) continue;
    {
      std::unique_lock lock(mutex_);
      auto it = sessions_.find(s->id());
      if (it == sessions_.end() || it->second != s) continue;
      sessions_.erase(it);
      metrics_->SetSessions(static_cast<int>(sessions_.size()));
    }
    metrics_->CountExpired();
    spdlog::info("session {} expired", s->id());
  }
}

void Registry::StartReaper() {
  reaper_ = std::thread([this] {
    std::unique_lock<std::mutex> lock(stop_mutex_);
    while (!stopping_) {
      stop_cv_.wait_for(lock, std::chrono::milliseconds(250));
      if (stopping_) break;
      lock.unlock();
      Reap();
      lock.lock();
    }
  });
}

void Registry::StopReaper() {
  {
    std::lock_guard<std::mutex> lock(stop_mutex_);
    stopping_ = true;
  }
  stop_cv_.notify_all();
  if (reaper_.joinable()) reaper_.join();
}

}  // namespace npfkct::server
