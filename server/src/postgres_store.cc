// The PostgreSQL session store (postgres_store.h) on libpq: a small pool of connections, every
// call sent with libpq's asynchronous API and waited for with poll() until its deadline, so a
// database that stops answering costs a request at most --store-timeout, never a hang.
#include "npfkct/server/postgres_store.h"

#include <spdlog/spdlog.h>

#include <cctype>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "npfkct/api/api.h"

#ifdef NPFKCT_WITH_POSTGRESQL
#include <libpq-fe.h>
#include <poll.h>
#endif

namespace npfkct::server {

Status PostgresStoreOptions::Validate() const {
  if (url.rfind("postgresql://", 0) != 0 && url.rfind("postgres://", 0) != 0) {
    return InvalidFieldError("store",
                             "expected a PostgreSQL URL, postgresql://[user@]host[:port]/"
                             "dbname (sessions in a directory: --state-dir)");
  }
  if (pool_size < 1 || pool_size > 64) return InvalidFieldError("store-pool", "must be in [1, 64]");
  if (!(timeout_seconds >= 0.1 && timeout_seconds <= 60.0)) {
    return InvalidFieldError("store-timeout", "must be in [0.1, 60] s");
  }
  if (!(wait_seconds >= 0.0 && wait_seconds <= 3600.0)) {
    return InvalidFieldError("store-wait", "must be in [0, 3600] s");
  }
  if (max_sessions < 1) return InvalidFieldError("max-stored-sessions", "must be >= 1");
  if (max_snapshot_bytes < 1024) return InvalidFieldError("store", "snapshot limit too small");
#ifdef NPFKCT_WITH_POSTGRESQL
  char* error = nullptr;
  PQconninfoOption* parsed = PQconninfoParse(url.c_str(), &error);
  if (parsed == nullptr) {
    std::string message = error ? error : "malformed";
    PQfreemem(error);
    while (!message.empty() && std::isspace(static_cast<unsigned char>(message.back()))) {
      message.pop_back();
    }
    return InvalidFieldError("store", "malformed PostgreSQL URL: " + message);
  }
  PQconninfoFree(parsed);
#endif
  return OkStatus();
}

#ifndef NPFKCT_WITH_POSTGRESQL

bool HavePostgresStore() { return false; }

StatusOr<std::unique_ptr<SessionStore>> OpenPostgresStore(const PostgresStoreOptions& options,
                                                          const api::Limits&) {
  if (Status s = options.Validate(); !s.ok()) return s;
  return FieldError(StatusCode::kFailedPrecondition, "store",
                    "this npfkct-server was built without the PostgreSQL store (libpq was not "
                    "found at build time: install libpq-dev and rebuild)");
}

std::string RedactedStoreUrl(const std::string& url) {
  const size_t at = url.find('@');
  const size_t scheme = url.find("://");
  if (at == std::string::npos || scheme == std::string::npos) return url;
  return url.substr(0, scheme + 3) + "***" + url.substr(at);
}

#else

bool HavePostgresStore() { return true; }

namespace {

using Clock = std::chrono::steady_clock;

struct ResultDeleter {
  void operator()(PGresult* r) const { PQclear(r); }
};
using Result = std::unique_ptr<PGresult, ResultDeleter>;
struct ConnDeleter {
  void operator()(PGconn* c) const { PQfinish(c); }
};
using Conn = std::unique_ptr<PGconn, ConnDeleter>;

constexpr char kTable[] = "npfkct_sessions";
// Version 2 added `summary`: each session's API view beside its record, which lists read
// instead of the records. A database of version 1 is migrated at start-up.
constexpr int kSchemaVersion = 3;

// When a row used now expires, given its time to live (an SQL expression): no sooner than 2 s,
// whatever the TTL. Replicas keep the sessions their requests work on alive every 250 ms; a
// shorter expiry let another replica delete a session between two of those ticks, under a
// running plan.
std::string ExpiresAt(const std::string& ttl) {
  return "now() + greatest(" + ttl + ", 2) * interval '1 second'";
}

// libpq's messages end in newlines and may hold several lines.
std::string Clean(const char* message) {
  std::string out;
  for (const char* p = message ? message : ""; *p; ++p) out += (*p == '\n') ? ' ' : *p;
  while (!out.empty() && out.back() == ' ') out.pop_back();
  return out.substr(0, 500);
}

Status Unavailable(const std::string& what) {
  return Status(StatusCode::kUnavailable, "session store: " + what);
}

// A failed statement: connection trouble, shutdowns, timeouts and resource shortages are
// UNAVAILABLE (worth retrying); serialization failures ABORTED; anything else INTERNAL.
Status Classify(const PGresult* r) {
  const char* state = PQresultErrorField(r, PG_DIAG_SQLSTATE);
  const std::string code = state ? state : "";
  const std::string message = Clean(PQresultErrorMessage(r));
  const std::string cls = code.substr(0, 2);
  if (cls == "08" || cls == "53" || cls == "57" || cls == "58" || code == "55P03") {
    return Unavailable(message);
  }
  if (code == "40001" || code == "40P01") {
    return Status(StatusCode::kAborted, "session store: " + message);
  }
  return Status(StatusCode::kInternal, "session store: " + message);
}

// Waits until the connection's socket is ready for `events` or the deadline passes.
bool Wait(PGconn* c, short events, Clock::time_point deadline) {
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) return false;
    pollfd p{PQsocket(c), events, 0};
    const int n = ::poll(&p, 1, static_cast<int>(std::min<int64_t>(left.count(), 1000)));
    if (n > 0) return true;
    if (n < 0 && errno != EINTR) return false;
  }
}

