#include "http_front.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstring>
#include <map>
#include <string_view>

namespace npfkct::server {
namespace {

using Clock = std::chrono::steady_clock;

Clock::duration Seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// The longest header line read (with its CRLF; httplib's CPPHTTPLIB_HEADER_MAX_LENGTH, which
// served the API before): a longer one is refused (431).
constexpr size_t kMaxHeaderLine = 8192;
// The longest request line read (httplib's CPPHTTPLIB_REQUEST_URI_MAX_LENGTH, 8,192 with the
// line's CRLF, less room for the method and version): a longer one is refused (414).
constexpr size_t kMaxRequestLine = 8000;

// A header field name: one or more tchar (RFC 9110 5.6.2).
bool IsToken(std::string_view s) {
  static constexpr std::string_view kSymbols = "!#$%&'*+-.^_`|~";
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || kSymbols.find(ch) != kSymbols.npos;
  });
}

// Whether `line` is a request line (RFC 9112 3): method SP request-target SP HTTP/d.d, the method
// a token and the target without spaces.
bool WellFormedRequestLine(std::string_view line) {
  const size_t sp1 = line.find(' ');
  if (sp1 == std::string_view::npos || !IsToken(line.substr(0, sp1))) return false;
  const size_t sp2 = line.find(' ', sp1 + 1);
  if (sp2 == std::string_view::npos || sp2 == sp1 + 1) return false;
  const std::string_view version = line.substr(sp2 + 1);
  return version.size() == 8 && version.substr(0, 5) == "HTTP/" &&
         std::isdigit(static_cast<unsigned char>(version[5])) && version[6] == '.' &&
         std::isdigit(static_cast<unsigned char>(version[7]));
}

// Whether the path of a request target (before any query) holds a percent-encoded '/' or ':'
// (%2F, %3A in any case) or a %uXXXX escape, which the path's decoding decodes too.
bool EncodesSeparator(std::string_view target) {
  const std::string_view path = target.substr(0, target.find('?'));
  for (size_t i = path.find('%'); i != std::string_view::npos && i + 1 < path.size();
       i = path.find('%', i + 1)) {
    const char hi = static_cast<char>(std::tolower(static_cast<unsigned char>(path[i + 1])));
    if (hi == 'u') return true;
    if (i + 2 >= path.size()) break;
    const char lo = static_cast<char>(std::tolower(static_cast<unsigned char>(path[i + 2])));
    if ((hi == '2' && lo == 'f') || (hi == '3' && lo == 'a')) return true;
  }
  return false;
}

// Whether a head (up to its final CRLF) holds a NUL, or a CR or LF that is not part of a CRLF:
// parsers that end lines at a bare LF (httplib did) would read such a head as other requests
// than this front does, e.g. behind a proxy.
bool HasStrayLineBreakOrNul(std::string_view head) {
  for (size_t i = 0; i < head.size(); ++i) {
    const char ch = head[i];
    if (ch == '\0') return true;
    if (ch == '\r' && (i + 1 >= head.size() || head[i + 1] != '\n')) return true;
    if (ch == '\n' && (i == 0 || head[i - 1] != '\r')) return true;
  }
  return false;
}

std::string_view Trim(std::string_view s) {
  const size_t a = s.find_first_not_of(" \t");
  if (a == std::string_view::npos) return {};
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

// Calls f with each item of a comma-separated header list (RFC 9110 5.6.1), trimmed and
// lower-cased.
template <typename F>
void ForEachListItem(std::string_view value, F f) {
  for (size_t a = 0; a <= value.size();) {
    const size_t b = std::min(value.find(',', a), value.size());
    f(Lower(Trim(value.substr(a, b - a))));
    a = b + 1;
  }
}

// Writes all of `data` to a non-blocking socket within `timeout`; false on failure.
bool WriteAll(int fd, const char* data, size_t size, Clock::duration timeout) {
  const auto deadline = Clock::now() + timeout;
  while (size > 0) {
    const ssize_t n = ::send(fd, data, size, MSG_NOSIGNAL);
    if (n > 0) {
      data += n;
      size -= static_cast<size_t>(n);
      continue;
    }
    if (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) return false;
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd, POLLOUT, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) return false;
  }
  return true;
}

// An error the front answers itself, closing the connection.
std::string ErrorReply(int status, const std::string& body) {
  std::string reply = "HTTP/1.1 " + std::to_string(status) + " " + ReasonPhrase(status) +
                      "\r\nContent-Type: application/json\r\nX-Content-Type-Options: "
                      "nosniff\r\nConnection: close\r\n";
  if (status == 429) reply += "Retry-After: 1\r\n";
  return reply + "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body;
}

thread_local Connection* current_connection = nullptr;

// What the header lines of a head say about its framing, read line by line.
struct HeaderScan {
  std::string content_length;
  int content_length_count = 0;
  std::string transfer_encoding;  // every value, lower case, comma-separated
  bool encoded = false;           // a Content-Encoding other than identity
  bool keep_alive_asked = false;
};

