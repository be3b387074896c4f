// npfkct-server: sessions over a gRPC-style HTTP/JSON API (see schemas/openapi.yaml and
// docs/api.md, which lists every limit and its error). Its settings are ServerOptions
// (server_options.h).
#pragma once

#include <memory>
#include <string>

#include "npfkct/common/status.h"
#include "npfkct/server/models.h"
#include "npfkct/server/server_options.h"

namespace npfkct::server {

/// The planning server. Start() restores, binds and serves on background threads; Stop() shuts
/// down (cancelling running plans).
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
  /// Sessions restored from the state directory at Start().
  int restored_sessions() const { return restored_; }

  /// Replaces the factory of NPF-kCT candidate samplers (default: FilterSamplerFactory over the
  /// model folder). Call before Start().
  void SetSamplerFactory(SamplerFactory factory) { samplers_ = std::move(factory); }

  struct Impl;

 private:
  ServerOptions options_;
  std::unique_ptr<Impl> impl_;
  SamplerFactory samplers_;
  int port_ = 0;
  int restored_ = 0;
};

}  // namespace npfkct::server