// A parameter: text, or bytes sent in binary format.
struct Param {
  std::string value;
  bool binary = false;
};

// Runs one statement (or, with no parameters and `simple`, a script) and returns its last
// result. Every result column comes in binary format: the SQL casts numbers to text, so a value
// is the text's bytes, or a bytea's raw bytes. `broken` is set when the connection is unusable.
StatusOr<Result> Exec(PGconn* c, const std::string& sql, const std::vector<Param>& params,
                      bool simple, Clock::time_point deadline, double timeout_s, bool* broken) {
  std::vector<const char*> values;
  std::vector<int> lengths, formats;
  for (const Param& p : params) {
    values.push_back(p.value.data());
    lengths.push_back(static_cast<int>(p.value.size()));
    formats.push_back(p.binary ? 1 : 0);
  }
  const int sent = simple
                       ? PQsendQuery(c, sql.c_str())
                       : PQsendQueryParams(c, sql.c_str(), static_cast<int>(params.size()), nullptr,
                                           values.data(), lengths.data(), formats.data(), 1);
  if (!sent) {
    *broken = true;
    return Unavailable(Clean(PQerrorMessage(c)));
  }
  char timeout[64];
  std::snprintf(timeout, sizeof timeout, "no answer within %g s", timeout_s);
  for (;;) {  // the request may not fit the socket's buffer at once
    const int flushed = PQflush(c);
    if (flushed == 0) break;
    if (flushed < 0 || !Wait(c, POLLOUT | POLLIN, deadline) || !PQconsumeInput(c)) {
      *broken = true;
      return Unavailable(flushed < 0 ? Clean(PQerrorMessage(c)) : timeout);
    }
  }
  Result last;
  Status error = OkStatus();
  for (;;) {
    while (PQisBusy(c)) {
      if (!Wait(c, POLLIN, deadline)) {
        *broken = true;
        return Unavailable(timeout);
      }
      if (!PQconsumeInput(c)) {
        *broken = true;
        return Unavailable(Clean(PQerrorMessage(c)));
      }
    }
    Result r(PQgetResult(c));
    if (!r) break;
    const ExecStatusType status = PQresultStatus(r.get());
    if (status == PGRES_FATAL_ERROR || status == PGRES_BAD_RESPONSE) {
      if (error.ok()) error = Classify(r.get());
    } else {
      last = std::move(r);
    }
  }
  if (PQstatus(c) != CONNECTION_OK) *broken = true;
  if (!error.ok()) return error;
  if (!last) return Status(StatusCode::kInternal, "session store: no result");
  return last;
}

