// The C++ client of npfkct-server, typed: requests and replies are the API layer's types
// (npfkct/api/types.h), put on the wire and read back by its encoders and decoders
// (npfkct/api/client_codec.h). Every call returns the typed reply or a Status: the server's error
// (its canonical code, message and field violations), or the client's own when the server did
// not answer as the API describes.
//
//   npfkct::client::Client client("http://127.0.0.1:8080");
//   npfkct::api::CreateSessionRequest create;
//   create.world = npfkct::api::ParseWorldSpec(scenario_text).value();
//   auto session = client.CreateSession(create);
//   auto plan = client.Plan(session->id, {.time_ms = 500});
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "npfkct/api/client_codec.h"
#include "npfkct/api/types.h"
#include "npfkct/common/status.h"

namespace npfkct::client {

/// Client of one server. Not thread-safe; use one per thread. A call that takes longer than
/// `timeout_seconds` in all (connecting included, and a server that sends slowly) is
/// DEADLINE_EXCEEDED; a reply larger than `max_reply_bytes` RESOURCE_EXHAUSTED; a reply that is
/// not what the API describes (not JSON, nested deeper than 64 levels, not of the API's types;
/// compressed: nothing is inflated) DATA_LOSS naming the field; a redirect, which is never
/// followed, UNKNOWN.
class Client {
 public:
  /// `url` like "http://127.0.0.1:8080"; `api_key` empty for no authentication.
  explicit Client(const std::string& url, const std::string& api_key = "",
                  double timeout_seconds = 120.0, size_t max_reply_bytes = size_t{64} << 20);
  ~Client();

  /// GET /healthz: the server's health, also while it does not serve (HTTP 503: store_ok false).
  StatusOr<api::HealthView> Health();
  /// POST /v1/sessions.
  StatusOr<api::SessionView> CreateSession(const api::CreateSessionRequest& request);
  /// GET /v1/sessions/{id}.
  StatusOr<api::SessionView> GetSession(const std::string& id);
  /// DELETE /v1/sessions/{id}.
  Status DeleteSession(const std::string& id);
  /// POST /v1/sessions/{id}:plan.
  StatusOr<api::PlanReply> Plan(const std::string& id, const api::PlanRequest& request);
  /// POST /v1/sessions/{id}:observe; the request carries the plan's actionId.
  StatusOr<api::ObserveReply> Observe(const std::string& id, const api::ObserveRequest& request);
  /// GET /v1/sessions/{id}/belief?format=png: the belief picture's PNG bytes.
  StatusOr<std::string> BeliefPng(const std::string& id);

 private:
  /// A reply: its HTTP status and body.
  struct Reply {
    long status = 0;
    std::string body;
  };
  /// One call; `body` is POSTed (DELETE and GET send none), `accept` the media type asked for. A
  /// reply that is no success (2xx) is the error it carries, except the HTTP status `also_ok`.
  StatusOr<Reply> Call(const std::string& method, const std::string& path, const std::string* body,
                       long also_ok = 0, const char* accept = "application/json");
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace npfkct::client
