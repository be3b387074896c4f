#include "npfkct/server/session_store.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>

#include "npfkct/api/api.h"

namespace npfkct::server {
namespace {

constexpr char kMagic[] = "npfkct-snapshot 2";

class MemoryStore : public SessionStore {
 public:
  StatusOr<int64_t> Save(const api::SessionRecord&, int64_t expected_version) override {
    return expected_version + 1;
  }
  Status Delete(const std::string&, bool* existed) override {
    if (existed) *existed = false;
    return OkStatus();
  }
  StatusOr<std::vector<std::string>> List(size_t, const std::string&) override {
    return std::vector<std::string>{};
  }
  StatusOr<Loaded> Load(const std::string& id) override {
    return NotFoundError("sessions/" + id + " is not stored");
  }
  std::string backend() const override { return "memory"; }
};

bool FsyncPath(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

bool WriteAll(int fd, const std::string& data) {
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

uint32_t Crc32(std::string_view data) {
  uLong crc = crc32(0L, Z_NULL, 0);
  size_t done = 0;
  while (done < data.size()) {
    const uInt n = static_cast<uInt>(std::min<size_t>(data.size() - done, 1u << 30));
    crc = crc32(crc, reinterpret_cast<const Bytef*>(data.data() + done), n);
    done += n;
  }
  return static_cast<uint32_t>(crc);
}

// "<32 hex>.snap", "<32 hex>.photos", and either with ".tmp.<hex>" after it.
bool IsSnapshotName(const std::string& name, std::string* id) {
  if (name.size() != 37 || name.compare(32, 5, ".snap") != 0) return false;
  *id = name.substr(0, 32);
  return api::IsSessionId(*id);
}
bool IsPhotosName(const std::string& name, std::string* id) {
  if (name.size() != 39 || name.compare(32, 7, ".photos") != 0) return false;
  *id = name.substr(0, 32);
  return api::IsSessionId(*id);
}
bool IsTempName(const std::string& name) {
  std::string id;
  return (name.size() > 42 && IsSnapshotName(name.substr(0, 37), &id) &&
          name.compare(37, 5, ".tmp.") == 0) ||
         (name.size() > 44 && IsPhotosName(name.substr(0, 39), &id) &&
          name.compare(39, 5, ".tmp.") == 0);
}

std::string RandomHex() {
  static thread_local std::mt19937_64 gen(std::random_device{}());
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(gen()));
  return buf;
}

// Writes `data` to `path` through a new temporary file (O_CREAT | O_EXCL | O_NOFOLLOW: never
// through a planted file or symbolic link), fsync, rename, fsync of the directory.
bool WriteDurably(const std::string& dir, const std::string& path, const std::string& data) {
  const std::string tmp = path + ".tmp." + RandomHex();
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  const bool written = WriteAll(fd, data) && ::fsync(fd) == 0;
  ::close(fd);
  if (!written || ::rename(tmp.c_str(), path.c_str()) != 0 || !FsyncPath(dir, true)) {
    ::unlink(tmp.c_str());
    return false;
  }
  return true;
}

// Reads a regular file of at most `max_bytes` (O_NOFOLLOW; O_NONBLOCK: a FIFO planted under the
// name must not hang). NOT_FOUND when absent, DATA_LOSS naming `what` otherwise.
StatusOr<std::string> ReadCapped(const std::string& path, size_t max_bytes,
                                 const std::string& what) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    return errno == ENOENT ? NotFoundError(what + " is not stored")
                           : Status(StatusCode::kDataLoss, what + ": cannot open");
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return Status(StatusCode::kDataLoss, what + ": not a regular file");
  }
  if (static_cast<uint64_t>(st.st_size) > max_bytes) {
    ::close(fd);
    return Status(StatusCode::kDataLoss,
                  what + ": " + std::to_string(st.st_size) + " bytes, more than the cap");
  }
  std::string data(static_cast<size_t>(st.st_size), '\0');
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::read(fd, data.data() + done, data.size() - done);
    if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    if (n <= 0) break;
    done += static_cast<size_t>(n);
  }
  ::close(fd);
  data.resize(done);
  return data;
}

std::string DigestOf(std::string_view bytes) {
  char digest[40];
  std::snprintf(digest, sizeof digest, "%08x-%zu", Crc32(bytes), bytes.size());
  return digest;
}

}  // namespace

StatusOr<SessionStore::Refreshed> SessionStore::Refresh(const std::string&, int64_t) {
  return Status(StatusCode::kUnimplemented, "not a shared store");
}
StatusOr<std::vector<std::string>> SessionStore::KeepAlive(const std::vector<std::string>& ids) {
  return ids;
}
StatusOr<std::vector<SessionStore::Listed>> SessionStore::ListViews(size_t limit,
                                                                    const std::string& after) {
  auto ids = List(limit, after);
  if (!ids.ok()) return ids.status();
  std::vector<Listed> out;
  for (std::string& id : *ids) out.push_back({std::move(id), std::nullopt});
  return out;
}
StatusOr<std::vector<std::string>> SessionStore::DeleteExpired(size_t) {
  return std::vector<std::string>{};
}