// Reads one header line into the request and the scan; a refusal when it cannot be read.
HeadRefusal ReadHeaderLine(std::string_view line, HttpRequest* request, RequestFraming* framing,
                           HeaderScan* scan) {
  if (line.size() + 2 > kMaxHeaderLine) {
    return {431, "a header line is longer than " + std::to_string(kMaxHeaderLine) + " bytes"};
  }
  if (!line.empty() && (line[0] == ' ' || line[0] == '\t')) {
    return {400, "a header line folded onto the next (obsolete line folding)"};
  }
  const size_t colon = line.find(':');
  if (colon == std::string_view::npos) return {400, "a header line without a colon"};
  if (!IsToken(line.substr(0, colon))) {
    return {400, "a header name that is not a token (no spaces before the colon)"};
  }
  const std::string name = Lower(line.substr(0, colon));
  const std::string_view value = Trim(line.substr(colon + 1));
  if (name == "content-length") {
    if (scan->content_length_count++ > 0 && value != scan->content_length) {
      return {400, "conflicting Content-Length headers"};
    }
    scan->content_length = value;
  } else if (name == "transfer-encoding") {
    if (!scan->transfer_encoding.empty()) scan->transfer_encoding.push_back(',');
    scan->transfer_encoding.append(Lower(value));
  } else if (name == "content-encoding") {
    // Every value and every coding in it (a check of the last header alone would pass "gzip"
    // then "identity").
    ForEachListItem(value, [&](const std::string& coding) {
      scan->encoded = scan->encoded || (!coding.empty() && coding != "identity");
    });
  } else if (name == "connection") {
    // A list of case-insensitive tokens (RFC 9110 7.6.1).
    ForEachListItem(value, [&](const std::string& option) {
      framing->close = framing->close || option == "close";
      scan->keep_alive_asked = scan->keep_alive_asked || option == "keep-alive";
    });
  } else if (name == "expect" && Lower(value) == "100-continue") {
    framing->expect_continue = true;
  } else if (name == "range" && value.find(',') != std::string_view::npos) {
    // Responses are never cut to ranges: one range is ignored (RFC 9110 14.2 allows it) and the
    // whole response sent; several are refused rather than ignored.
    return {416, "Range: at most one range, and it is ignored"};
  }
  // Values as the routes read them since httplib: percent-decoded; empty ones dropped.
  if (!value.empty()) {
    request->headers.emplace(std::string(line.substr(0, colon)), DecodeUrl(value, false));
  }
  return {};
}

// The body framing a head's header lines name; a refusal for an ambiguous or refused one.
HeadRefusal ReadBodyFraming(const HeaderScan& scan, size_t max_body_bytes,
                            RequestFraming* framing) {
  if (scan.encoded) {
    return {415, "Content-Encoding: only 'identity' is accepted; send the body as is"};
  }
  if (!scan.transfer_encoding.empty()) {
    if (scan.transfer_encoding != "chunked") {
      return {400, "Transfer-Encoding: only 'chunked' is accepted"};
    }
    if (scan.content_length_count > 0) return {400, "both Content-Length and Transfer-Encoding"};
    framing->chunked = true;
  } else if (scan.content_length_count > 0) {
    const std::string& length = scan.content_length;
    if (length.empty() || length.size() > 18 ||
        length.find_first_not_of("0123456789") != std::string::npos) {
      return {400, "a malformed Content-Length"};
    }
    framing->content_length = std::stoull(length);
    if (framing->content_length > max_body_bytes) {
      return {413, "the body of " + length + " bytes is larger than " +
                       std::to_string(max_body_bytes) + " bytes"};
    }
  }
  // Requests without Content-Length or Transfer-Encoding have no body (RFC 9112 6.3).
  return {};
}

}  // namespace

bool SameSecret(std::string_view a, std::string_view b) {
  size_t diff = a.size() ^ b.size();
  const size_t n = std::max(a.size(), b.size());
  for (size_t i = 0; i < n; ++i) {
    const unsigned char x = i < a.size() ? a[i] : 0, y = i < b.size() ? b[i] : 0;
    diff |= x ^ y;
  }
  return diff == 0;
}

HeadRefusal ReadRequestHead(std::string_view head, size_t max_body_bytes, HttpRequest* request,
                            RequestFraming* framing) {
  if (HasStrayLineBreakOrNul(head)) {
    return {400, "the request head holds a NUL, or a CR or LF outside a CRLF"};
  }
  const size_t line_end = head.find("\r\n");
  const std::string_view line = head.substr(0, line_end);
  // Nothing after an unparsable request line can be framed: refused, and the connection closed.
  if (!WellFormedRequestLine(line)) {
    return {400,
            "a malformed request line: expected METHOD TARGET HTTP/1.1, separated by single "
            "spaces"};
  }
  const size_t sp1 = line.find(' '), sp2 = line.find(' ', sp1 + 1);
  const std::string_view target = line.substr(sp1 + 1, sp2 - sp1 - 1);
  request->method = line.substr(0, sp1);
  request->target = target;
  request->version = line.substr(sp2 + 1);
  const bool http10 = request->version == "HTTP/1.0";
  if (!http10 && request->version != "HTTP/1.1") {
    return {505, "the HTTP version: only HTTP/1.1 and HTTP/1.0 are served"};
  }
  if (line.size() > kMaxRequestLine) {
    return {414,
            "the request target (path and query) is too long: the request line holds at "
            "most " +
                std::to_string(kMaxRequestLine) + " bytes"};
  }
  // Origin form only (absolute form is for proxies; "?/v1/..." has no path).
  if (!target.starts_with('/')) return {400, "the request target must be a path starting with '/'"};
  // The path is decoded before routing: an encoded '/' or ':' would reach another route than the
  // one the raw path names (RFC 3986 2.2), past any proxy rule on the raw path.
  if (EncodesSeparator(target)) {
    return {404,
            "no route for a path with an encoded '/' or ':' (%2F, %3A, %u...): send them as they "
            "are"};
  }
  HeaderScan scan;
  for (size_t pos = line_end + 2; pos < head.size();) {
    const size_t next = head.find("\r\n", pos);
    if (HeadRefusal r = ReadHeaderLine(head.substr(pos, next - pos), request, framing, &scan);
        r.status != 0) {
      return r;
    }
    pos = next + 2;
  }
  if (HeadRefusal r = ReadBodyFraming(scan, max_body_bytes, framing); r.status != 0) return r;
  // HTTP/1.0 closes unless the client asked to keep the connection (RFC 9112 9.3).
  if (http10 && !scan.keep_alive_asked) framing->close = true;
  ReadTarget(target, request);
  return {};
}

