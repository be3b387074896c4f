#include "npfkct/client/client.h"

#include <httplib.h>

namespace npfkct::client {
namespace {

StatusCode CodeOf(const std::string& name) {
  for (int c = 0; c <= 16; ++c) {
    if (StatusCodeName(static_cast<StatusCode>(c)) == name) return static_cast<StatusCode>(c);
  }
  return StatusCode::kUnknown;
}

}  // namespace

struct Client::Impl {
  Impl(const std::string& url, const std::string& key, double timeout) : http(url) {
    const auto sec = static_cast<time_t>(timeout);
    http.set_read_timeout(sec, static_cast<time_t>((timeout - sec) * 1e6));
    http.set_tcp_nodelay(true);
    if (!key.empty()) headers = {{"Authorization", "Bearer " + key}};
  }
  httplib::Client http;
  httplib::Headers headers;
};

Client::Client(const std::string& url, const std::string& api_key, double timeout_seconds)
    : impl_(std::make_unique<Impl>(url, api_key, timeout_seconds)) {}

Client::~Client() = default;

StatusOr<json> Client::Call(const std::string& method, const std::string& path, const json* body) {
  httplib::Result r = method == "POST"
                          ? impl_->http.Post(path.c_str(), impl_->headers,
                                             body ? body->dump() : "{}", "application/json")
                      : method == "GET" ? impl_->http.Get(path.c_str(), impl_->headers)
                                        : impl_->http.Delete(path.c_str(), impl_->headers);
  if (!r) {
    return Status(StatusCode::kUnavailable,
                  "cannot reach the server: " + httplib::to_string(r.error()));
  }
  json parsed = json::parse(r->body, nullptr, false);
  if (r->status >= 400) {
    if (parsed.is_object() && parsed.contains("error") && parsed["error"].is_object()) {
      const json& e = parsed["error"];
      Status s(CodeOf(e.value("status", "UNKNOWN")), e.value("message", r->body));
      if (e.contains("details") && e["details"].is_array()) {
        for (const json& d : e["details"]) {
          if (!d.is_object() || !d.contains("fieldViolations")) continue;
          for (const json& v : d["fieldViolations"]) {
            if (v.is_object())
              s.WithFieldViolation(v.value("field", ""), v.value("description", ""));
          }
        }
      }
      return s;
    }
    return Status(StatusCode::kUnknown, "HTTP " + std::to_string(r->status) + ": " + r->body);
  }
  if (parsed.is_discarded()) return Status(StatusCode::kDataLoss, "the reply is not JSON");
  return parsed;
}

StatusOr<json> Client::Health() { return Call("GET", "/healthz", nullptr); }
StatusOr<json> Client::CreateSession(const json& request) {
  return Call("POST", "/v1/sessions", &request);
}
StatusOr<json> Client::GetSession(const std::string& id) {
  return Call("GET", "/v1/sessions/" + id, nullptr);
}
StatusOr<json> Client::ListSessions() { return Call("GET", "/v1/sessions", nullptr); }
Status Client::DeleteSession(const std::string& id) {
  return Call("DELETE", "/v1/sessions/" + id, nullptr).status();
}
StatusOr<json> Client::Plan(const std::string& id, double time_ms, int64_t simulations,
                            double cpu_ms) {
  json budget = json::object();
  if (time_ms > 0) budget["timeMs"] = time_ms;
  if (cpu_ms > 0) budget["cpuMs"] = cpu_ms;
  if (simulations > 0) budget["simulations"] = simulations;
  const json body = {{"budget", budget}};
  return Call("POST", "/v1/sessions/" + id + ":plan", &body);
}
StatusOr<json> Client::Observe(const std::string& id, const json& body) {
  return Call("POST", "/v1/sessions/" + id + ":observe", &body);
}
StatusOr<json> Client::Belief(const std::string& id) {
  return Call("GET", "/v1/sessions/" + id + "/belief", nullptr);
}

}  // namespace npfkct::client
