// Where sessions are kept between requests and across restarts. The interface fits a shared
// database with optimistic concurrency (every save names the version it replaces); the directory
// backend is the embedded default, the memory backend keeps nothing.
//
//   auto store = DirectoryStore::Open("/var/lib/npfkct", limits).value();
//   int64_t v = store->Save(record, /*expected_version=*/0).value();   // a new session
//   v = store->Save(record, v).value();                                // after a plan
//   store->Delete(record.id);
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "npfkct/api/limits.h"
#include "npfkct/api/types.h"
#include "npfkct/solver/status.h"

namespace npfkct::server {

/// Durable session records.
class SessionStore {
 public:
  /// A record as stored, with its version.
  struct Loaded {
    api::SessionRecord record;
    int64_t version = 0;
  };

  virtual ~SessionStore() = default;
  /// Stores `record` durably before returning. `expected_version` is the version the caller last
  /// loaded or saved (0 for a new session); the new version is returned. ABORTED when the stored
  /// version is another (someone else saved the session meanwhile).
  virtual StatusOr<int64_t> Save(const api::SessionRecord& record, int64_t expected_version) = 0;
  /// Removes a session; OK when it was not stored.
  virtual Status Delete(const std::string& id) = 0;
  /// The ids of stored sessions, at most `limit` of them.
  virtual StatusOr<std::vector<std::string>> List(size_t limit) = 0;
  /// A stored session; NOT_FOUND when absent, DATA_LOSS when unreadable.
  virtual StatusOr<Loaded> Load(const std::string& id) = 0;
};

/// A store that keeps nothing (sessions live in memory only).
std::unique_ptr<SessionStore> MakeMemoryStore();

/// Snapshots in a directory, one file "<id>.snap" per session: a header line with the format,
/// the version, the payload length and its CRC-32, then the record (api::EncodeRecord). Writes go
/// to a new temporary file (O_CREAT | O_EXCL | O_NOFOLLOW), fsync, rename, fsync of the
/// directory. Reads open with O_NOFOLLOW | O_NONBLOCK, skip anything that is not a regular file,
/// cap the size before reading, and check the checksum and the record's limits.
class DirectoryStore : public SessionStore {
 public:
  /// Opens (creating) `dir`; leftover temporary files of an interrupted save are removed.
  static StatusOr<std::unique_ptr<DirectoryStore>> Open(const std::string& dir,
                                                        const api::Limits& limits,
                                                        size_t max_snapshot_bytes = 256 << 20);
  StatusOr<int64_t> Save(const api::SessionRecord& record, int64_t expected_version) override;
  Status Delete(const std::string& id) override;
  StatusOr<std::vector<std::string>> List(size_t limit) override;
  StatusOr<Loaded> Load(const std::string& id) override;

 private:
  DirectoryStore(std::string dir, const api::Limits& limits, size_t max_bytes)
      : dir_(std::move(dir)), limits_(limits), max_bytes_(max_bytes) {}
  std::string PathOf(const std::string& id) const { return dir_ + "/" + id + ".snap"; }

  std::string dir_;
  api::Limits limits_;
  size_t max_bytes_;
  std::mutex mutex_;
  std::map<std::string, int64_t> versions_;  // last version saved or loaded, per id
};

}  // namespace npfkct::server
