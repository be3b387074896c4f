#include "npfkct/client/client.h"

#include <httplib.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

namespace npfkct::client {
namespace {

constexpr int kMaxDepth = 64;

StatusCode CodeOf(const std::string& name) {
  for (int c = 0; c <= 16; ++c) {
    if (StatusCodeName(static_cast<StatusCode>(c)) == name) return static_cast<StatusCode>(c);
  }
  return StatusCode::kUnknown;
}

// The string member `key` of `o`, or `fallback` where `o` is no object or the member no string.
std::string StringOf(const json& o, const char* key, const std::string& fallback) {
  if (!o.is_object()) return fallback;
  const auto it = o.find(key);
  return it != o.end() && it->is_string() ? it->get<std::string>() : fallback;
}

// Whether JSON text nests arrays and objects deeper than `limit` (strings skipped).
bool NestsDeeper(const std::string& text, int limit) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char ch = text[i];
    if (in_string) {
      if (ch == '\\') {
        ++i;
      } else if (ch == '"') {
        in_string = false;
      }
    } else if (ch == '"') {
      in_string = true;
    } else if (ch == '[' || ch == '{') {
      if (++depth > limit) return true;
    } else if (ch == ']' || ch == '}') {
      --depth;
    }
  }
  return false;
}

}  // namespace

struct Client::Impl {
  Impl(const std::string& url, const std::string& key, double timeout, size_t max_bytes)
      : http(url), max_reply_bytes(max_bytes) {
    const double t = timeout > 0 ? timeout : 0.001;
    deadline = std::chrono::duration_cast<std::chrono::milliseconds>(
        std::chrono::duration<double>(std::min(t, 1e6)));
    const auto sec = static_cast<time_t>(std::min(t, 1e6));
    http.set_read_timeout(sec, static_cast<time_t>((std::min(t, 1e6) - sec) * 1e6));
    http.set_write_timeout(sec, static_cast<time_t>((std::min(t, 1e6) - sec) * 1e6));
    http.set_tcp_nodelay(true);
    if (!key.empty()) headers = {{"Authorization", "Bearer " + key}};
  }
  httplib::Client http;
  httplib::Headers headers;
  size_t max_reply_bytes;
  std::chrono::milliseconds deadline;
};

Client::Client(const std::string& url, const std::string& api_key, double timeout_seconds,
               size_t max_reply_bytes)
    : impl_(std::make_unique<Impl>(url, api_key, timeout_seconds, max_reply_bytes)) {}

Client::~Client() = default;

StatusOr<json> Client::Call(const std::string& method, const std::string& path, const json* body) {
  httplib::Request req;
  req.method = method;
  req.path = path;
  req.headers = impl_->headers;
  if (method == "POST") {
    req.body = body ? body->dump() : "{}";
    req.set_header("Content-Type", "application/json");
  }
  // The reply is taken as it arrives, up to the cap (httplib would keep any length it is told).
  std::string reply;
  bool too_large = false;
  req.content_receiver = [&](const char* data, size_t n, uint64_t, uint64_t) {
    if (n > impl_->max_reply_bytes - reply.size()) {
      too_large = true;
      return false;
    }
    reply.append(data, n);
    return true;
  };
  // httplib's timeouts bound each read: a server sending a byte at a time would hold the call
  // forever, so the whole call has a deadline, past which its socket is shut.
  std::mutex mutex;
  std::condition_variable done_cv;
  bool done = false, timed_out = false;
  std::thread watchdog([&] {
    std::unique_lock<std::mutex> lock(mutex);
    if (!done_cv.wait_for(lock, impl_->deadline, [&] { return done; })) {
      timed_out = true;
      impl_->http.stop();
    }
  });
  httplib::Result r = impl_->http.send(req);
  {
    std::lock_guard<std::mutex> lock(mutex);
    done = true;
  }
  done_cv.notify_one();
  watchdog.join();
  const double seconds = std::chrono::duration<double>(impl_->deadline).count();
  if (timed_out) {
    return Status(StatusCode::kDeadlineExceeded, "the server did not answer " + method + " " +
                                                     path + " within " + std::to_string(seconds) +
                                                     " s");
  }
  if (too_large) {
    return Status(StatusCode::kResourceExhausted,
                  "the reply is larger than " + std::to_string(impl_->max_reply_bytes) + " bytes");
  }
  if (!r) {
    return Status(StatusCode::kUnavailable,
                  "cannot reach the server: " + httplib::to_string(r.error()));
  }
  if (NestsDeeper(reply, kMaxDepth)) {
    return Status(StatusCode::kDataLoss,
                  "the reply nests deeper than " + std::to_string(kMaxDepth) + " levels");
  }
  json parsed = json::parse(reply, nullptr, false);
  if (r->status >= 400) {
    if (parsed.is_object() && parsed.contains("error") && parsed["error"].is_object()) {
      const json& e = parsed["error"];
      Status s(CodeOf(StringOf(e, "status", "UNKNOWN")), StringOf(e, "message", reply));
      const auto details = e.find("details");
      if (details != e.end() && details->is_array()) {
        for (const json& d : *details) {
          if (!d.is_object() || !d.contains("fieldViolations")) continue;
          const json& violations = d["fieldViolations"];
          if (!violations.is_array()) continue;
          for (const json& v : violations) {
            if (v.is_object())
              s.WithFieldViolation(StringOf(v, "field", ""), StringOf(v, "description", ""));
          }
        }
      }
      return s;
    }
    return Status(StatusCode::kUnknown, "HTTP " + std::to_string(r->status) + ": " + reply);
  }
  if (parsed.is_discarded()) return Status(StatusCode::kDataLoss, "the reply is not JSON");
  if (!parsed.is_object()) return Status(StatusCode::kDataLoss, "the reply is not a JSON object");
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