std::string_view Value(const PGresult* r, int row, int column) {
  return std::string_view(PQgetvalue(r, row, column),
                          static_cast<size_t>(PQgetlength(r, row, column)));
}

// The result columns of a row's photos: the bytes when within the cap (the parameter `cap`) and
// `condition` holds, and their length.
std::string PhotosColumns(const std::string& cap, const std::string& condition = "true") {
  return "CASE WHEN " + condition + " AND octet_length(photos) <= " + cap +
         "::bigint THEN photos END, octet_length(photos)::text";
}

int64_t IntValue(const PGresult* r, int row, int column) {
  return std::strtoll(std::string(Value(r, row, column)).c_str(), nullptr, 10);
}

// A fixed number of connections, opened on demand. After a failed connection attempt, new
// connections fail at once for a second (the database is down; requests answer 503 quickly).
class Pool {
 public:
  Pool(std::string url, int size, double timeout_s)
      : url_(std::move(url)), size_(size), timeout_s_(timeout_s) {}

  StatusOr<Conn> Take(Clock::time_point deadline) {
    std::unique_lock<std::mutex> lock(mutex_);
    while (idle_.empty() && open_ >= size_) {
      if (cv_.wait_until(lock, deadline) == std::cv_status::timeout && idle_.empty() &&
          open_ >= size_) {
        return Unavailable("all " + std::to_string(size_) + " connections are busy");
      }
    }
    if (!idle_.empty()) {
      Conn c = std::move(idle_.back());
      idle_.pop_back();
      return c;
    }
    if (Clock::now() < down_until_) return Unavailable(last_error_);
    ++open_;
    lock.unlock();
    auto c = Connect(deadline);
    lock.lock();
    if (!c.ok()) {
      --open_;
      last_error_ = std::string(c.status().message()).substr(std::string("session store: ").size());
      down_until_ = Clock::now() + std::chrono::seconds(1);
      cv_.notify_one();
    }
    return c;
  }

  void Give(Conn c, bool broken) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (broken) {
      c.reset();
      --open_;
      // The others were opened to the same server: after a restart they are dead too.
      open_ -= static_cast<int>(idle_.size());
      idle_.clear();
    } else {
      idle_.push_back(std::move(c));
    }
    cv_.notify_all();
  }

 private:
  StatusOr<Conn> Connect(Clock::time_point deadline) const {
    const double left = std::chrono::duration<double>(deadline - Clock::now()).count();
    const std::string connect_timeout = std::to_string(std::max(2, static_cast<int>(left + 0.999)));
    const std::string ms = std::to_string(static_cast<int64_t>(timeout_s_ * 1000));
    // Server-side bounds too: no statement or lock wait outlives a call, no transaction idles.
    const std::string options = "-c statement_timeout=" + ms + " -c lock_timeout=" + ms +
                                " -c idle_in_transaction_session_timeout=" + ms + "0";
    // Our settings first: the URL's own parameters (dbname, expanded last) override them.
    const std::pair<const char*, const char*> settings[] = {
        {"connect_timeout", connect_timeout.c_str()},
        {"keepalives", "1"},
        {"keepalives_idle", "5"},
        {"keepalives_interval", "2"},
        {"keepalives_count", "3"},
        {"tcp_user_timeout", ms.c_str()},
        {"application_name", "npfkct-server"},
        {"options", options.c_str()},
        {"dbname", url_.c_str()},
    };
    std::vector<const char*> keys, values;
    for (const auto& [key, value] : settings) {
      keys.push_back(key);
      values.push_back(value);
    }
    keys.push_back(nullptr);
    values.push_back(nullptr);
    Conn c(PQconnectdbParams(keys.data(), values.data(), 1));
    if (!c) return Unavailable("out of memory");
    if (PQstatus(c.get()) != CONNECTION_OK) {
      return Unavailable("cannot connect: " + Clean(PQerrorMessage(c.get())));
    }
    if (PQsetnonblocking(c.get(), 1) != 0) return Unavailable("cannot make the socket nonblocking");
    return c;
  }

  const std::string url_;
  const int size_;
  const double timeout_s_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Conn> idle_;
  int open_ = 0;  // idle or taken
  Clock::time_point down_until_{};
  std::string last_error_;
};

