// The settings of npfkct-server (its flags; Server takes them), with their defaults and limits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "npfkct/api/limits.h"
#include "npfkct/common/status.h"
#include "npfkct/filter/filter.h"
#include "npfkct/object_search/planner_registry.h"

namespace npfkct::server {

/// Settings of the server (npfkct-server's flags).
struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;
  /// Directory for session snapshots; empty: sessions live in memory only.
  std::string state_dir;
  /// PostgreSQL URL of the session store a fleet of replicas shares (fleet mode); empty: none.
  std::string store_url;
  /// Fleet mode: connections to the store, the longest a store call may take, how long to wait
  /// for the store at start-up, and the most sessions the store may hold.
  int store_pool = 4;
  double store_timeout_seconds = 5.0;
  double store_wait_seconds = 10.0;
  int64_t max_stored_sessions = 10000;
  /// Fleet mode: sessions unused for this long are dropped from memory (they stay stored).
  double evict_idle_seconds = 300.0;
  /// Bearer token clients must send on /v1; empty: no authentication.
  std::string api_key;
  /// Serve without authentication on a non-loopback `host`. Without it, an empty `api_key` is
  /// only accepted on a loopback address (127.0.0.0/8, ::1, localhost): Validate() refuses to
  /// open the API to the network with nobody asked for a key.
  bool insecure = false;
  /// Sessions idle for longer than this are deleted (a session may ask for less).
  double session_ttl_seconds = 3600.0;
  /// Sessions held in memory at once (restored ones included). In fleet mode the least recently
  /// used idle session is dropped from memory to make room.
  int max_sessions = 256;
  /// Request threads (health and metrics have their own).
  int threads = 16;
  /// Plans running at once (0: one per core) and plans waiting for a slot (0: twice the slots).
  int plan_slots = 0;
  int plan_queue = 0;
  /// Largest request body, in any framing, and request bytes in flight across all connections.
  size_t max_body_bytes = 32u << 20;
  size_t max_inflight_bytes = 128u << 20;
  /// Open connections.
  int max_connections = 512;
  /// Deadlines: the request head from its first byte, the body after the head, keep-alive idle.
  double head_timeout_seconds = 10.0;
  double body_timeout_seconds = 60.0;
  double idle_timeout_seconds = 5.0;
  /// Folder of the neural filter models clients may name (planner.model).
  std::string model_dir;
  /// The model npfkct sessions plan with when they name none (planner.model absent); "" for
  /// none. When the folder lacks it, such sessions plan with uniform candidates (and say so).
  std::string default_model = filter::kDefaultModelName;
  /// Models kept loaded at once.
  int max_models = 4;
  /// Largest snapshot file read at start-up.
  size_t max_snapshot_bytes = 256u << 20;
  /// The API's limits (budgets and particles may be lowered; the rest are the documented ones).
  api::Limits limits;
  /// The planners sessions may use (the create request's planner.name, GET /v1/planners).
  object_search::PlannerRegistry planners = object_search::PlannerRegistry::BuiltIn();

  /// Checks every field; the violation names the offending flag.
  Status Validate() const;
};

}  // namespace npfkct::server
