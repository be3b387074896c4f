// The sessions a server holds: lookup, paging, creation within --max-sessions, deletion,
// restore from the session store at start-up, and the reaper of idle sessions.
//
// With a local store (memory, --state-dir) the sessions held are all the sessions. With a shared
// store (--store postgresql://..., a fleet of replicas) the store is the truth and the held
// sessions are a cache: every request refreshes the session's time to live in the store and
// learns its stored version; a session not held, or held at an older version, is loaded from
// the store and its belief rebuilt; idle sessions are dropped from memory (they stay stored),
// and expiry is the store's.
#pragma once

#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <thread>
#include <vector>

#include "npfkct/api/types.h"
#include "npfkct/server/metrics.h"
#include "npfkct/server/postgres_store.h"
#include "npfkct/server/server.h"
#include "npfkct/server/session.h"
#include "npfkct/server/session_store.h"

namespace npfkct::server {

/// The PostgreSQL store's settings of a server (--store, --store-pool, ...).
PostgresStoreOptions StoreOptions(const ServerOptions& o);

/// Whether the store answers, as last seen.
struct StoreHealth {
  bool ok = true;
  std::string message;
};

/// Sessions by id. Thread-safe; never holds its lock while a session works or the store is
/// called.
class Registry {
 public:
  Registry(const ServerOptions& options, Metrics* metrics);
  ~Registry();

  /// Opens the store. A local store's sessions are restored (at most --max-sessions; a snapshot
  /// that cannot be restored is skipped, and kept, with a warning); a shared store's are loaded
  /// when a request names them. Returns how many were restored.
  StatusOr<int> Open(const SamplerFactory& samplers);

  /// The session a request names, ready to serve: the one held, or the stored one when it is
  /// not held, is held at an older version (another replica advanced it) or is stale (a save
  /// failed). NOT_FOUND when there is none (deleted, expired); UNAVAILABLE when the store is.
  StatusOr<std::shared_ptr<Session>> Acquire(const std::string& id);
  /// Stores the planning a stale copy of a session spent (its save lost to another replica's, or
  /// failed): the usage moves to the stored session, loaded, which is saved unless a request
  /// works on it (which saves it when it ends).
  /// False when the stored session could not be loaded or saved (the usage stays with `stale`).
  bool KeepUsageOf(const std::shared_ptr<Session>& stale);
  /// Up to `size` sessions after `token` in id order; `next` gets the token of the next page.
  StatusOr<std::vector<api::SessionView>> Page(const std::string& token, int size,
                                               std::string* next) const;
  /// Sessions held in memory.
  int size() const;
  /// OK when a new session can be held (in a fleet, by dropping an idle one from memory) and the
  /// heap is within its bound; RESOURCE_EXHAUSTED otherwise.
  Status CheckCapacity();
  /// Saves and adds a new session; RESOURCE_EXHAUSTED when the server (or store) is full.
  StatusOr<std::shared_ptr<Session>> Add(std::unique_ptr<Session> session);
  /// Deletes a session and its stored copy, cancelling its running plan; NOT_FOUND when absent.
  Status Remove(const std::string& id);
  /// Cancels every running plan (shutdown).
  void CancelAll();
  /// The store's health (always OK for a local store).
  StoreHealth store_health() const;

  void StartReaper();
  void StopReaper();

  SessionStore* store() const { return store_.get(); }
  const SessionLimits& session_limits() const { return session_limits_; }

  /// A new session id: 128 bits from the kernel's random source (getrandom), so ids made by
  /// any number of replicas do not collide.
  static std::string NewId();

 private:
  Status FullError() const;
  // Remove() but for giving the memory back.
  Status RemoveSession(const std::string& id);
  // The lock that serializes loads of session `id` (held by its loaders only).
  std::shared_ptr<std::mutex> LoadLock(const std::string& id);
  // Restores a stored session and holds it in place of `replaced` (unless another request
  // installed a newer copy meanwhile); RESOURCE_EXHAUSTED past the heap bound.
  StatusOr<std::shared_ptr<Session>> Install(SessionStore::Loaded loaded,
                                             const std::shared_ptr<Session>& replaced);
  // Drops sessions from memory (fleet): the least recently used idle ones until `room` more fit.
  bool MakeRoomLocked(int room);
  // Forgets a held session whose stored copy is gone (deleted or expired elsewhere).
  void Drop(const std::string& id);
  void Reap();
  void Maintain(bool full_round);

  ServerOptions options_;
  Metrics* metrics_;
  SessionLimits session_limits_;
  SamplerFactory samplers_;
  std::unique_ptr<SessionStore> store_;
  bool shared_ = false;
  mutable std::shared_mutex mutex_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
  std::mutex load_locks_mutex_;
  std::map<std::string, std::weak_ptr<std::mutex>> load_locks_;
  // Upkeep rounds that failed to store a held copy's unsaved planning (the reaper thread's).
  std::map<std::string, int> usage_failures_;
  std::thread reaper_;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
};

}  // namespace npfkct::server