// A connection and the bytes of its current request.
struct HttpFront::Conn {
  int fd = -1;
  std::string buf;            // received and not yet read into the request
  bool head_started = false;  // a request's first bytes arrived (the head deadline runs)
  bool head_done = false;     // `request` and `framing` hold the head; buf starts at the body
  HttpRequest request;
  RequestFraming framing;
  size_t chunk_pos = 0;      // chunked: the next chunk-size line in buf
  size_t body_bytes = 0;     // chunked: the payload of the chunks read, at the start of buf
  size_t request_bytes = 0;  // bytes of the request taken out of buf, counted until answered
  bool health = false;       // GET /healthz or /metrics
  bool registered = false;   // in the epoll set
  std::string out;           // response bytes the socket has not taken yet, from out_pos
  size_t out_pos = 0;
  size_t out_reserved = 0;  // bytes of out counted in the front's pending_out_
  bool writing = false;     // the reactor sends `out` (watching EPOLLOUT), then reads again
  bool close_after_out = false;
  Clock::time_point deadline;
  int served = 0;
  size_t accounted = 0;  // bytes counted in the front's in-flight total
  size_t discard = 0;    // closing: request bytes still to read and drop (lingering close)
  bool closing = false;
  // A request on it carried the server's bearer token: never evicted for a newcomer.
  bool trusted = false;
  Clock::time_point accepted;
  Connection view;
};

// A fixed pool of threads taking connections with complete requests.
class HttpFront::Pool {
 public:
  // Throws std::system_error when a thread cannot be started (the threads started are joined).
  Pool(int threads, std::function<void(std::unique_ptr<Conn>)> serve) : serve_(std::move(serve)) {
    try {
      for (int i = 0; i < threads; ++i) threads_.emplace_back([this] { Run(); });
    } catch (...) {
      Stop();
      throw;
    }
  }
  ~Pool() { Stop(); }
  void Push(std::unique_ptr<Conn> c) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      queue_.push_back(std::move(c));
    }
    cv_.notify_one();
  }
  void Stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stopped_) return;
      stopped_ = true;
    }
    cv_.notify_all();
    for (auto& t : threads_) t.join();
  }
  // Connections never served (at shutdown).
  std::deque<std::unique_ptr<Conn>> Drain() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::move(queue_);
  }

 private:
  void Run() {
    for (;;) {
      std::unique_ptr<Conn> c;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        cv_.wait(lock, [this] { return stopped_ || !queue_.empty(); });
        if (stopped_) return;
        c = std::move(queue_.front());
        queue_.pop_front();
      }
      serve_(std::move(c));
    }
  }
  std::function<void(std::unique_ptr<Conn>)> serve_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<std::unique_ptr<Conn>> queue_;
  bool stopped_ = false;
  std::vector<std::thread> threads_;
};

// The reactor thread's state and steps: it accepts connections, reads requests until they are
// complete, refuses what it must, sends what slow readers have not taken yet, and enforces the
// deadlines. Only the reactor thread touches it.
class HttpFront::Reactor {
 public:
  explicit Reactor(HttpFront* front) : f_(*front), events_(64) {}
  void Run();

 private:
  // Advances a connection's request: 1 complete, 0 waiting for bytes, -1 refused (closed).
  int Advance(std::unique_ptr<Conn>& c);
  int AdvanceHead(std::unique_ptr<Conn>& c);
  int AdvanceChunks(std::unique_ptr<Conn>& c);
  void Refuse(std::unique_ptr<Conn> c, int status, const std::string& message,
              size_t drain = 4u << 20, double drain_s = 1.0);
  void Dispatch(std::unique_ptr<Conn> c);
  std::unique_ptr<Conn> SendRest(std::unique_ptr<Conn> c);
  void Settle(std::unique_ptr<Conn> c);
  void Accept();
  // At the connection limit: closes the connection that is least likely a client's being served
  // (lingering after a refusal, then idle or still sending its head, oldest first; never one that
  // carried the bearer token, sends a body or waits for its response); false if none may go.
  bool EvictOne();
  void OnEvent(int fd);
  void Linger(std::unique_ptr<Conn> c);
  void Receive(std::unique_ptr<Conn> c);
  void TakeIncoming();
  void ExpireDeadlines();
  // Starts the head deadline at a request's first bytes; drops empty lines between requests.
  void NoteHeadStart(Conn* c);
  // Watches a connection for `events` (adding it to the epoll set if needed); false on failure.
  bool Watch(Conn* c, uint32_t events);
  void Hold(std::unique_ptr<Conn> c) {
    const int fd = c->fd;
    conns_[fd] = std::move(c);
  }