std::string PhotoDigests::Find(const std::string& id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = digests_.find(id);
  return it == digests_.end() ? std::string() : it->second;
}

void PhotoDigests::Remember(const std::string& id, const std::string& digest) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (digest.empty()) {
    digests_.erase(id);
    return;
  }
  if (digests_.size() >= kMaxPhotoDigestsKept) digests_.clear();
  digests_[id] = digest;
}

PhotosBlob EncodePhotosBlob(const std::vector<std::string>& photos) {
  PhotosBlob blob;
  blob.bytes = api::EncodePhotos(photos);
  blob.digest = DigestOf(blob.bytes);
  return blob;
}

StatusOr<std::vector<std::string>> DecodePhotosBlob(std::string_view bytes, std::string_view digest,
                                                    const api::Limits& limits) {
  if (DigestOf(bytes) != digest) {
    return Status(StatusCode::kDataLoss,
                  "snapshot: the target photos kept apart are not those the record names");
  }
  return api::DecodePhotos(bytes, limits);
}

std::string EncodeSnapshot(const api::SessionRecord& record, int64_t version,
                           std::string_view photos_digest) {
  const std::string payload = api::EncodeRecord(record, photos_digest);
  char header[128];
  std::snprintf(header, sizeof header, "%s %lld %zu %08x\n", kMagic,
                static_cast<long long>(version), payload.size(), Crc32(payload));
  return header + payload;
}

StatusOr<SessionStore::Loaded> DecodeSnapshot(std::string_view data, const std::string& id,
                                              const api::Limits& limits,
                                              std::string* photos_digest) {
  const size_t newline = data.find('\n');
  long long version = 0;
  size_t length = 0;
  unsigned crc = 0;
  char magic[32] = "";
  if (newline == std::string::npos || newline > 100 ||
      std::sscanf(std::string(data.substr(0, newline)).c_str(), "%31s 2 %lld %zu %8x", magic,
                  &version, &length, &crc) != 4 ||
      data.compare(0, sizeof kMagic - 1, kMagic) != 0 || version < 1) {
    return Status(StatusCode::kDataLoss, "snapshot: not an npfkct snapshot (format 2)");
  }
  const std::string_view payload = data.substr(newline + 1);
  if (payload.size() != length || Crc32(payload) != crc) {
    return Status(StatusCode::kDataLoss, "snapshot: truncated or corrupted (checksum)");
  }
  auto record = api::DecodeRecord(payload, limits, photos_digest);
  if (!record.ok()) return record.status();
  if (record->id != id) return Status(StatusCode::kDataLoss, "snapshot: its id is not its name");
  return SessionStore::Loaded{std::move(record).value(), version};
}

std::unique_ptr<SessionStore> MakeMemoryStore() { return std::make_unique<MemoryStore>(); }