class PostgresStore : public SessionStore {
 public:
  PostgresStore(const PostgresStoreOptions& o, const api::Limits& limits)
      : options_(o), limits_(limits), pool_(o.url, o.pool_size, o.timeout_seconds) {}

  std::string backend() const override { return "postgresql"; }
  bool shared() const override { return true; }

  // Creates the table if missing (under an advisory lock: replicas start at once) and checks
  // the schema version.
  Status Prepare() {
    static const std::string kSchema =
        std::string(
            "BEGIN; SELECT pg_advisory_xact_lock(4244837122);"
            " CREATE TABLE IF NOT EXISTS npfkct_schema (version integer NOT NULL);"
            " INSERT INTO npfkct_schema (version) SELECT ") +
        std::to_string(kSchemaVersion) +
        " WHERE NOT EXISTS (SELECT 1 FROM npfkct_schema);"
        " CREATE TABLE IF NOT EXISTS " +
        kTable +
        " (id text PRIMARY KEY CHECK (id ~ '^[0-9a-f]{32}$'),"
        "  version bigint NOT NULL CHECK (version >= 1),"
        "  snapshot bytea NOT NULL,"
        "  ttl_seconds double precision NOT NULL CHECK (ttl_seconds > 0),"
        "  expires_at timestamptz NOT NULL,"
        "  created_at timestamptz NOT NULL DEFAULT now(),"
        "  updated_at timestamptz NOT NULL DEFAULT now(),"
        "  updated_by text NOT NULL DEFAULT '',"
        "  summary bytea NOT NULL DEFAULT ''::bytea,"
        "  photos bytea);"
        " CREATE INDEX IF NOT EXISTS npfkct_sessions_expires_at ON " +
        kTable +
        " (expires_at);"
        // Version 1 to 2: rows saved before have an empty summary and are listed from their
        // records until saved again (a server of version 1 still running keeps writing them).
        // 2 to 3: the target photos kept apart, written once; rows saved before hold them in
        // their snapshot until saved again (a server of version 2 still running keeps writing
        // them there, and reads a snapshot of version 3 as a session without photos).
        " DO $$ BEGIN IF (SELECT max(version) FROM npfkct_schema) < 3 THEN"
        " ALTER TABLE " +
        kTable +
        " ADD COLUMN IF NOT EXISTS summary bytea NOT NULL DEFAULT ''::bytea;"
        " ALTER TABLE " +
        kTable +
        " ADD COLUMN IF NOT EXISTS photos bytea;"
        " UPDATE npfkct_schema SET version = 3 WHERE version < 3; END IF; END $$;"
        " COMMIT; SELECT max(version)::text FROM npfkct_schema;";
    auto r = Query(kSchema, {}, false, /*simple=*/true);
    if (!r.ok()) return r.status();
    const int64_t version = PQntuples(r->get()) == 1 ? IntValue(r->get(), 0, 0) : 0;
    if (version != kSchemaVersion) {
      return FieldError(StatusCode::kFailedPrecondition, "store",
                        "the database's npfkct_schema version is " + std::to_string(version) +
                            "; this server knows version " + std::to_string(kSchemaVersion));
    }
    return OkStatus();
  }

