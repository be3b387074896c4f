#include "options.h"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <algorithm>
#include <cctype>
#include <string>
#include <thread>

#include "npfkct/api/api.h"
#include "registry.h"

namespace npfkct::server {
namespace {

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// The host name of an authority ("Name:8080", "[::1]:8080", "name."): lower case, without the
// port, the brackets of an IPv6 literal or a trailing dot.
std::string NameOfAuthority(std::string_view authority) {
  std::string_view name = authority;
  if (!name.empty() && name.front() == '[') {
    const size_t close = name.find(']');
    name = close == std::string_view::npos ? name.substr(1) : name.substr(1, close - 1);
  } else if (const size_t colon = name.rfind(':');
             colon != std::string_view::npos && name.find(':') == colon) {
    name = name.substr(0, colon);
  }
  if (!name.empty() && name.back() == '.') name.remove_suffix(1);
  return Lower(name);
}

}  // namespace

bool IsLoopbackHost(const std::string& host) {
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  return inet_pton(AF_INET6, host.c_str(), &v6) == 1 && IN6_IS_ADDR_LOOPBACK(&v6);
}

std::string BrowserRefusal(const ServerOptions& o, bool api_route, std::string_view host_header,
                           std::string_view origin, std::string_view fetch_site) {
  const std::string host = NameOfAuthority(host_header);
  if (o.api_key.empty() && IsLoopbackHost(o.host) && !host_header.empty() &&
      !(IsLoopbackHost(host) || host.ends_with(".localhost"))) {
    return "Host: a server without an API key on a loopback address answers only requests "
           "for localhost, 127.0.0.0/8 or [::1] (another name may be a web page's DNS "
           "rebinding)";
  }
  if (!api_route) return "";
  const std::string site = Lower(fetch_site);
  if (site == "cross-site" || site == "same-site") {
    return "Sec-Fetch-Site: requests from the web pages of other sites are refused";
  }
  if (origin.empty()) return "";
  const size_t scheme = origin.find("://");
  if (scheme == std::string_view::npos || NameOfAuthority(origin.substr(scheme + 3)) != host) {
    return "Origin: requests from the web pages of other origins are refused";
  }
  return "";
}

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
  if (!o.api_key.empty()) front.body_authorization = "Bearer " + o.api_key;
  return front;
}

Status ServerOptions::Validate() const {
  if (port < 0 || port > 65535) return InvalidFieldError("port", "must be in [0, 65535]");
  if (!default_model.empty() && !api::IsModelName(default_model)) {
    return InvalidFieldError("default-model", "must be a file name of --model-dir");
  }
  if (!(session_ttl_seconds > 0.0 && session_ttl_seconds <= api::kMaxTtlSeconds)) {
    return InvalidFieldError("session-ttl", "must be in (0, 1e9]");
  }
  if (max_sessions < 1) return InvalidFieldError("max-sessions", "must be >= 1");
  if (threads < 1 || threads > 1024) return InvalidFieldError("threads", "must be in [1, 1024]");
  // Each queued plan holds a request thread (Resolved): slots and queue bound the threads.
  if (plan_slots < 0 || plan_slots > 1024 || plan_queue < 0 || plan_queue > 2048) {
    return InvalidFieldError("plan-slots", "plan slots in [0, 1024], queue in [0, 2048]");
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
  // Header values are percent-decoded and trimmed before the server compares them (as httplib,
  // which served the API before, read them): a key with '%', a space or a control character
  // could never be sent as it is.
  if (std::any_of(api_key.begin(), api_key.end(), [](char ch) {
        const auto u = static_cast<unsigned char>(ch);
        return ch == '%' || u <= 0x20 || u == 0x7f;
      })) {
    return InvalidFieldError("api-key",
                             "must not hold '%', spaces or control characters (the server "
                             "decodes and trims the Authorization header)");
  }
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
    const StatusCode status = code == 401   ? StatusCode::kUnauthenticated
                              : code == 404 ? StatusCode::kNotFound
                              : code == 408 ? StatusCode::kDeadlineExceeded
                              : code == 416 ? StatusCode::kOutOfRange
                              : code == 413 ? StatusCode::kResourceExhausted
                              : code == 429 ? StatusCode::kResourceExhausted
                              : code == 431 ? StatusCode::kResourceExhausted
                              : code == 500 ? StatusCode::kInternal
                                            : StatusCode::kInvalidArgument;
    return api::RenderError(Status(status, message), code, code == 429 ? 1 : 0);
  };
}

}  // namespace npfkct::server
