#include "registry.h"

#include <spdlog/spdlog.h>
#include <sys/random.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>

#include "npfkct/api/api.h"
#include "npfkct/server/postgres_store.h"

namespace npfkct::server {
namespace {

using Clock = std::chrono::steady_clock;

Status NotHeld(const std::string& id) {
  return NotFoundError("sessions/" + id.substr(0, 64) + " not found");
}

// A store that times every call into the metrics, counts conflicts and failures, and remembers
// whether the store answered last time (for /healthz).
class InstrumentedStore : public SessionStore {
 public:
  InstrumentedStore(std::unique_ptr<SessionStore> store, Metrics* metrics)
      : store_(std::move(store)), metrics_(metrics) {}

  StatusOr<int64_t> Save(const api::SessionRecord& r, int64_t expected) override {
    return Timed("save", [&] { return store_->Save(r, expected); });
  }
  Status Delete(const std::string& id, bool* existed) override {
    return Timed("delete", [&] { return store_->Delete(id, existed); });
  }
  StatusOr<std::vector<std::string>> List(size_t limit, const std::string& after) override {
    return Timed("list", [&] { return store_->List(limit, after); });
  }
  StatusOr<std::vector<Listed>> ListViews(size_t limit, const std::string& after) override {
    return Timed("list", [&] { return store_->ListViews(limit, after); });
  }
  StatusOr<Loaded> Load(const std::string& id) override {
    return Timed("load", [&] { return store_->Load(id); });
  }
  bool shared() const override { return store_->shared(); }
  StatusOr<Refreshed> Refresh(const std::string& id, int64_t held) override {
    return Timed("refresh", [&] { return store_->Refresh(id, held); });
  }
  StatusOr<std::vector<std::string>> KeepAlive(const std::vector<std::string>& ids) override {
    return Timed("keepalive", [&] { return store_->KeepAlive(ids); });
  }
  StatusOr<std::vector<std::string>> DeleteExpired(size_t limit) override {
    return Timed("expire", [&] { return store_->DeleteExpired(limit); });
  }
  Status Ping() override {
    return Timed("ping", [&] { return store_->Ping(); });
  }
  std::string backend() const override { return store_->backend(); }

  StoreHealth health() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return health_;
  }

 private:
  static const Status& StatusOf(const Status& s) { return s; }
  template <typename T>
  static const Status& StatusOf(const StatusOr<T>& s) {
    return s.status();
  }

  template <typename F>
  auto Timed(const char* op, F&& call) -> decltype(call()) {
    const auto start = Clock::now();
    auto result = call();
    const Status& s = StatusOf(result);
    const bool conflict = s.code() == StatusCode::kAborted;
    const bool failed = !s.ok() && s.code() != StatusCode::kNotFound && !conflict &&
                        s.code() != StatusCode::kAlreadyExists &&
                        s.code() != StatusCode::kResourceExhausted;
    metrics_->ObserveStore(op, std::chrono::duration<double>(Clock::now() - start).count(), failed);
    if (conflict && std::string(op) == "save") metrics_->CountStoreConflict();
    if (s.code() == StatusCode::kUnavailable || s.ok()) {
      std::lock_guard<std::mutex> lock(mutex_);
      const bool was_ok = health_.ok;
      health_.ok = s.ok();
      health_.message = s.ok() ? "" : std::string(s.message());
      metrics_->SetStoreUp(health_.ok);
      if (was_ok != health_.ok) {
        if (health_.ok) {
          spdlog::info("the session store answers again");
        } else {
          spdlog::warn("the session store is unavailable: {}", health_.message);
        }
      }
    }
    return result;
  }

  std::unique_ptr<SessionStore> store_;
  Metrics* metrics_;
  mutable std::mutex mutex_;
  StoreHealth health_;
};

std::string ReplicaName(const ServerOptions& o) {
  char host[256] = "";
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return std::string(host) + ":" + std::to_string(o.port) + "/" + std::to_string(::getpid());
}

}  // namespace

