// The live sessions of a server: lookup, paging, creation within --max-sessions, deletion,
// restore from the session store at start-up, and the reaper of idle sessions.
#pragma once

#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <thread>
#include <vector>

#include "npfkct/server/metrics.h"
#include "npfkct/server/server.h"
#include "npfkct/server/session.h"
#include "npfkct/server/session_store.h"

namespace npfkct::server {

/// Sessions by id. Thread-safe; never holds its lock while a session works.
class Registry {
 public:
  Registry(const ServerOptions& options, Metrics* metrics);
  ~Registry();

  /// Opens the store and restores at most --max-sessions sessions from it; a snapshot that cannot
  /// be restored is skipped (and kept) with a warning. Returns how many were restored.
  StatusOr<int> Open(const SamplerFactory& samplers);

  std::shared_ptr<Session> Find(const std::string& id) const;
  /// Up to `size` sessions after `token` in id order; `next` gets the token of the next page.
  std::vector<std::shared_ptr<Session>> Page(const std::string& token, int size,
                                             std::string* next) const;
  int size() const;
  /// RESOURCE_EXHAUSTED: the server holds the maximum of sessions.
  Status FullError() const;
  /// Saves and adds a new session; RESOURCE_EXHAUSTED when the server is full.
  StatusOr<std::shared_ptr<Session>> Add(std::unique_ptr<Session> session);
  /// Removes a session and its stored copy, cancelling its running plan.
  Status Remove(const std::shared_ptr<Session>& session);
  /// Cancels every running plan (shutdown).
  void CancelAll();

  void StartReaper();
  void StopReaper();

  SessionStore* store() const { return store_.get(); }
  const SessionLimits& session_limits() const { return session_limits_; }

 private:
  void Reap();

  ServerOptions options_;
  Metrics* metrics_;
  SessionLimits session_limits_;
  std::unique_ptr<SessionStore> store_;
  mutable std::shared_mutex mutex_;
  std::map<std::string, std::shared_ptr<Session>> sessions_;
  std::thread reaper_;
  std::mutex stop_mutex_;
  std::condition_variable stop_cv_;
  bool stopping_ = false;
};

}  // namespace npfkct::server
