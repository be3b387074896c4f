#include "npfkct/client/client.h"

#include <curl/curl.h>

#include <algorithm>
#include <cmath>

#include "npfkct/api/wire.h"

namespace npfkct::client {

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

// The body as it arrives, up to `cap` bytes.
struct Received {
  std::string body;
  size_t cap = 0;
  bool too_large = false;
};

size_t Append(char* data, size_t size, size_t count, void* user) {
  auto* reply = static_cast<Received*>(user);
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

StatusOr<Client::Reply> Client::Call(const std::string& method, const std::string& path,
                                     const std::string* body, long also_ok, const char* accept) {
  InitCurl();
  // What the handle points to is declared first, so that it outlives the handle.
  const std::string url = impl_->base + path;
  const std::string payload = method == "POST" ? (body ? *body : "{}") : "";
  const std::string accept_header = std::string("Accept: ") + accept;
  curl_slist* headers = nullptr;
  headers = curl_slist_append(headers, accept_header.c_str());
  if (method == "POST") headers = curl_slist_append(headers, "Content-Type: application/json");
  if (!impl_->authorization.empty()) {
    headers = curl_slist_append(headers, impl_->authorization.c_str());
  }
  std::unique_ptr<curl_slist, decltype(&curl_slist_free_all)> header_list(headers,
                                                                          curl_slist_free_all);
  Received reply;
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
  // Never followed (libcurl's default, said here): a redirect is an error of the client's own.
  curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 0L);
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
  if (status >= 300 && status < 400) {
    return Status(StatusCode::kUnknown, "HTTP " + std::to_string(status) + " for " + what +
                                            ": a redirect, which the client does not follow");
  }
  if ((status < 200 || status >= 300) && status != also_ok) {
    return api::ParseErrorReply(static_cast<int>(status), reply.body);
  }
  return Reply{status, std::move(reply.body)};
}

StatusOr<api::HealthView> Client::Health() {
  // 503 with the health of a server whose store is unavailable.
  auto reply = Call("GET", "/healthz", nullptr, /*also_ok=*/503);
  if (!reply.ok()) return reply.status();
  return api::ParseHealthReply(reply->body);
}

StatusOr<api::SessionView> Client::CreateSession(const api::CreateSessionRequest& request) {
  const std::string body = api::EncodeCreateSession(request);
  auto reply = Call("POST", "/v1/sessions", &body);
  if (!reply.ok()) return reply.status();
  return api::ParseSessionReply(reply->body);
}

StatusOr<api::SessionView> Client::GetSession(const std::string& id) {
  auto reply = Call("GET", "/v1/sessions/" + id, nullptr);
  if (!reply.ok()) return reply.status();
  return api::ParseSessionReply(reply->body);
}

Status Client::DeleteSession(const std::string& id) {
  return Call("DELETE", "/v1/sessions/" + id, nullptr).status();
}

StatusOr<api::PlanReply> Client::Plan(const std::string& id, const api::PlanRequest& request) {
  const std::string body = api::EncodePlan(request);
  auto reply = Call("POST", "/v1/sessions/" + id + ":plan", &body);
  if (!reply.ok()) return reply.status();
  return api::ParsePlanReply(reply->body);
}

StatusOr<api::ObserveReply> Client::Observe(const std::string& id,
                                            const api::ObserveRequest& request) {
  const StatusOr<std::string> body = api::EncodeObserve(request);
  if (!body.ok()) return body.status();
  auto reply = Call("POST", "/v1/sessions/" + id + ":observe", &*body);
  if (!reply.ok()) return reply.status();
  return api::ParseObserveReply(reply->body);
}

StatusOr<std::string> Client::BeliefPng(const std::string& id) {
  auto reply = Call("GET", "/v1/sessions/" + id + "/belief?format=png", nullptr, 0, "image/png");
  if (!reply.ok()) return reply.status();
  // The picture as the server sends it; only its header is read.
  auto info = api::ProbeImage(reply->body, "body");
  if (!info.ok() || info->format != api::ImageInfo::Format::kPng) {
    return FieldError(StatusCode::kDataLoss, "body", "the belief picture is not a PNG");
  }
  return std::move(reply->body);
}

}  // namespace npfkct::client