StatusOr<std::unique_ptr<DirectoryStore>> DirectoryStore::Open(const std::string& dir,
                                                               const api::Limits& limits,
                                                               size_t max_snapshot_bytes) {
  if (dir.empty()) return InvalidArgumentError("state_dir: empty");
  if (::mkdir(dir.c_str(), 0700) != 0 && errno != EEXIST) {
    return InvalidArgumentError("state_dir: cannot create '" + dir + "': " + std::strerror(errno));
  }
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) {
    return InvalidArgumentError("state_dir: '" + dir + "' is not a directory");
  }
  // One process per directory: two servers on one directory would each trust their own versions
  // and overwrite the other's snapshots (acknowledged steps lost, deleted sessions written back),
  // and the second's start would remove the first's temporary files.
  const std::string lock_path = dir + "/.lock";
  const int lock_fd =
      ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0600);
  if (lock_fd < 0) {
    return InvalidArgumentError("state_dir: cannot open '" + lock_path +
                                "': " + std::strerror(errno));
  }
  if (::flock(lock_fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    ::close(lock_fd);
    if (err == EWOULDBLOCK) {
      return FailedPreconditionError("state_dir: '" + dir +
                                     "' is in use by another process (it holds " + lock_path +
                                     "); give each server a directory of its own");
    }
    return InvalidArgumentError("state_dir: cannot lock '" + lock_path +
                                "': " + std::strerror(err));
  }
  // Temporary files of a save that never finished (a crash between write and rename), or planted
  // there: unlink removes the entry itself, never what a symbolic link points to.
  // Photos files without their snapshot (a create that stopped between the two writes, or a
  // delete between the two removals) are removed as well.
  if (DIR* d = ::opendir(dir.c_str())) {
    while (dirent* e = ::readdir(d)) {
      const std::string name = e->d_name;
      std::string id;
      struct stat st {};
      if (IsTempName(name) ||
          (IsPhotosName(name, &id) &&
           ::fstatat(::dirfd(d), (id + ".snap").c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0 &&
           errno == ENOENT)) {
        ::unlinkat(::dirfd(d), name.c_str(), 0);
      }
    }
    ::closedir(d);
  }
  return std::unique_ptr<DirectoryStore>(
      new DirectoryStore(dir, lock_fd, limits, max_snapshot_bytes));
}

DirectoryStore::~DirectoryStore() { ::close(lock_fd_); }

StatusOr<int64_t> DirectoryStore::Save(const api::SessionRecord& record, int64_t expected_version) {
  if (!api::IsSessionId(record.id)) return InvalidArgumentError("store: bad session id");
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = versions_.find(record.id);
    const int64_t stored = it == versions_.end() ? 0 : it->second;
    if (stored != expected_version) {
      return Status(StatusCode::kAborted, "sessions/" + record.id +
                                              " was saved meanwhile (version " +
                                              std::to_string(stored) + ", expected " +
                                              std::to_string(expected_version) + ")");
    }
  }
  const int64_t version = expected_version + 1;
  // The photos are written once, before the first snapshot that names them.
  std::string digest;
  if (!record.target.photos.empty()) {
    digest = photos_kept_.Find(record.id);
    if (digest.empty()) {
      const PhotosBlob blob = EncodePhotosBlob(record.target.photos);
      if (!WriteDurably(dir_, PhotosPathOf(record.id), blob.bytes)) {
        return Status(StatusCode::kUnavailable, "cannot store the session's target photos");
      }
      digest = blob.digest;
    }
  }
  if (!WriteDurably(dir_, PathOf(record.id), EncodeSnapshot(record, version, digest))) {
    return Status(StatusCode::kUnavailable, "cannot store the session snapshot");
  }
  if (!digest.empty()) photos_kept_.Remember(record.id, digest);
  std::lock_guard<std::mutex> lock(mutex_);
  versions_[record.id] = version;
  return version;
}

Status DirectoryStore::Delete(const std::string& id, bool* existed) {
  if (existed) *existed = false;
  if (!api::IsSessionId(id)) return OkStatus();
  const int r = ::unlink(PathOf(id).c_str());
  if (r != 0 && errno != ENOENT) {
    return Status(StatusCode::kUnavailable, "cannot remove the session snapshot");
  }
  if (existed) *existed = r == 0;
  ::unlink(PhotosPathOf(id).c_str());  // an orphan left by a failure here goes at the next Open
  FsyncPath(dir_, true);
  photos_kept_.Remember(id, "");
  std::lock_guard<std::mutex> lock(mutex_);
  versions_.erase(id);
  return OkStatus();
}

StatusOr<std::vector<std::string>> DirectoryStore::List(size_t limit, const std::string& after) {
  std::vector<std::string> ids;
  DIR* d = ::opendir(dir_.c_str());
  if (d == nullptr) return Status(StatusCode::kUnavailable, "cannot read the state directory");
  while (dirent* e = ::readdir(d)) {
    std::string id;
    if (!IsSnapshotName(e->d_name, &id) || id <= after) continue;
    // Only regular files, never followed through a symbolic link.
    struct stat st {};
    if (::fstatat(::dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISREG(st.st_mode)) {
      continue;
    }
    ids.push_back(id);
  }
  ::closedir(d);
  std::sort(ids.begin(), ids.end());
  if (ids.size() > limit) ids.resize(limit);
  return ids;
}

StatusOr<SessionStore::Loaded> DirectoryStore::Load(const std::string& id) {
  if (!api::IsSessionId(id)) return NotFoundError("not a session id");
  auto data = ReadCapped(PathOf(id), max_bytes_, "snapshot");
  if (!data.ok()) {
    return data.status().code() == StatusCode::kNotFound
               ? NotFoundError("sessions/" + id + " is not stored")
               : data.status();
  }
  std::string digest;
  auto loaded = DecodeSnapshot(*data, id, limits_, &digest);
  if (!loaded.ok()) return loaded.status();
  if (!digest.empty()) {
    auto blob = ReadCapped(PhotosPathOf(id), max_bytes_, "snapshot: the target photos");
    if (!blob.ok()) return Status(StatusCode::kDataLoss, std::string(blob.status().message()));
    auto photos = DecodePhotosBlob(*blob, digest, limits_);
    if (!photos.ok()) return photos.status();
    loaded->record.target.photos = std::move(photos).value();
  }
  // Photos in the snapshot (digest ""): kept apart from the next save on.
  photos_kept_.Remember(id, digest);
  std::lock_guard<std::mutex> lock(mutex_);
  versions_[id] = loaded->version;
  return loaded;
}

}  // namespace npfkct::server