  HttpFront& f_;
  std::map<int, std::unique_ptr<Conn>> conns_;
  std::vector<epoll_event> events_;
  Clock::time_point accept_paused_until_{};  // out of file descriptors: accept again then
};

bool HttpFront::Reactor::Watch(Conn* c, uint32_t events) {
  epoll_event ev{};
  ev.events = events;
  ev.data.fd = c->fd;
  if (::epoll_ctl(f_.epoll_fd_, c->registered ? EPOLL_CTL_MOD : EPOLL_CTL_ADD, c->fd, &ev) != 0) {
    return false;
  }
  c->registered = true;
  return true;
}

// Answers an error itself and closes the connection after a lingering close: the client may still
// be sending the request it is refused, and closing with unread bytes would reset the connection
// and lose the answer, so what it sends is read and dropped for a while. `drain` (and `drain_s`):
// how much of the request to read and drop, and for how long.
void HttpFront::Reactor::Refuse(std::unique_ptr<Conn> c, int status, const std::string& message,
                                size_t drain, double drain_s) {
  const std::string reply = ErrorReply(status, f_.render_error_(status, message));
  WriteAll(c->fd, reply.data(), reply.size(), std::chrono::milliseconds(100));
  if (f_.observe_) f_.observe_(status);
  ::shutdown(c->fd, SHUT_WR);
  f_.ReleaseBytes(c.get(), c->accounted);
  c->buf.clear();
  c->buf.shrink_to_fit();
  c->request = HttpRequest{};
  c->closing = true;
  c->discard = drain;
  c->deadline = Clock::now() + Seconds(drain_s);
  if (!c->registered && !Watch(c.get(), EPOLLIN | EPOLLRDHUP)) return f_.Close(std::move(c));
  Hold(std::move(c));
}

int HttpFront::Reactor::AdvanceHead(std::unique_ptr<Conn>& c) {
  const HttpFrontOptions& o = f_.options_;
  // Empty lines before a request line are ignored (RFC 9112 2.2).
  size_t empty = 0;
  while (c->buf.compare(empty, 2, "\r\n") == 0) empty += 2;
  if (empty > 0) {
    f_.ReleaseBytes(c.get(), empty);
    c->buf.erase(0, empty);
  }
  const size_t end = c->buf.find("\r\n\r\n");
  if (end == std::string::npos ? c->buf.size() > o.max_head_bytes : end + 4 > o.max_head_bytes) {
    Refuse(std::move(c), 431,
           "the request head is larger than " + std::to_string(o.max_head_bytes) + " bytes");
    return -1;
  }
  if (end == std::string::npos) return 0;
  if (HeadRefusal r = ReadRequestHead(std::string_view(c->buf).substr(0, end + 2), o.max_body_bytes,
                                      &c->request, &c->framing);
      r.status != 0) {
    Refuse(std::move(c), r.status, r.message);
    return -1;
  }
  // A body is read, counted and answered with 100 Continue only for a client with the server's
  // bearer token: without it, clients could hold the in-flight bound unauthenticated.
  const bool authorized = !o.body_authorization.empty() &&
                          SameSecret(c->request.Header("Authorization"), o.body_authorization);
  if (authorized) c->trusted = true;
  if (!o.body_authorization.empty() && c->framing.has_body() && !authorized) {
    // The body it announced is read and dropped, never kept, so that the client (a robot with a
    // mistyped key sending photos) reads the 401 instead of a reset connection.
    const size_t announced =
        c->framing.chunked ? o.max_body_bytes + 4096 : c->framing.content_length;
    Refuse(std::move(c), 401,
           "missing or wrong bearer token (Authorization header): a request body is read only "
           "from an authenticated client",
           announced, std::max(1.0, o.head_timeout_s));
    return -1;
  }
  // Not to HTTP/1.0 clients (RFC 9110 15.2), nor for a request without a body.
  if (c->framing.expect_continue && c->request.version != "HTTP/1.0" && c->framing.has_body()) {
    static const char kContinue[] = "HTTP/1.1 100 Continue\r\n\r\n";
    WriteAll(c->fd, kContinue, sizeof kContinue - 1, std::chrono::milliseconds(100));
  }
  // The head is read: the buffer holds the body (and what follows it) from now on.
  c->buf.erase(0, end + 4);
  c->request_bytes = end + 4;
  c->head_done = true;
  c->health = (c->request.method == "GET" || c->request.method == "HEAD") &&
              (c->request.path == "/healthz" || c->request.path == "/metrics");
  c->deadline = Clock::now() + Seconds(o.body_timeout_s);
  return 1;
}