  StatusOr<int64_t> Save(const api::SessionRecord& record, int64_t expected) override {
    if (!api::IsSessionId(record.id)) return InvalidArgumentError("store: bad session id");
    const int64_t version = expected + 1;
    // The photos are written with the row's first save (or the first after a save of a
    // server that kept them in the snapshot), then named by their digest.
    std::string digest;
    std::optional<Param> photos;
    if (!record.target.photos.empty()) {
      if (expected > 0) digest = photos_kept_.Find(record.id);
      if (digest.empty()) {
        PhotosBlob blob = EncodePhotosBlob(record.target.photos);
        if (blob.bytes.size() > options_.max_snapshot_bytes) {
          return ResourceExhaustedError("the session's target photos are " +
                                        std::to_string(blob.bytes.size()) +
                                        " bytes, more than the store's limit of " +
                                        std::to_string(options_.max_snapshot_bytes));
        }
        digest = std::move(blob.digest);
        photos = Param{std::move(blob.bytes), true};
      }
    }
    Param snapshot{EncodeSnapshot(record, version, digest), true};
    if (snapshot.value.size() > options_.max_snapshot_bytes) {
      return ResourceExhaustedError(
          "the session's snapshot is " + std::to_string(snapshot.value.size()) +
          " bytes, more than the store's limit of " + std::to_string(options_.max_snapshot_bytes));
    }
    auto saved = SaveRow(record, expected, version, std::move(snapshot), std::move(photos));
    if (saved.ok() && !digest.empty()) photos_kept_.Remember(record.id, digest);
    return saved;
  }

  // The INSERT of a new session or the UPDATE of a stored version; `photos`, when given, is
  // written to the row too.
  StatusOr<int64_t> SaveRow(const api::SessionRecord& record, int64_t expected, int64_t version,
                            Param snapshot, std::optional<Param> photos) {
    char ttl[64];
    std::snprintf(ttl, sizeof ttl, "%.17g", record.ttl_seconds);
    const std::string& id = record.id;
    Param summary{SummaryOf(record), true};
    if (expected == 0) {
      // A new session: inserted only when the id is free and the table below its limit.
      std::vector<Param> params = {{id},
                                   std::move(snapshot),
                                   {ttl},
                                   {options_.replica},
                                   {std::to_string(options_.max_sessions)},
                                   std::move(summary)};
      if (photos) params.push_back(std::move(*photos));
      auto r =
          Query(std::string("INSERT INTO ") + kTable +
                    " (id, version, snapshot, ttl_seconds, expires_at, updated_by, summary" +
                    (params.size() > 6 ? ", photos" : "") +
                    ")"
                    " SELECT $1::text, 1, $2::bytea, $3::float8, " +
                    ExpiresAt("$3::float8") + ", $4::text, $6::bytea" +
                    (params.size() > 6 ? ", $7::bytea" : "") + " WHERE (SELECT count(*) FROM " +
                    kTable + ") < $5::bigint ON CONFLICT (id) DO NOTHING RETURNING 1",
                params, false);
      if (!r.ok()) return r.status();
      if (PQntuples(r->get()) == 1) return version;
      auto exists = Query(std::string("SELECT 1 FROM ") + kTable + " WHERE id = $1", {{id}}, true);
      if (!exists.ok()) return exists.status();
      if (PQntuples(exists->get()) > 0) {
        return Status(StatusCode::kAlreadyExists, "sessions/" + id + " exists already");
      }
      return ResourceExhaustedError("sessions: the session store holds its maximum of " +
                                    std::to_string(options_.max_sessions) +
                                    " sessions (--max-stored-sessions); delete one or retry later");
    }
    // The version check is the statement's WHERE: of two replicas saving over one version, the
    // second waits for the first's row lock, then finds another version and updates nothing.
    std::vector<Param> params = {{id},
                                 std::move(snapshot),
                                 {std::to_string(version)},
                                 {ttl},
                                 {options_.replica},
                                 {std::to_string(expected)},
                                 std::move(summary)};
    if (photos) params.push_back(std::move(*photos));
    auto r = Query(std::string("UPDATE ") + kTable +
                       " SET version = $3::bigint, snapshot = $2::bytea, ttl_seconds = $4::float8,"
                       " expires_at = " +
                       ExpiresAt("$4::float8") +
                       ","
                       " updated_at = now(), updated_by = $5::text, summary = $7::bytea" +
                       (params.size() > 7 ? ", photos = $8::bytea" : "") +
                       " WHERE id = $1::text AND version = $6::bigint RETURNING 1",
                   params, false);
    if (!r.ok()) return r.status();
    if (PQntuples(r->get()) == 1) return version;
    auto now =
        Query(std::string("SELECT version::text FROM ") + kTable + " WHERE id = $1", {{id}}, true);
    if (!now.ok()) return now.status();
    if (PQntuples(now->get()) == 0) {
      return Status(StatusCode::kAborted, "sessions/" + id + " was deleted meanwhile");
    }
    return Status(StatusCode::kAborted, "sessions/" + id +
                                            " was saved meanwhile by another request (version " +
                                            std::string(Value(now->get(), 0, 0)) + ", expected " +
                                            std::to_string(expected) + ")");
  }

