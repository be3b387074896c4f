// The session store of a fleet: every replica reads and writes one PostgreSQL table, so any
// replica can serve any session. Built when libpq is found (NPFKCT_WITH_POSTGRESQL).
//
//   PostgresStoreOptions o;
//   o.url = "postgresql://npfkct@db:5432/npfkct";
//   auto store = OpenPostgresStore(o, limits);      // creates the table when it is missing
//   if (!store.ok()) return store.status();        // INVALID_ARGUMENT, UNAVAILABLE, ...
//
// Table (created with CREATE TABLE IF NOT EXISTS under an advisory lock; schema version 1 in
// npfkct_schema):
//
//   npfkct_sessions(id text PRIMARY KEY, version bigint, snapshot bytea, ttl_seconds float8,
//                   expires_at timestamptz, created_at timestamptz, updated_at timestamptz,
//                   updated_by text)
//
// `snapshot` holds exactly the bytes of a directory snapshot file (EncodeSnapshot), with the
// row's version in its header. A save is one statement (its own transaction) that names the
// version it replaces: "UPDATE ... WHERE id = $1 AND version = $expected"; no row updated is a
// conflict (ABORTED). Time to live is kept on the database's clock: every use sets expires_at
// to now() + ttl_seconds, and any replica deletes rows past it.
//
// Every call is bounded in time (timeout_seconds, client-side, with statement_timeout on the
// server as well); a store that does not answer is UNAVAILABLE, never a hang.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "npfkct/api/limits.h"
#include "npfkct/common/status.h"
#include "npfkct/server/session_store.h"

namespace npfkct::server {

/// Settings of the PostgreSQL store (npfkct-server's --store flags).
struct PostgresStoreOptions {
  /// A libpq connection URI: postgresql://[user[:password]@]host[:port]/dbname[?param=value...].
  std::string url;
  /// Connections to the database, opened on demand (--store-pool).
  int pool_size = 4;
  /// Longest time one store call may take, connecting included (--store-timeout).
  double timeout_seconds = 5.0;
  /// At start-up, how long to keep trying to reach the database (--store-wait).
  double wait_seconds = 10.0;
  /// Largest snapshot written or read.
  size_t max_snapshot_bytes = 256u << 20;
  /// Most sessions (rows) the table may hold; a create beyond is RESOURCE_EXHAUSTED.
  int64_t max_sessions = 10000;
  /// Written to updated_by (which replica saved a row last), for operators.
  std::string replica;

  /// Checks the fields and the URL's syntax (libpq's parser); the violation names the flag.
  Status Validate() const;
};

/// Whether this build has the PostgreSQL store.
bool HavePostgresStore();

/// Connects (retrying for wait_seconds), creates the table if missing and checks its schema
/// version. INVALID_ARGUMENT for a malformed URL, UNAVAILABLE when the database cannot be
/// reached, FAILED_PRECONDITION when the table has another schema version or this build has no
/// PostgreSQL support.
StatusOr<std::unique_ptr<SessionStore>> OpenPostgresStore(const PostgresStoreOptions& options,
                                                          const api::Limits& limits);

/// The URL without its password (for logs).
std::string RedactedStoreUrl(const std::string& url);

}  // namespace npfkct::server