// Chunked: size line, data, CRLF; a zero size ends the body (no trailers). Each chunk's data is
// moved down to the end of the body decoded so far, at the start of the buffer.
int HttpFront::Reactor::AdvanceChunks(std::unique_ptr<Conn>& c) {
  const size_t max_body = f_.options_.max_body_bytes;
  for (;;) {
    const size_t line_end = c->buf.find("\r\n", c->chunk_pos);
    if (line_end == std::string::npos) {
      if (c->buf.size() - c->chunk_pos > 256) {
        Refuse(std::move(c), 400, "a malformed chunk size line");
        return -1;
      }
      return 0;
    }
    const std::string_view line(c->buf.data() + c->chunk_pos, line_end - c->chunk_pos);
    const std::string digits(Trim(line.substr(0, line.find(';'))));
    if (digits.empty() || digits.size() > 15 ||
        digits.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos) {
      Refuse(std::move(c), 400, "a malformed chunk size");
      return -1;
    }
    const size_t size = std::stoull(digits, nullptr, 16);
    if (size == 0) {
      if (c->buf.size() < line_end + 4) return 0;
      if (c->buf.compare(line_end + 2, 2, "\r\n") != 0) {
        Refuse(std::move(c), 400, "chunked trailers are not accepted");
        return -1;
      }
      c->request.body.assign(c->buf, 0, c->body_bytes);
      c->buf.erase(0, line_end + 4);
      c->request_bytes += line_end + 4;
      return 1;
    }
    if (c->body_bytes + size > max_body) {
      Refuse(std::move(c), 413,
             "the chunked body is larger than " + std::to_string(max_body) + " bytes");
      return -1;
    }
    // Framing may at most double the wire size of the body (no floods of 1-byte chunks).
    if (line_end + 2 > 2 * (c->body_bytes + size) + 4096) {
      Refuse(std::move(c), 400, "chunks too small");
      return -1;
    }
    if (c->buf.size() < line_end + 2 + size + 2) return 0;
    if (c->buf.compare(line_end + 2 + size, 2, "\r\n") != 0) {
      Refuse(std::move(c), 400, "a chunk without its CRLF");
      return -1;
    }
    std::memmove(c->buf.data() + c->body_bytes, c->buf.data() + line_end + 2, size);
    c->body_bytes += size;
    c->chunk_pos = line_end + 2 + size + 2;
  }
}

int HttpFront::Reactor::Advance(std::unique_ptr<Conn>& c) {
  if (!c->head_done) {
    const int head = AdvanceHead(c);
    if (head <= 0) return head;
  }
  if (c->framing.chunked) return AdvanceChunks(c);
  const size_t length = c->framing.content_length;
  if (c->buf.size() < length) return 0;
  if (c->buf.size() == length) {
    c->request.body = std::move(c->buf);  // the whole buffer: no copy
    c->buf = std::string();
  } else {
    c->request.body.assign(c->buf, 0, length);
    c->buf.erase(0, length);
  }
  c->request_bytes += length;
  return 1;
}

void HttpFront::Reactor::Dispatch(std::unique_ptr<Conn> c) {
  if (c->registered) {
    ::epoll_ctl(f_.epoll_fd_, EPOLL_CTL_DEL, c->fd, nullptr);
    c->registered = false;
  }
  Pool* pool = c->health ? f_.health_.get() : f_.workers_.get();
  pool->Push(std::move(c));
}

// A connection whose response waits for the client to read: watched for EPOLLOUT until sent
// (within the write timeout), then closed or read again.
std::unique_ptr<HttpFront::Conn> HttpFront::Reactor::SendRest(std::unique_ptr<Conn> c) {
  const size_t before = c->out_pos;
  if (!f_.FlushOut(c.get())) {
    f_.Close(std::move(c));
    return nullptr;
  }
  if (c->writing) {
    // The write timeout runs between two sends that make progress (nginx's send_timeout).
    if (c->out_pos > before) c->deadline = Clock::now() + Seconds(f_.options_.write_timeout_s);
    if (!Watch(c.get(), EPOLLOUT)) {
      f_.Close(std::move(c));
      return nullptr;
    }
    Hold(std::move(c));
    return nullptr;
  }
  if (c->close_after_out) {
    f_.Close(std::move(c));
    return nullptr;
  }
  c->deadline = Clock::now() + Seconds(f_.options_.idle_timeout_s);
  if (c->registered && !Watch(c.get(), EPOLLIN | EPOLLRDHUP)) {  // read again
    f_.Close(std::move(c));
    return nullptr;
  }
  return c;
}

// A connection's bytes so far: dispatched when complete, kept (and watched) otherwise.
void HttpFront::Reactor::Settle(std::unique_ptr<Conn> c) {
  const int state = Advance(c);
  if (state < 0) return;
  if (state > 0) {
    conns_.erase(c->fd);
    return Dispatch(std::move(c));
  }
  if (!c->registered && !Watch(c.get(), EPOLLIN | EPOLLRDHUP)) return f_.Close(std::move(c));
  Hold(std::move(c));
}

void HttpFront::Reactor::NoteHeadStart(Conn* c) {
  if (c->head_done) return;
  if (c->buf.find_first_not_of("\r\n") == std::string::npos) {
    f_.ReleaseBytes(c, c->buf.size());
    c->buf.clear();  // nothing of a request yet: the connection stays idle
  } else if (!c->head_started) {
    c->head_started = true;
    c->deadline = Clock::now() + Seconds(f_.options_.head_timeout_s);
  }
}

void HttpFront::Reactor::Accept() {
  for (;;) {
    const int fd = ::accept4(f_.listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd >= 0) {
      // Idle or unauthenticated connections must not keep a robot with the key out: at the limit
      // a newcomer takes the place of one of them, and is refused only when none is left.
      if (f_.open_connections_.load() >= f_.options_.max_connections) EvictOne();
      f_.Admit(fd);
      continue;
    }
    if (errno == EINTR || errno == ECONNABORTED) continue;
    if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
      // Out of descriptors: the connections wait in the listen queue a moment (the listening
      // socket, level-triggered, would wake the reactor at once otherwise).
      epoll_event ev{};
      ev.data.fd = f_.listen_fd_;
      ::epoll_ctl(f_.epoll_fd_, EPOLL_CTL_MOD, f_.listen_fd_, &ev);
      accept_paused_until_ = Clock::now() + std::chrono::milliseconds(10);
    }
    return;
  }
}