  Status Delete(const std::string& id, bool* existed) override {
    if (existed) *existed = false;
    if (!api::IsSessionId(id)) return OkStatus();
    auto r =
        Query(std::string("DELETE FROM ") + kTable + " WHERE id = $1 RETURNING 1", {{id}}, true);
    if (!r.ok()) return r.status();
    if (existed) *existed = PQntuples(r->get()) > 0;
    photos_kept_.Remember(id, "");
    return OkStatus();
  }

  StatusOr<std::vector<std::string>> List(size_t limit, const std::string& after) override {
    auto r = Query(std::string("SELECT id FROM ") + kTable +
                       " WHERE id > $1 AND expires_at > now() ORDER BY id LIMIT $2::bigint",
                   {{after}, {std::to_string(limit)}}, true);
    if (!r.ok()) return r.status();
    std::vector<std::string> ids;
    for (int i = 0; i < PQntuples(r->get()); ++i) ids.emplace_back(Value(r->get(), i, 0));
    return ids;
  }

  StatusOr<std::vector<Listed>> ListViews(size_t limit, const std::string& after) override {
    auto r =
        Query(std::string("SELECT id, CASE WHEN octet_length(summary) <= $3::bigint"
                          " THEN summary END FROM ") +
                  kTable + " WHERE id > $1 AND expires_at > now() ORDER BY id LIMIT $2::bigint",
              {{after}, {std::to_string(limit)}, {std::to_string(api::kMaxSummaryBytes)}}, true);
    if (!r.ok()) return r.status();
    std::vector<Listed> out;
    for (int i = 0; i < PQntuples(r->get()); ++i) {
      Listed l{std::string(Value(r->get(), i, 0)), std::nullopt};
      if (!PQgetisnull(r->get(), i, 1) && PQgetlength(r->get(), i, 1) > 0) {
        auto view = api::DecodeSessionSummary(Value(r->get(), i, 1), limits_);
        if (view.ok() && view->id == l.id) l.view = std::move(view).value();  // else: the record
      }
      out.push_back(std::move(l));
    }
    return out;
  }

  StatusOr<Loaded> Load(const std::string& id) override {
    if (!api::IsSessionId(id)) return NotFoundError("not a session id");
    auto r =
        Query(std::string("SELECT version::text, CASE WHEN octet_length(snapshot) <= "
                          "$2::bigint THEN snapshot END, octet_length(snapshot)::text, ") +
                  PhotosColumns("$2") + " FROM " + kTable + " WHERE id = $1 AND expires_at > now()",
              {{id}, {std::to_string(options_.max_snapshot_bytes)}}, true);
    if (!r.ok()) return r.status();
    if (PQntuples(r->get()) == 0) return NotFoundError("sessions/" + id + " is not stored");
    return Decode(r->get(), id);
  }