PostgresStoreOptions StoreOptions(const ServerOptions& o) {
  PostgresStoreOptions p;
  p.url = o.store_url;
  p.pool_size = o.store_pool;
  p.timeout_seconds = o.store_timeout_seconds;
  p.wait_seconds = o.store_wait_seconds;
  p.max_snapshot_bytes = o.max_snapshot_bytes;
  p.max_sessions = o.max_stored_sessions;
  return p;
}

std::string Registry::NewId() {
  unsigned char bytes[16];
  size_t done = 0;
  while (done < sizeof bytes) {
    const ssize_t n = ::getrandom(bytes + done, sizeof bytes - done, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) std::abort();  // the kernel's random source never fails once initialised
    done += static_cast<size_t>(n);
  }
  char hex[33];
  for (size_t i = 0; i < sizeof bytes; ++i) std::snprintf(hex + 2 * i, 3, "%02x", bytes[i]);
  return hex;
}

Registry::Registry(const ServerOptions& options, Metrics* metrics)
    : options_(options), metrics_(metrics) {
  session_limits_.max_plan_seconds = options.limits.max_session_plan_seconds;
  session_limits_.max_heap_bytes = options.limits.max_heap_mb << 20;
  session_limits_.max_perception_map_points = options.limits.max_perception_map_points;
  session_limits_.max_photo_pixels = options.limits.max_photo_pixels;
}

Registry::~Registry() { StopReaper(); }