bool HttpFront::Reactor::EvictOne() {
  auto rank = [](const Conn& c) {
    if (c.closing) return 0;
    if (c.trusted || c.writing || c.head_done) return 3;  // kept
    return c.head_started ? 2 : 1;
  };
  auto victim = conns_.end();
  for (auto it = conns_.begin(); it != conns_.end(); ++it) {
    const int r = rank(*it->second);
    if (r == 3) continue;
    if (victim == conns_.end() || r < rank(*victim->second) ||
        (r == rank(*victim->second) && it->second->accepted < victim->second->accepted)) {
      victim = it;
    }
  }
  if (victim == conns_.end()) return false;
  std::unique_ptr<Conn> c = std::move(victim->second);
  conns_.erase(victim);
  f_.Close(std::move(c));
  return true;
}

// Closing: reads and drops what the client still sends, up to the refusal's drain.
void HttpFront::Reactor::Linger(std::unique_ptr<Conn> c) {
  char chunk[16384];
  ssize_t got = 0;
  while ((got = ::recv(c->fd, chunk, sizeof chunk, 0)) > 0 && c->discard > 0) {
    c->discard -= std::min(c->discard, static_cast<size_t>(got));
  }
  const bool again = got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
  if (again && c->discard > 0) return Hold(std::move(c));
  f_.Close(std::move(c));
}

// Reads what the socket holds, within the in-flight bound, and advances the request.
void HttpFront::Reactor::Receive(std::unique_ptr<Conn> c) {
  const HttpFrontOptions& o = f_.options_;
  char chunk[16384];
  bool eof = false, over = false;
  for (;;) {
    const ssize_t got = ::recv(c->fd, chunk, sizeof chunk, 0);
    if (got > 0) {
      if (f_.inflight_ + static_cast<size_t>(got) > o.max_inflight_bytes) {
        over = true;
        break;
      }
      c->buf.append(chunk, static_cast<size_t>(got));
      f_.inflight_ += static_cast<size_t>(got);
      c->accounted += static_cast<size_t>(got);
      // Enough to decide: Advance() refuses heads and bodies past their limits.
      if (!c->head_done && c->buf.size() > o.max_head_bytes + sizeof chunk) break;
      if (c->buf.size() > 2 * o.max_body_bytes + o.max_head_bytes + 8192) break;
      continue;
    }
    if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    if (got < 0 && errno == EINTR) continue;
    eof = true;  // end of stream or a reset
    break;
  }
  if (over) return Refuse(std::move(c), 429, "too many request bytes in flight; retry later");
  NoteHeadStart(c.get());
  if (!eof) return Settle(std::move(c));
  // A client that closed its side after a complete request still gets the answer.
  if (Advance(c) > 0) return Dispatch(std::move(c));
  if (c) f_.Close(std::move(c));
}

void HttpFront::Reactor::OnEvent(int fd) {
  if (fd == f_.wake_fd_) {
    uint64_t value;
    while (::read(f_.wake_fd_, &value, sizeof value) > 0) {
    }
    return;
  }
  if (fd == f_.listen_fd_) return Accept();
  auto it = conns_.find(fd);
  if (it == conns_.end()) return;
  std::unique_ptr<Conn> c = std::move(it->second);
  conns_.erase(it);
  if (c->writing) {
    if (auto ready = SendRest(std::move(c))) Settle(std::move(ready));
    return;
  }
  if (c->closing) return Linger(std::move(c));
  Receive(std::move(c));
}

// New connections, and those a worker gave back (to read the next request or send the rest).
void HttpFront::Reactor::TakeIncoming() {
  std::vector<std::unique_ptr<Conn>> incoming;
  {
    std::lock_guard<std::mutex> lock(f_.incoming_mutex_);
    incoming.swap(f_.incoming_);
  }
  for (auto& c : incoming) {
    if (c->writing) {
      c->deadline = Clock::now() + Seconds(f_.options_.write_timeout_s);
      c = SendRest(std::move(c));
      if (!c) continue;
    }
    NoteHeadStart(c.get());
    Settle(std::move(c));
  }
}

// Deadlines: an idle connection closes quietly, a slow request gets 408.
void HttpFront::Reactor::ExpireDeadlines() {
  const auto now = Clock::now();
  for (auto it = conns_.begin(); it != conns_.end();) {
    if (it->second->deadline > now) {
      ++it;
      continue;
    }
    std::unique_ptr<Conn> c = std::move(it->second);
    it = conns_.erase(it);
    if (!c->head_started || c->closing || c->writing) {
      f_.Close(std::move(c));
    } else {
      Refuse(std::move(c), 408,
             c->head_done ? "the request body did not arrive in time"
                          : "the request head did not arrive in time");
    }
  }
}