  StatusOr<Refreshed> Refresh(const std::string& id, int64_t held_version) override {
    if (!api::IsSessionId(id)) return NotFoundError("not a session id");
    // One round trip: the time to live restarts, and the record comes only when it changed.
    auto r =
        Query(std::string("UPDATE ") + kTable + " SET expires_at = " + ExpiresAt("ttl_seconds") +
                  " WHERE id = $1 AND expires_at > now() RETURNING version::text,"
                  " CASE WHEN version <> $2::bigint AND octet_length(snapshot) <= $3::bigint"
                  " THEN snapshot END, octet_length(snapshot)::text, " +
                  // The photos, like the record, only when the version is another.
                  PhotosColumns("$3", "version <> $2::bigint"),
              {{id}, {std::to_string(held_version)}, {std::to_string(options_.max_snapshot_bytes)}},
              true);
    if (!r.ok()) return r.status();
    if (PQntuples(r->get()) == 0) return NotFoundError("sessions/" + id + " is not stored");
    Refreshed out;
    out.version = IntValue(r->get(), 0, 0);
    if (out.version == held_version) return out;
    auto loaded = Decode(r->get(), id);
    if (!loaded.ok()) return loaded.status();
    out.loaded = std::move(loaded).value();
    return out;
  }

  StatusOr<std::vector<std::string>> KeepAlive(const std::vector<std::string>& ids) override {
    if (ids.empty()) return std::vector<std::string>{};
    std::string array = "{";
    for (const std::string& id : ids) {
      if (!api::IsSessionId(id)) continue;
      array += (array.size() > 1 ? "," : "") + id;
    }
    array += "}";
    auto r =
        Query(std::string("UPDATE ") + kTable + " SET expires_at = " + ExpiresAt("ttl_seconds") +
                  " WHERE id = ANY($1::text[]) AND expires_at > now() RETURNING id",
              {{array}}, true);
    if (!r.ok()) return r.status();
    std::vector<std::string> kept;
    for (int i = 0; i < PQntuples(r->get()); ++i) kept.emplace_back(Value(r->get(), i, 0));
    return kept;
  }

  StatusOr<std::vector<std::string>> DeleteExpired(size_t limit) override {
    auto r = Query(std::string("DELETE FROM ") + kTable + " WHERE id IN (SELECT id FROM " + kTable +
                       " WHERE expires_at <= now() ORDER BY expires_at LIMIT $1::bigint"
                       " FOR UPDATE SKIP LOCKED) RETURNING id",
                   {{std::to_string(limit)}}, true);
    if (!r.ok()) return r.status();
    std::vector<std::string> ids;
    for (int i = 0; i < PQntuples(r->get()); ++i) ids.emplace_back(Value(r->get(), i, 0));
    return ids;
  }

  Status Ping() override {
    auto r = Query("SELECT 1", {}, false);
    return r.ok() ? OkStatus() : r.status();
  }

 private:
  // Columns: version, snapshot (NULL when larger than the limit), its length, then the photos
  // and their length (PhotosColumns). Remembers the digest of the photos the row holds.
  StatusOr<Loaded> Decode(const PGresult* r, const std::string& id) {
    const int64_t version = IntValue(r, 0, 0);
    if (PQgetisnull(r, 0, 1)) {
      return Status(StatusCode::kDataLoss,
                    "snapshot: " + std::string(Value(r, 0, 2)) + " bytes, more than the cap");
    }
    std::string digest;
    auto loaded = DecodeSnapshot(Value(r, 0, 1), id, limits_, &digest);
    if (!loaded.ok()) return loaded.status();
    if (loaded->version != version) {
      return Status(StatusCode::kDataLoss, "snapshot: its version is not the row's");
    }
    if (!digest.empty()) {
      // Columns 3 and 4 (PhotosColumns): the photos within the cap, and their length.
      if (PQgetisnull(r, 0, 3)) {
        return Status(StatusCode::kDataLoss,
                      PQgetisnull(r, 0, 4)
                          ? std::string("snapshot: the target photos it names are not stored")
                          : "snapshot: target photos of " + std::string(Value(r, 0, 4)) +
                                " bytes, more than the cap");
      }
      auto photos = DecodePhotosBlob(Value(r, 0, 3), digest, limits_);
      if (!photos.ok()) return photos.status();
      loaded->record.target.photos = std::move(photos).value();
    }
    photos_kept_.Remember(id, digest);  // "" (photos in the snapshot) forgets
    return loaded;
  }

