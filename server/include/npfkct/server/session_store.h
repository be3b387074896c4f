// Where sessions are kept between requests and across restarts. The interface fits a shared
// database with optimistic concurrency (every save names the version it replaces); the directory
// backend is the embedded default, the memory backend keeps nothing, and the PostgreSQL backend
// (postgres_store.h) is shared by the replicas of a fleet.
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
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "npfkct/api/limits.h"
#include "npfkct/api/types.h"
#include "npfkct/common/status.h"

namespace npfkct::server {

/// Durable session records.
class SessionStore {
 public:
  /// A record as stored, with its version.
  struct Loaded {
    api::SessionRecord record;
    int64_t version = 0;
  };
  /// What Refresh found: the stored version, and the record when it is not the caller's.
  struct Refreshed {
    int64_t version = 0;
    std::optional<Loaded> loaded;
  };

  virtual ~SessionStore() = default;
  /// Stores `record` durably before returning. `expected_version` is the version the caller last
  /// loaded or saved (0 for a new session); the new version is returned. ABORTED when the stored
  /// version is another (someone else saved the session meanwhile) or the session was deleted;
  /// ALREADY_EXISTS when a new session's id is taken; UNAVAILABLE when the store cannot be
  /// reached (the save may or may not have happened).
  virtual StatusOr<int64_t> Save(const api::SessionRecord& record, int64_t expected_version) = 0;
  /// Removes a session; OK when it was not stored (`existed`, when given, tells which).
  virtual Status Delete(const std::string& id, bool* existed = nullptr) = 0;
  /// The ids of stored sessions in id order, after `after`, at most `limit` of them.
  virtual StatusOr<std::vector<std::string>> List(size_t limit, const std::string& after = "") = 0;
  /// A stored session; NOT_FOUND when absent, DATA_LOSS when unreadable.
  virtual StatusOr<Loaded> Load(const std::string& id) = 0;

  /// One session of ListViews: its API view when the store keeps one (SummaryOf), else none
  /// (the caller loads the record).
  struct Listed {
    std::string id;
    std::optional<api::SessionView> view;
  };
  /// As List, with each session's view where the store keeps summaries beside the records (the
  /// PostgreSQL store), so that a page of sessions reads no records; this default gives ids.
  virtual StatusOr<std::vector<Listed>> ListViews(size_t limit, const std::string& after = "");

  // ---- shared stores (several replicas write them) ----

  /// Whether other processes write this store too: a held session may be stale, and the store
  /// keeps the sessions' time to live.
  virtual bool shared() const { return false; }
  /// Marks a session used now (its time to live counts from here) and returns its stored
  /// version, with the record when that version is not `held_version`. NOT_FOUND when absent
  /// or expired. Shared stores only.
  virtual StatusOr<Refreshed> Refresh(const std::string& id, int64_t held_version);
  /// Keeps sessions that requests are working on from expiring (a plan may outlast the TTL);
  /// returns those of `ids` still stored (the others were deleted or expired meanwhile).
  virtual StatusOr<std::vector<std::string>> KeepAlive(const std::vector<std::string>& ids);
  /// Deletes up to `limit` sessions whose time to live has passed; returns their ids.
  virtual StatusOr<std::vector<std::string>> DeleteExpired(size_t limit);
  /// Whether the store answers (UNAVAILABLE with the reason when not). Bounded in time.
  virtual Status Ping() { return OkStatus(); }
  /// "memory", "directory" or "postgresql".
  virtual std::string backend() const = 0;
};

/// The bytes of a snapshot, one format for every store: a header line "npfkct-snapshot 2
/// <version> <payload length> <CRC-32 of the payload, 8 hex digits>" then the record
/// (api::EncodeRecord). With a `photos_digest`, the target's photos are kept apart (PhotosBlob)
/// and the record names them by it.
std::string EncodeSnapshot(const api::SessionRecord& record, int64_t version,
                           std::string_view photos_digest = {});
/// Reads snapshot bytes that should hold session `id`: DATA_LOSS when they are not a snapshot,
/// are truncated or corrupted (checksum), break a limit, or hold another session. A record whose
/// photos are kept apart comes without them, and their digest goes to `photos_digest`.
StatusOr<SessionStore::Loaded> DecodeSnapshot(std::string_view bytes, const std::string& id,
                                              const api::Limits& limits,
                                              std::string* photos_digest = nullptr);

/// A target's photos as a store keeps them apart from the snapshots: they never change after
/// creation, and a session is saved at every step (eight large photos made every 150-byte plan
/// or observation rewrite and fsync 31 MB). `digest` ("<CRC-32>-<length>") names them.
struct PhotosBlob {
  std::string bytes;
  std::string digest;
};
/// The blob of `photos` (api::EncodePhotos) with its digest.
PhotosBlob EncodePhotosBlob(const std::vector<std::string>& photos);
/// The photos of a blob that a snapshot names by `digest`: DATA_LOSS when the bytes are not
/// those (another digest: truncated, corrupted or another session's) or break a limit.
StatusOr<std::vector<std::string>> DecodePhotosBlob(std::string_view bytes, std::string_view digest,
                                                    const api::Limits& limits);
/// Ids whose photos a store remembers having stored (and their digests) before it forgets them
/// all, so that a long-running store's memory stays bounded (each then stores its photos again
/// once).
inline constexpr size_t kMaxPhotoDigestsKept = 100'000;

/// The digest of the photos a store wrote or read, per session id: a save that finds one names
/// the photos instead of writing them again. Bounded by kMaxPhotoDigestsKept. Thread-safe.
class PhotoDigests {
 public:
  /// The digest remembered for `id`, or "" (the next save writes the photos).
  std::string Find(const std::string& id) const;
  /// Remembers `digest` for `id`; an empty one forgets it.
  void Remember(const std::string& id, const std::string& digest);