void HttpFront::Reactor::Run() {
  while (!f_.stopping_) {
    auto now = Clock::now();
    Clock::time_point next = now + std::chrono::milliseconds(200);
    for (const auto& [fd, c] : conns_) next = std::min(next, c->deadline);
    if (accept_paused_until_ != Clock::time_point{}) {
      if (accept_paused_until_ <= now) {
        epoll_event ev{};
        ev.events = EPOLLIN;
        ev.data.fd = f_.listen_fd_;
        ::epoll_ctl(f_.epoll_fd_, EPOLL_CTL_MOD, f_.listen_fd_, &ev);
        accept_paused_until_ = {};
      } else {
        next = std::min(next, accept_paused_until_);
      }
    }
    const int timeout = static_cast<int>(std::max<int64_t>(
        0, std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count() + 1));
    const int n =
        ::epoll_wait(f_.epoll_fd_, events_.data(), static_cast<int>(events_.size()), timeout);
    for (int i = 0; i < n; ++i) OnEvent(events_[i].data.fd);
    TakeIncoming();
    ExpireDeadlines();
  }
  for (auto& [fd, c] : conns_) f_.Close(std::move(c));
}

HttpFront::HttpFront(HttpFrontOptions options, Handler handler, ErrorRenderer render_error,
                     FrontResponseObserver observe)
    : options_(std::move(options)),
      handler_(std::move(handler)),
      render_error_(std::move(render_error)),
      observe_(std::move(observe)) {}

HttpFront::~HttpFront() { Shutdown(); }

Connection* HttpFront::Current() { return current_connection; }

bool HttpFront::ClientGone() { return ClientGone(current_connection); }

bool HttpFront::ClientGone(const Connection* c) {
  if (c == nullptr || c->fd < 0) return false;
  pollfd p{c->fd, POLLIN | POLLRDHUP, 0};
  if (::poll(&p, 1, 0) <= 0) return false;
  if (p.revents & (POLLRDHUP | POLLHUP | POLLERR | POLLNVAL)) return true;
  if (p.revents & POLLIN) {
    // Data (a pipelined request) or the end of the stream.
    char byte;
    return ::recv(c->fd, &byte, 1, MSG_PEEK | MSG_DONTWAIT) == 0;
  }
  return false;
}

int HttpFront::Bind(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* result = nullptr;
  const std::string service = std::to_string(port);
  if (::getaddrinfo(host.empty() ? nullptr : host.c_str(), service.c_str(), &hints, &result) != 0) {
    return -1;
  }
  for (addrinfo* a = result; a != nullptr && listen_fd_ < 0; a = a->ai_next) {
    const int fd =
        ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC | SOCK_NONBLOCK, a->ai_protocol);
    if (fd < 0) continue;
    // SO_REUSEADDR lets a restart bind while the old connections linger in TIME_WAIT; never
    // SO_REUSEPORT, with which another process of the same user could bind the same port and take
    // a share of the connections.
    const int yes = 1, no = 0;
    ::setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    if (a->ai_family == AF_INET6) ::setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &no, sizeof no);
    // A wide accept queue: a burst of connects (six plans and a health check at once) must not
    // overflow it while the reactor waits for a core (the kernel caps it at net.core.somaxconn;
    // a dropped SYN is retried only after 1 s).
    if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, SOMAXCONN) == 0) {
      listen_fd_ = fd;
    } else {
      ::close(fd);
    }
  }
  ::freeaddrinfo(result);
  if (listen_fd_ < 0) return -1;
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  if (::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len) != 0) return -1;
  if (addr.ss_family == AF_INET) return ntohs(reinterpret_cast<sockaddr_in*>(&addr)->sin_port);
  if (addr.ss_family == AF_INET6) return ntohs(reinterpret_cast<sockaddr_in6*>(&addr)->sin6_port);
  return -1;
}

void HttpFront::Start() {
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  for (const int fd : {wake_fd_, listen_fd_}) {
    if (fd < 0) continue;
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.fd = fd;
    ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &ev);
  }
  workers_ = std::make_unique<Pool>(options_.workers,
                                    [this](std::unique_ptr<Conn> c) { Serve(std::move(c)); });
  health_ = std::make_unique<Pool>(options_.health_workers,
                                   [this](std::unique_ptr<Conn> c) { Serve(std::move(c)); });
  reactor_ = std::thread([this] { Reactor(this).Run(); });
}

void HttpFront::Shutdown() {
  if (stopping_.exchange(true)) return;
  Wake();
  if (reactor_.joinable()) reactor_.join();
  if (listen_fd_ >= 0) ::close(listen_fd_);
  listen_fd_ = -1;
  if (workers_) workers_->Stop();
  if (health_) health_->Stop();
  for (Pool* pool : {workers_.get(), health_.get()}) {
    if (!pool) continue;
    for (auto& c : pool->Drain()) Close(std::move(c));
  }
  {
    std::lock_guard<std::mutex> lock(incoming_mutex_);
    for (auto& c : incoming_) Close(std::move(c));
    incoming_.clear();
  }
  if (wake_fd_ >= 0) ::close(wake_fd_);
  if (epoll_fd_ >= 0) ::close(epoll_fd_);
  wake_fd_ = epoll_fd_ = -1;
}

void HttpFront::Wake() {
  if (wake_fd_ < 0) return;
  const uint64_t one = 1;
  (void)!::write(wake_fd_, &one, sizeof one);
}

