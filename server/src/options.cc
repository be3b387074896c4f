#include "options.h"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <algorithm>
#include <string>
#include <thread>

#include "npfkct/api/api.h"
#include "registry.h"

namespace npfkct::server {
namespace {

// Whether `host` only accepts connections from this machine: "localhost", an IPv4 address in
// 127.0.0.0/8 or the IPv6 loopback. Anything else (0.0.0.0, ::, a name, an interface address)
// may be reached from the network.
bool IsLoopbackHost(const std::string& host) {
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  return inet_pton(AF_INET6, host.c_str(), &v6) == 1 && IN6_IS_ADDR_LOOPBACK(&v6);
}

}  // namespace

ServerOptions Resolved(ServerOptions o) {
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  if (o.plan_slots == 0) o.plan_slots = cores;
  if (o.plan_queue == 0) o.plan_queue = 2 * o.plan_slots;
  // Plans waiting for a slot hold a request thread: keep threads for everything else too.
  o.threads = std::max(o.threads, o.plan_slots + o.plan_queue + 4);
  return o;
}

HttpFrontOptions FrontOptions(const ServerOptions& o) {
  HttpFrontOptions front;
  front.workers = o.threads;
  front.max_connections = o.max_connections;
  front.head_timeout_s = o.head_timeout_seconds;
  front.body_timeout_s = o.body_timeout_seconds;
  front.idle_timeout_s = o.idle_timeout_seconds;
  front.max_body_bytes = o.max_body_bytes;
  front.max_inflight_bytes = o.max_inflight_bytes;
  return front;
}

Status ServerOptions::Validate() const {
  if (port < 0 || port > 65535) return InvalidFieldError("port", "must be in [0, 65535]");
  if (!default_model.empty() && !api::IsModelName(default_model)) {
    return InvalidFieldError("default-model", "must be a file name of --model-dir");
  }
  if (!(session_ttl_seconds > 0.0)) return InvalidFieldError("session-ttl", "must be > 0");
  if (max_sessions < 1) return InvalidFieldError("max-sessions", "must be >= 1");
  if (threads < 1 || threads > 1024) return InvalidFieldError("threads", "must be in [1, 1024]");
  if (plan_slots < 0 || plan_slots > 1024 || plan_queue < 0 || plan_queue > 100000) {
    return InvalidFieldError("plan-slots", "plan slots in [0, 1024], queue in [0, 100000]");
  }
  if (max_body_bytes < 1024) return InvalidFieldError("max-body-mb", "must be >= 1 KiB");
  if (max_inflight_bytes < max_body_bytes) {
    return InvalidFieldError("max-inflight-mb", "must be >= the body limit");
  }
  if (max_connections < 4 || max_connections > 4096) {
    return InvalidFieldError("max-connections", "must be in [4, 4096]");
  }
  for (double t : {head_timeout_seconds, body_timeout_seconds, idle_timeout_seconds}) {
    if (!(t > 0.0 && t <= 3600.0)) return InvalidFieldError("timeouts", "must be in (0, 3600] s");
  }
  if (max_models < 1) return InvalidFieldError("max-models", "must be >= 1");
  if (api_key.empty() && !insecure && !IsLoopbackHost(host)) {
    return InvalidFieldError(
        "api-key", "listening on " + host +
                       " (not a loopback address) needs --api-key KEY (or NPFKCT_API_KEY); "
                       "--insecure serves without authentication");
  }
  if (!store_url.empty()) {
    if (!state_dir.empty()) {
      return InvalidFieldError("store", "--store and --state-dir exclude each other");
    }
    if (Status s = StoreOptions(*this).Validate(); !s.ok()) return s;
    if (!(evict_idle_seconds > 0.0)) return InvalidFieldError("evict-idle", "must be > 0");
  }
  if (Status s = limits.Validate(); !s.ok()) return s;
  return OkStatus();
}

HttpFront::ErrorRenderer FrontErrors() {
  return [](int code, const std::string& message) {
    const StatusCode status = code == 408   ? StatusCode::kDeadlineExceeded
                              : code == 416 ? StatusCode::kOutOfRange
                              : code == 413 ? StatusCode::kResourceExhausted
                              : code == 429 ? StatusCode::kResourceExhausted
                              : code == 431 ? StatusCode::kResourceExhausted
                                            : StatusCode::kInvalidArgument;
    return api::RenderError(Status(status, message), code, code == 429 ? 1 : 0);
  };
}

httplib::Server::HandlerWithResponse HttpErrorBodies() {
  return [](const httplib::Request&, httplib::Response& res) {
    using R = httplib::Server::HandlerResponse;
    if (!res.body.empty()) return R::Unhandled;
    const int code = res.status;
    const StatusCode status = code == 404   ? StatusCode::kNotFound
                              : code == 413 ? StatusCode::kResourceExhausted
                              : code == 416 ? StatusCode::kOutOfRange
                              : code >= 500 ? StatusCode::kInternal
                                            : StatusCode::kInvalidArgument;
    res.set_content(api::RenderError(Status(status, "HTTP " + std::to_string(code)), code),
                    "application/json");
    return R::Handled;
  };
}

}  // namespace npfkct::server
