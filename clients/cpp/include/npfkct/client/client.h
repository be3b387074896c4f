// A small C++ client of npfkct-server: every call returns the response body or a Status carrying
// the server's error (canonical code, message, and its field violations as Status payload).
#pragma once

#include <cstddef>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "npfkct/common/status.h"

namespace npfkct::client {

using nlohmann::json;

/// Client of one server. Not thread-safe; use one per thread. A reply larger than
/// `max_reply_bytes`, nested deeper than 64 levels or not JSON, and a call that takes longer than
/// `timeout_seconds` in all (a server that sends slowly included), end in an error Status.
class Client {
 public:
  /// `url` like "http://127.0.0.1:8080"; `api_key` empty for no authentication.
  explicit Client(const std::string& url, const std::string& api_key = "",
                  double timeout_seconds = 120.0, size_t max_reply_bytes = size_t{64} << 20);
  ~Client();

  StatusOr<json> Health();
  /// POST /v1/sessions with a full request body (see schemas/create_session_request.schema.json).
  StatusOr<json> CreateSession(const json& request);
  StatusOr<json> GetSession(const std::string& id);
  StatusOr<json> ListSessions();
  Status DeleteSession(const std::string& id);
  /// POST :plan with {"budget": {"timeMs": time_ms, "simulations": simulations, "cpuMs":
  /// cpu_ms}} (0: omitted).
  StatusOr<json> Plan(const std::string& id, double time_ms, int64_t simulations = 0,
                      double cpu_ms = 0.0);
  /// POST :observe; `body` must carry the actionId.
  StatusOr<json> Observe(const std::string& id, const json& body);
  StatusOr<json> Belief(const std::string& id);

 private:
  StatusOr<json> Call(const std::string& method, const std::string& path, const json* body);
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace npfkct::client