void HttpFront::Admit(int fd) {
  // Responses go out as header and body writes: without TCP_NODELAY, Nagle's algorithm holds the
  // body until the client's delayed ACK (40 ms).
  const int one = 1;
  ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  if (stopping_ || open_connections_.fetch_add(1) >= options_.max_connections) {
    if (!stopping_) --open_connections_;
    const std::string reply =
        ErrorReply(429, render_error_(429, "too many open connections; retry later"));
    WriteAll(fd, reply.data(), reply.size(), std::chrono::milliseconds(100));
    if (observe_) observe_(429);
    ::shutdown(fd, SHUT_RDWR);
    ::close(fd);
    return;
  }
  auto c = std::make_unique<Conn>();
  c->fd = fd;
  c->view.fd = fd;
  c->accepted = Clock::now();
  c->deadline = c->accepted + Seconds(options_.idle_timeout_s);
  std::lock_guard<std::mutex> lock(incoming_mutex_);
  incoming_.push_back(std::move(c));
}

void HttpFront::ReleaseBytes(Conn* c, size_t n) {
  n = std::min(n, c->accounted);
  c->accounted -= n;
  inflight_ -= n;
}

bool HttpFront::FlushOut(Conn* c) {
  while (c->out_pos < c->out.size()) {
    const ssize_t n =
        ::send(c->fd, c->out.data() + c->out_pos, c->out.size() - c->out_pos, MSG_NOSIGNAL);
    if (n > 0) {
      c->out_pos += static_cast<size_t>(n);
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
    }
  }
  pending_out_ -= c->out_reserved;
  c->out_reserved = 0;
  c->out.clear();
  c->out.shrink_to_fit();
  c->out_pos = 0;
  c->writing = false;
  return true;
}

bool HttpFront::Reserve(Conn* c, size_t n) {
  size_t now = pending_out_.load();
  do {
    if (now + n > options_.max_inflight_bytes) return false;
  } while (!pending_out_.compare_exchange_weak(now, now + n));
  c->out_reserved += n;
  return true;
}

// What the socket takes now goes; the rest waits in the connection for the reactor, which sends
// it as the client reads. Past the front's bound on waiting bytes, the worker sends it itself,
// waiting for the socket up to the write timeout (what waited before it first).
bool HttpFront::Send(Conn* c, const char* data, size_t size) {
  const Clock::duration timeout = Seconds(options_.write_timeout_s);
  if (c->out_pos == c->out.size()) {
    size_t sent = 0;
    while (sent < size) {
      const ssize_t n = ::send(c->fd, data + sent, size - sent, MSG_NOSIGNAL);
      if (n > 0) {
        sent += static_cast<size_t>(n);
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        break;
      } else {
        return false;
      }
    }
    if (sent == size) return true;
    c->out.clear();
    c->out_pos = 0;
    data += sent;
    size -= sent;
  }
  if (Reserve(c, size)) {
    c->out.append(data, size);
    return true;
  }
  if (!WriteAll(c->fd, c->out.data() + c->out_pos, c->out.size() - c->out_pos, timeout)) {
    return false;
  }
  pending_out_ -= c->out_reserved;
  c->out_reserved = 0;
  c->out.clear();
  c->out_pos = 0;
  return WriteAll(c->fd, data, size, timeout);
}

void HttpFront::Close(std::unique_ptr<Conn> c) {
  if (!c || c->fd < 0) return;
  pending_out_ -= c->out_reserved;
  c->out_reserved = 0;
  ReleaseBytes(c.get(), c->accounted);
  if (c->registered && epoll_fd_ >= 0) ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c->fd, nullptr);
  ::shutdown(c->fd, SHUT_RDWR);
  ::close(c->fd);
  c->fd = -1;
  --open_connections_;
}

void HttpFront::Return(std::unique_ptr<Conn> c) {
  {
    std::lock_guard<std::mutex> lock(incoming_mutex_);
    incoming_.push_back(std::move(c));
  }
  Wake();
}

void HttpFront::Serve(std::unique_ptr<Conn> c) {
  c->view.must_close = false;
  const bool last = ++c->served >= options_.keep_alive_max || stopping_ || c->framing.close;
  HttpResponse response;
  current_connection = &c->view;
  try {
    response = handler_(c->request);
  } catch (...) {
    response = HttpResponse{};
    response.status = 500;
    response.SetContent(render_error_(500, "unexpected error"), "application/json");
  }
  current_connection = nullptr;
  // A connection that closes says so in its answer.
  const bool close = last || c->view.must_close;
  FinishResponse(
      c->request,
      {close, static_cast<int>(std::max(1.0, options_.idle_timeout_s)), options_.keep_alive_max},
      &response);
  const std::string head = ResponseHead(response);
  bool ok = Send(c.get(), head.data(), head.size());
  if (ok && c->request.method != "HEAD" && !response.body.empty()) {
    ok = Send(c.get(), response.body.data(), response.body.size());
  }
  const bool keep = ok && !close && !stopping_;
  if (c->out_pos < c->out.size() && ok && !stopping_) {
    // The reactor sends the rest as the client reads, then reads the next request or closes.
    c->close_after_out = !keep;
    c->writing = true;
  }
  if (!keep && !c->writing) return Close(std::move(c));
  // The next request may already be buffered (pipelining).
  ReleaseBytes(c.get(), c->request_bytes);
  c->request = HttpRequest{};
  c->framing = RequestFraming{};
  c->head_started = c->head_done = false;
  c->chunk_pos = c->body_bytes = c->request_bytes = 0;
  c->health = false;
  c->deadline = Clock::now() + Seconds(options_.idle_timeout_s);
  Return(std::move(c));
}

}  // namespace npfkct::server
