// npfkct-server: sessions over a gRPC-style HTTP/JSON API (see schemas/openapi.yaml).
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <thread>
#include <vector>

#include "npfkct/server/metrics.h"
#include "npfkct/server/session.h"

namespace npfkct::server {

/// Settings of the server.
struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;
  /// Directory for session snapshots; empty: sessions live in memory only.
  std::string state_dir;
  /// Bearer token clients must send; empty: no authentication.
  std::string api_key;
  /// Sessions idle for longer than this are deleted (a session may ask for less).
  double session_ttl_seconds = 3600.0;
  int max_sessions = 256;
  /// Worker threads serving requests (sessions plan in parallel up to this many).
  int threads = 8;
  /// Largest request body.
  size_t max_body_bytes = 64u << 20;
  /// Planning budget when a :plan request gives none, and the most a request may ask for.
  double default_plan_ms = 1000.0;
  double max_plan_ms = 60000.0;
  int64_t max_plan_simulations = 100'000'000;
  /// Largest particle count a session may ask for.
  int max_particles = 100000;

  /// Checks every field; the message names the offending one.
  Status Validate() const;
};

/// The planning server. Start() binds and serves on background threads; Stop() shuts down.
class Server {
 public:
  explicit Server(ServerOptions options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Restores snapshots from the state directory, binds the port and starts serving.
  Status Start();
  /// Stops serving and joins the threads.
  void Stop();
  /// The port actually bound (useful with port 0).
  int port() const { return port_; }
  /// Blocks until Stop() is called (from another thread or a signal handler).
  void Wait();

  /// Sessions restored from the state directory at Start().
  int restored_sessions() const { return restored_; }

  /// Replaces the factory of NPF-kCT candidate samplers (default: FilterSamplerFactory()).
  void SetSamplerFactory(SamplerFactory factory) { samplers_ = std::move(factory); }

 private:
  struct Impl;
  ServerOptions options_;
  std::unique_ptr<Impl> impl_;
  SamplerFactory samplers_;
  int port_ = 0;
  int restored_ = 0;
};

}  // namespace npfkct::server