StatusOr<int> Registry::Open(const SamplerFactory& samplers) {
  samplers_ = samplers;
  std::unique_ptr<SessionStore> store;
  if (!options_.store_url.empty()) {
    PostgresStoreOptions o = StoreOptions(options_);
    o.replica = ReplicaName(options_);
    auto opened = OpenPostgresStore(o, options_.limits);
    if (!opened.ok()) return opened.status();
    store = std::move(opened).value();
    spdlog::info("session store {} (pool of {} connections)", RedactedStoreUrl(o.url), o.pool_size);
  } else if (!options_.state_dir.empty()) {
    auto opened =
        DirectoryStore::Open(options_.state_dir, options_.limits, options_.max_snapshot_bytes);
    if (!opened.ok()) return opened.status();
    store = std::move(opened).value();
  } else {
    store = MakeMemoryStore();
  }
  shared_ = store->shared();
  store_ = std::make_unique<InstrumentedStore>(std::move(store), metrics_);
  metrics_->SetStoreUp(true);
  if (shared_) return 0;  // sessions are loaded when a request names them
  // Entries that do not restore do not count against --max-sessions; the listing itself is
  // bounded so that a directory full of junk cannot stall the start.
  const size_t max = static_cast<size_t>(options_.max_sessions);
  auto ids = store_->List(16 * max + 1024, "");
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
    auto session = Session::Restore(std::move(loaded->record), loaded->version, samplers,
                                    options_.planners, session_limits_);
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

StatusOr<std::shared_ptr<Session>> Registry::Acquire(const std::string& id) {
  if (!api::IsSessionId(id)) return NotHeld(id);
  std::shared_ptr<Session> held;
  {
    std::shared_lock lock(mutex_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) held = it->second;
  }
  if (!shared_) {
    if (!held) return NotHeld(id);
    if (!held->stale()) return held;
    // A save failed (a full disk): what was acknowledged is the stored record.
    auto loaded = store_->Load(id);
    if (!loaded.ok()) return loaded.status();
    return Install(std::move(loaded).value(), held);
  }
  // Fleet: the store says which version is current (and restarts the session's time to live).
  const int64_t held_version = held && !held->stale() ? held->version() : -1;
  auto fresh = store_->Refresh(id, held_version);
  if (!fresh.ok()) {
    if (fresh.status().code() != StatusCode::kNotFound) return fresh.status();
    if (held) Drop(id);
    return NotHeld(id);
  }
  if (!fresh->loaded) return held;
  return Install(std::move(*fresh->loaded), held);
}

bool Registry::KeepUsageOf(const std::shared_ptr<Session>& stale) {
  auto fresh = Acquire(stale->id());
  if (fresh.status().code() == StatusCode::kNotFound) return true;  // deleted: nothing to count
  if (!fresh.ok() || *fresh == stale) return false;
  (*fresh)->KeepUsage(*stale);  // unless Install moved it already (the copy was held)
  // Best effort: the upkeep saves the fresh copy later if this fails or a request holds it.
  (void)(*fresh)->SaveIfIdle(store_.get());
  return true;
}

std::shared_ptr<std::mutex> Registry::LoadLock(const std::string& id) {
  std::lock_guard<std::mutex> lock(load_locks_mutex_);
  for (auto it = load_locks_.begin(); it != load_locks_.end();) {
    it = it->second.expired() ? load_locks_.erase(it) : std::next(it);
  }
  std::shared_ptr<std::mutex> held = load_locks_[id].lock();
  if (!held) {
    held = std::make_shared<std::mutex>();
    load_locks_[id] = held;
  }
  return held;
}

StatusOr<std::shared_ptr<Session>> Registry::Install(SessionStore::Loaded loaded,
                                                     const std::shared_ptr<Session>& replaced) {
  const std::string id = loaded.record.id;
  // The held copy's own save, which a request's refresh read before the copy learnt its new
  // version: the copy is current (replacing it would leave its request working unseen).
  if (replaced && !replaced->stale() && replaced->version() >= loaded.version) return replaced;
  // One load of a session at a time: requests that arrive together (a fleet replica that does
  // not hold the session, or holds an older version) wait for the first, then share its copy.
  const std::shared_ptr<std::mutex> load_lock = LoadLock(id);
  std::lock_guard<std::mutex> loading(*load_lock);
  std::shared_ptr<Session> held;  // the copy held now (another request may have loaded one)
  {
    std::shared_lock lock(mutex_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) held = it->second;
  }
  if (held && held != replaced && !held->stale() && held->version() >= loaded.version) {
    if (replaced) held->KeepUsage(*replaced);  // another request loaded it meanwhile
    return held;
  }
  // A session holds its particles and tree: none is loaded past the heap bound.
  if (Status heap = CheckHeap(session_limits_, "load a session"); !heap.ok()) return heap;
  auto restored = Session::Restore(std::move(loaded.record), loaded.version, samplers_,
                                   options_.planners, session_limits_);
  if (!restored.ok()) {
    spdlog::warn("session {} cannot be loaded from the store: {}", id,
                 restored.status().ToString());
    return restored.status();
  }
  std::shared_ptr<Session> session = std::move(restored).value();
  metrics_->CountLoaded();
  {
    // Only loads (under the load lock) install a session of an existing id.
    std::unique_lock lock(mutex_);
    if (sessions_.find(id) == sessions_.end() && !MakeRoomLocked(1)) return FullError();
    sessions_[id] = session;
    metrics_->SetSessions(static_cast<int>(sessions_.size()));
  }
  for (const std::shared_ptr<Session>& old : {replaced, held}) {
    if (!old || old == session) continue;
    // A request still working on (or about to work on) a copy older than the new one could only
    // fail to save it, and DELETE, expiry and keep-alive see only the new copy: it stops now.
    if (old->stale() || old->version() < session->version()) old->Supersede();
    // A copy whose save failed or lost a race (stale, or older than the store) planned
    // meanwhile: the stored record does not count that.
    session->KeepUsage(*old);
  }
  return session;
}

bool Registry::MakeRoomLocked(int room) {
  while (static_cast<int>(sessions_.size()) + room > options_.max_sessions) {
    if (!shared_) return false;
    // The least recently used session no request works on; it stays in the store.
    auto victim = sessions_.end();
    double idlest = 0.0;
    for (auto it = sessions_.begin(); it != sessions_.end(); ++it) {
      const double idle = it->second->IdleSeconds();
      // A copy holding planning the store does not have yet stays (Maintain saves it).
      if (idle > idlest && !it->second->busy() && !it->second->has_unsaved_usage()) {
        idlest = idle;
        victim = it;
      }
    }
    if (victim == sessions_.end()) return false;
    sessions_.erase(victim);
    metrics_->CountEvicted();
  }
  metrics_->SetSessions(static_cast<int>(sessions_.size()));
  return true;
}

void Registry::Drop(const std::string& id) {
  std::shared_ptr<Session> held;
  {
    std::unique_lock lock(mutex_);
    auto it = sessions_.find(id);
    if (it == sessions_.end()) return;
    held = std::move(it->second);
    sessions_.erase(it);
    metrics_->SetSessions(static_cast<int>(sessions_.size()));
  }
  (void)held->Delete(nullptr);  // stops its plan; never saved again
  held.reset();
  ReleaseFreedMemory();
}

StatusOr<std::vector<api::SessionView>> Registry::Page(const std::string& token, int size,
                                                       std::string* next) const {
  std::vector<api::SessionView> page;
  if (!shared_) {
    std::shared_lock lock(mutex_);
    auto it = sessions_.upper_bound(token);
    for (; it != sessions_.end() && static_cast<int>(page.size()) < size; ++it) {
      page.push_back(it->second->View());
    }
    if (it != sessions_.end() && !page.empty()) *next = page.back().id;
    return page;
  }
  // Fleet: the store's sessions from the summaries it keeps beside the records (a page is at
  // most 100 of them). A record is read only for a row without one (saved by a server of schema
  // version 1): records hold worlds and photos, megabytes each.
  size = std::min(size, 100);
  auto listed = store_->ListViews(static_cast<size_t>(size) + 1, token);
  if (!listed.ok()) return listed.status();
  for (size_t i = 0; i < listed->size() && static_cast<int>(i) < size; ++i) {
    if ((*listed)[i].view) {
      page.push_back(std::move(*(*listed)[i].view));
      continue;
    }
    auto loaded = store_->Load((*listed)[i].id);
    if (loaded.status().code() == StatusCode::kNotFound) continue;  // deleted meanwhile
    if (!loaded.ok()) return loaded.status();
    page.push_back(Session::ViewOf(loaded->record));
  }
  if (static_cast<int>(listed->size()) > size) *next = (*listed)[size - 1].id;
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

Status Registry::CheckCapacity() {
  // A session holds its particles and tree: none is created past the heap bound.
  if (Status heap = CheckHeap(session_limits_, "create a session"); !heap.ok()) return heap;
  std::unique_lock lock(mutex_);
  return MakeRoomLocked(1) ? OkStatus() : FullError();
}

StatusOr<std::shared_ptr<Session>> Registry::Add(std::unique_ptr<Session> created) {
  std::shared_ptr<Session> session = std::move(created);
  if (Status s = CheckCapacity(); !s.ok()) return s;
  if (Status s = session->Save(store_.get()); !s.ok()) return s;
  std::unique_lock lock(mutex_);
  if (!MakeRoomLocked(1)) {
    lock.unlock();
    (void)session->Delete(store_.get());
    return FullError();
  }
  sessions_[session->id()] = session;
  metrics_->SetSessions(static_cast<int>(sessions_.size()));
  return session;
}

Status Registry::Remove(const std::string& id) {
  const Status removed = RemoveSession(id);
  ReleaseFreedMemory();  // the session is gone unless a request still holds it
  return removed;
}

Status Registry::RemoveSession(const std::string& id) {
  if (!api::IsSessionId(id)) return NotHeld(id);
  std::shared_ptr<Session> held;
  {
    std::unique_lock lock(mutex_);
    auto it = sessions_.find(id);
    if (it != sessions_.end()) held = it->second;
  }
  auto forget = [&] {
    std::unique_lock lock(mutex_);
    auto it = sessions_.find(id);
    if (it == sessions_.end() || it->second != held) return;
    sessions_.erase(it);
    metrics_->SetSessions(static_cast<int>(sessions_.size()));
  };
  if (!shared_) {
    if (!held) return NotHeld(id);
    // Removes the snapshot under the session's persistence lock, then cancels a running plan;
    // a snapshot that cannot be removed keeps the session held (the client may retry), since
    // it would come back at the next start.
    if (Status s = held->Delete(store_.get()); !s.ok()) return s;
    forget();
    return OkStatus();
  }
  if (held) forget();
  // Fleet: the row is the session, wherever it is held. The held copy is marked deleted first
  // (waiting for a save in flight), so it is never written again.
  if (held) (void)held->Delete(nullptr);
  bool existed = false;
  if (Status s = store_->Delete(id, &existed); !s.ok()) return s;
  return existed ? OkStatus() : NotHeld(id);
}

void Registry::CancelAll() {
  std::shared_lock lock(mutex_);
  for (const auto& [id, s] : sessions_) s->Cancel();
}

StoreHealth Registry::store_health() const {
  if (!shared_ || !store_) return StoreHealth{};
  return static_cast<const InstrumentedStore*>(store_.get())->health();
}

void Registry::Reap() {
  bool expired = false;
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
    expired = true;
    spdlog::info("session {} expired", s->id());
  }
  all.clear();
  if (expired) ReleaseFreedMemory();
}

// Fleet upkeep: keeps the sessions requests work on from expiring (every tick); once a second,
// checks the store, deletes expired sessions (any replica may) and drops idle ones from memory.
void Registry::Maintain(bool full_round) {
  std::vector<std::string> busy;
  std::vector<std::string> idle;
  std::vector<std::shared_ptr<Session>> unsaved;
  {
    std::shared_lock lock(mutex_);
    for (const auto& [id, s] : sessions_) {
      if (s->busy()) {
        busy.push_back(id);
      } else if (full_round && s->has_unsaved_usage()) {
        unsaved.push_back(s);
      } else if (full_round &&
                 s->IdleSeconds() > std::min(options_.evict_idle_seconds, s->ttl_seconds())) {
        idle.push_back(id);
      }
    }
  }
  if (!busy.empty()) {
    // A session deleted through another replica (or expired) stops its plan here within a tick.
    auto kept = store_->KeepAlive(busy);
    if (kept.ok()) {
      for (const std::string& id : busy) {
        if (std::find(kept->begin(), kept->end(), id) == kept->end()) {
          spdlog::info("session {} is no longer stored; its request stops", id);
          Drop(id);
        }
      }
    }
  }
  if (!full_round) return;
  // Planning moved to a copy by KeepUsage while a request held it, which then ended unsaved (a
  // stale copy passes it on to the stored version). After 30 failed rounds (the store refuses or
  // the session cannot be loaded here) it is given up, so that the copy can go.
  for (const auto& s : unsaved) {
    // A save subtracts what it stored and KeepUsage moves the usage: success needs no more. A
    // copy a request holds now is that request's to save.
    bool done = false;
    if (s->stale()) {
      done = KeepUsageOf(s);
    } else {
      const Status saved = s->SaveIfIdle(store_.get());
      if (saved.code() == StatusCode::kFailedPrecondition) continue;  // busy
      done = saved.ok();
    }
    if (done) {
      usage_failures_.erase(s->id());
    } else if (++usage_failures_[s->id()] >= 30) {
      spdlog::warn("session {}: planning time not stored, given up", s->id());
      s->DropUnsavedUsage();
      usage_failures_.erase(s->id());
    }
  }
  for (auto it = usage_failures_.begin(); it != usage_failures_.end();) {
    const bool listed = std::any_of(unsaved.begin(), unsaved.end(),
                                    [&](const auto& s) { return s->id() == it->first; });
    it = listed ? std::next(it) : usage_failures_.erase(it);
  }
  unsaved.clear();
  (void)store_->Ping();
  if (auto expired = store_->DeleteExpired(100); expired.ok()) {
    for (const std::string& id : *expired) {
      Drop(id);
      metrics_->CountExpired();
      spdlog::info("session {} expired", id);
    }
  }
  std::unique_lock lock(mutex_);
  for (const std::string& id : idle) {
    auto it = sessions_.find(id);
    if (it == sessions_.end() || it->second->busy() || it->second->has_unsaved_usage()) continue;
    sessions_.erase(it);
    metrics_->CountEvicted();
  }
  metrics_->SetSessions(static_cast<int>(sessions_.size()));
}

void Registry::StartReaper() {
  reaper_ = std::thread([this] {
    std::unique_lock<std::mutex> lock(stop_mutex_);
    for (int tick = 0; !stopping_; ++tick) {
      stop_cv_.wait_for(lock, std::chrono::milliseconds(250));
      if (stopping_) break;
      lock.unlock();
      if (shared_) {
        Maintain(tick % 4 == 0);
      } else {
        Reap();
      }
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