 private:
  mutable std::mutex mutex_;
  std::map<std::string, std::string> digests_;
};

/// What a store that lists from summaries keeps beside `record`: its API view
/// (api::EncodeSessionSummary of Session::ViewOf), a few hundred bytes.
std::string SummaryOf(const api::SessionRecord& record);

/// A store that keeps nothing (sessions live in memory only).
std::unique_ptr<SessionStore> MakeMemoryStore();

/// Snapshots in a directory, one file "<id>.snap" per session (EncodeSnapshot), and "<id>.photos"
/// (PhotosBlob) for a session with target photos, written once. Writes go
/// to a new temporary file (O_CREAT | O_EXCL | O_NOFOLLOW), fsync, rename, fsync of the
/// directory. Reads open with O_NOFOLLOW | O_NONBLOCK, skip anything that is not a regular file,
/// cap the size before reading, and check the checksum and the record's limits.
class DirectoryStore : public SessionStore {
 public:
  /// Opens (creating) `dir` and holds its lock (`dir`/.lock, flock) until destroyed: a directory
  /// another process holds is a FAILED_PRECONDITION naming it. Leftover temporary files of an
  /// interrupted save are removed.
  static StatusOr<std::unique_ptr<DirectoryStore>> Open(const std::string& dir,
                                                        const api::Limits& limits,
                                                        size_t max_snapshot_bytes = 256 << 20);
  StatusOr<int64_t> Save(const api::SessionRecord& record, int64_t expected_version) override;
  Status Delete(const std::string& id, bool* existed = nullptr) override;
  StatusOr<std::vector<std::string>> List(size_t limit, const std::string& after = "") override;
  StatusOr<Loaded> Load(const std::string& id) override;
  std::string backend() const override { return "directory"; }
  ~DirectoryStore() override;

 private:
  DirectoryStore(std::string dir, int lock_fd, const api::Limits& limits, size_t max_bytes)
      : dir_(std::move(dir)), lock_fd_(lock_fd), limits_(limits), max_bytes_(max_bytes) {}
  std::string PathOf(const std::string& id) const { return dir_ + "/" + id + ".snap"; }
  std::string PhotosPathOf(const std::string& id) const { return dir_ + "/" + id + ".photos"; }

  std::string dir_;
  int lock_fd_;  // holds the directory's flock
  api::Limits limits_;
  size_t max_bytes_;
  std::mutex mutex_;
  std::map<std::string, int64_t> versions_;  // last version saved or loaded, per id
  PhotoDigests photos_kept_;                 // of the photos files written or read
};

}  // namespace npfkct::server
