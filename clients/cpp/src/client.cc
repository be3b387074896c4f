#include "npfkct/client/client.h"

#include <curl/curl.h>

#include <algorithm>
#include <cmath>

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

// libcurl, not httplib, on the client side: httplib 0.11 keeps any number of header lines of
// any length, matches the status line with a recursive std::regex (60,000 characters overflowed
// the stack), and bounds only each read, not a call. libcurl bounds the head (100 kB a header),
// the whole call (CURLOPT_TIMEOUT_MS, connecting and name resolution included) and, through the
// write callback below, the body.
struct Client::Impl {
  Impl(const std::string& url, const std::string& key, double timeout, size_t max_bytes)
      : base(url), max_reply_bytes(max_bytes) {
    while (!base.empty() && base.back() == '/') base.pop_back();
    // Not a number: the default (a cast of NaN is undefined).
    timeout_ms =
        static_cast<long>(std::clamp(std::isnan(timeout) ? 120.0 : timeout, 0.001, 1e6) * 1000.0);
    if (!key.empty()) authorization = "Authorization: Bearer " + key;
  }
  std::string base;
  std::string authorization;
  size_t max_reply_bytes;
  long timeout_ms;
};

namespace {

// Once per process, before any thread could use libcurl.
void InitCurl() {
  static const bool once = [] { return curl_global_init(CURL_GLOBAL_DEFAULT) == CURLE_OK; }();
  (void)once;
}

struct Reply {
  std::string body;
  size_t cap = 0;
  bool too_large = false;
};

size_t Append(char* data, size_t size, size_t count, void* user) {
  auto* reply = static_cast<Reply*>(user);
  const size_t n = size * count;
  if (n > reply->cap - reply->body.size()) {
    reply->too_large = true;
    return 0;  // libcurl stops with CURLE_WRITE_ERROR
  }
  reply->body.append(data, n);
  return n;
}

}  // namespace

Client::Client(const std::string& url, const std::string& api_key, double timeout_seconds,
               size_t max_reply_bytes)
    : impl_(std::make_unique<Impl>(url, api_key, timeout_seconds, max_reply_bytes)) {}

Client::~Client() = default;

StatusOr<json> Client::Call(const std::string& method, const std::string& path, const json* body) {
  InitCurl();
  // What the handle points to is declared first, so that it outlives the handle.
  const std::string url = impl_->base + path;
  const std::string payload = method == "POST" ? (body ? body->dump() : "{}") : "";
  curl_slist* headers = nullptr;
  headers = curl_slist_append(headers, "Accept: application/json");
  if (method == "POST") headers = curl_slist_append(headers, "Content-Type: application/json");
  if (!impl_->authorization.empty()) {
    headers = curl_slist_append(headers, impl_->authorization.c_str());
  }
  std::unique_ptr<curl_slist, decltype(&curl_slist_free_all)> header_list(headers,
                                                                          curl_slist_free_all);
  Reply reply;
  reply.cap = impl_->max_reply_bytes;
  char error[CURL_ERROR_SIZE] = {0};
  std::unique_ptr<CURL, decltype(&curl_easy_cleanup)> curl(curl_easy_init(), curl_easy_cleanup);
  if (!curl) return Status(StatusCode::kInternal, "libcurl could not start a call");
  CURL* c = curl.get();
  curl_easy_setopt(c, CURLOPT_URL, url.c_str());
  curl_easy_setopt(c, CURLOPT_HTTPHEADER, header_list.get());
  curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);
  curl_easy_setopt(c, CURLOPT_TIMEOUT_MS, impl_->timeout_ms);
  curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT_MS, impl_->timeout_ms);
  curl_easy_setopt(c, CURLOPT_TCP_NODELAY, 1L);
  curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http,https");
  curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, Append);
  curl_easy_setopt(c, CURLOPT_WRITEDATA, &reply);
  curl_easy_setopt(c, CURLOPT_ERRORBUFFER, error);
  // A Content-Length past the cap is refused before a byte of the body is read.
  curl_easy_setopt(c, CURLOPT_MAXFILESIZE_LARGE, static_cast<curl_off_t>(reply.cap));
  if (method == "POST") {
    curl_easy_setopt(c, CURLOPT_POST, 1L);
    curl_easy_setopt(c, CURLOPT_POSTFIELDS, payload.data());
    curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, static_cast<curl_off_t>(payload.size()));
  } else if (method != "GET") {
    curl_easy_setopt(c, CURLOPT_CUSTOMREQUEST, method.c_str());
  }
  const CURLcode code = curl_easy_perform(c);
  const std::string what = method + " " + path;
  if (code == CURLE_OPERATION_TIMEDOUT) {
    return Status(StatusCode::kDeadlineExceeded,
                  "the server did not answer " + what + " within " +
                      std::to_string(static_cast<double>(impl_->timeout_ms) / 1000.0) + " s");
  }
  if (reply.too_large || code == CURLE_FILESIZE_EXCEEDED) {
    return Status(StatusCode::kResourceExhausted,
                  "the reply is larger than " + std::to_string(reply.cap) + " bytes");
  }
  if (code != CURLE_OK) {
    return Status(StatusCode::kUnavailable, "cannot reach the server (" + what + "): " +
                                                (error[0] ? error : curl_easy_strerror(code)));
  }
  long status = 0;
  curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, &status);
  const std::string& body_text = reply.body;
  if (NestsDeeper(body_text, kMaxDepth)) {
    return Status(StatusCode::kDataLoss,
                  "the reply nests deeper than " + std::to_string(kMaxDepth) + " levels");
  }
  json parsed = json::parse(body_text, nullptr, false);
  if (status >= 400) {
    if (parsed.is_object() && parsed.contains("error") && parsed["error"].is_object()) {
      const json& e = parsed["error"];
      Status s(CodeOf(StringOf(e, "status", "UNKNOWN")),
               StringOf(e, "message", body_text.substr(0, 4096)));
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
    return Status(StatusCode::kUnknown,
                  "HTTP " + std::to_string(status) + ": " + body_text.substr(0, 4096));
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