  // One statement on a pooled connection within --store-timeout. Reads and idempotent writes
  // (`retry`) are tried once more on a new connection when the first one turned out dead (the
  // database restarted); a save is not, since it may have happened.
  StatusOr<Result> Query(const std::string& sql, const std::vector<Param>& params, bool retry,
                         bool simple = false) {
    const Clock::time_point deadline =
        Clock::now() + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(options_.timeout_seconds));
    StatusOr<Result> result = Unavailable("not run");
    for (int attempt = 0; attempt < (retry ? 2 : 1); ++attempt) {
      if (attempt > 0 && Clock::now() >= deadline) break;
      auto conn = pool_.Take(deadline);
      if (!conn.ok()) return conn.status();
      bool broken = false;
      result = Exec(conn->get(), sql, params, simple, deadline, options_.timeout_seconds, &broken);
      pool_.Give(std::move(conn).value(), broken || (simple && !result.ok()));
      if (result.ok() || !broken) break;
    }
    return result;
  }

  const PostgresStoreOptions options_;
  const api::Limits limits_;
  Pool pool_;
  PhotoDigests photos_kept_;  // of the photos this replica wrote to or read from a row
};

}  // namespace

std::string RedactedStoreUrl(const std::string& url) {
  char* error = nullptr;
  PQconninfoOption* options = PQconninfoParse(url.c_str(), &error);
  if (options == nullptr) {
    PQfreemem(error);
    return "postgresql://(malformed)";
  }
  std::string user, host, port, dbname;
  for (PQconninfoOption* o = options; o->keyword; ++o) {
    const std::string k = o->keyword, v = o->val ? o->val : "";
    if (k == "user") user = v;
    if (k == "host") host = v;
    if (k == "port") port = v;
    if (k == "dbname") dbname = v;
  }
  PQconninfoFree(options);
  return "postgresql://" + (user.empty() ? "" : user + "@") + host +
         (port.empty() ? "" : ":" + port) + "/" + dbname;
}

StatusOr<std::unique_ptr<SessionStore>> OpenPostgresStore(const PostgresStoreOptions& options,
                                                          const api::Limits& limits) {
  if (Status s = options.Validate(); !s.ok()) return s;
  auto store = std::make_unique<PostgresStore>(options, limits);
  const Clock::time_point give_up =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(
                         std::chrono::duration<double>(options.wait_seconds));
  for (;;) {
    Status s = store->Prepare();
    if (s.ok()) return std::unique_ptr<SessionStore>(std::move(store));
    const std::string message(s.message());
    // Waiting does not help a wrong password or database name.
    const bool permanent = s.code() != StatusCode::kUnavailable ||
                           message.find("authentication failed") != std::string::npos ||
                           message.find("does not exist") != std::string::npos ||
                           message.find("no password supplied") != std::string::npos;
    if (permanent || Clock::now() >= give_up) {
      return Status(s.code() == StatusCode::kInternal ? StatusCode::kFailedPrecondition : s.code(),
                    "store " + RedactedStoreUrl(options.url) + ": " + message);
    }
    spdlog::warn("store {}: {}; retrying", RedactedStoreUrl(options.url), message);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

#endif  // NPFKCT_WITH_POSTGRESQL

}  // namespace npfkct::server
