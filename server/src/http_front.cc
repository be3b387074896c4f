#include "http_front.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <strings.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cstring>
#include <map>
#include <string_view>

namespace npfkct::server {
namespace {

using Clock = std::chrono::steady_clock;

Clock::duration Seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The longest header line httplib reads (its CPPHTTPLIB_HEADER_MAX_LENGTH); it would answer a
// longer one with 400.
constexpr size_t kMaxHeaderLine = 8192;
// The longest request line the front passes on: below httplib's CPPHTTPLIB_REQUEST_URI_MAX_LENGTH
// (8,192 with the line's CRLF), past which httplib answers a bare 414.
constexpr size_t kMaxRequestLine = 8000;

// A header field name: one or more tchar (RFC 9110 5.6.2).
bool IsToken(const std::string& s) {
  static constexpr std::string_view kSymbols = "!#$%&'*+-.^_`|~";
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char ch) {
    return std::isalnum(static_cast<unsigned char>(ch)) || kSymbols.find(ch) != kSymbols.npos;
  });
}

// Whether `line` is a request line (RFC 9112 3): method SP request-target SP HTTP/d.d, the method
// a token and the target without spaces.
bool WellFormedRequestLine(const std::string& line) {
  const size_t sp1 = line.find(' ');
  if (sp1 == std::string::npos || !IsToken(line.substr(0, sp1))) return false;
  const size_t sp2 = line.find(' ', sp1 + 1);
  if (sp2 == std::string::npos || sp2 == sp1 + 1) return false;
  const std::string_view version = std::string_view(line).substr(sp2 + 1);
  return version.size() == 8 && version.substr(0, 5) == "HTTP/" &&
         std::isdigit(static_cast<unsigned char>(version[5])) && version[6] == '.' &&
         std::isdigit(static_cast<unsigned char>(version[7]));
}

// The target of a well-formed request line.
std::string_view TargetOf(std::string_view line) {
  const size_t sp1 = line.find(' ');
  const size_t sp2 = line.find(' ', sp1 + 1);
  return line.substr(sp1 + 1, sp2 - sp1 - 1);
}

// Whether the path of a request target (before any query) holds a percent-encoded '/' or ':'
// (%2F, %3A in any case) or a %uXXXX escape, which httplib decodes too.
bool EncodesSeparator(std::string_view target) {
  const std::string_view path = target.substr(0, target.find('?'));
  for (size_t i = path.find('%'); i != std::string_view::npos && i + 1 < path.size();
       i = path.find('%', i + 1)) {
    const char hi = static_cast<char>(std::tolower(path[i + 1]));
    if (hi == 'u') return true;
    if (i + 2 >= path.size()) break;
    const char lo = static_cast<char>(std::tolower(path[i + 2]));
    if ((hi == '2' && lo == 'f') || (hi == '3' && lo == 'a')) return true;
  }
  return false;
}

// Whether a head (up to its final CRLF) holds a NUL, or a CR or LF that is not part of a CRLF:
// httplib ends lines at a bare LF where the front does not, so such a head would be read as two
// different requests.
bool HasStrayLineBreakOrNul(std::string_view head) {
  for (size_t i = 0; i < head.size(); ++i) {
    const char ch = head[i];
    if (ch == '\0') return true;
    if (ch == '\r' && (i + 1 >= head.size() || head[i + 1] != '\n')) return true;
    if (ch == '\n' && (i == 0 || head[i - 1] != '\r')) return true;
  }
  return false;
}

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t");
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(" \t") - a + 1);
}

// Calls f with each item of a comma-separated header list (RFC 9110 5.6.1), trimmed and
// lower-cased.
template <typename F>
void ForEachListItem(const std::string& value, F f) {
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

thread_local Connection* current_connection = nullptr;

// Reason phrases of the statuses the front answers itself.
const char* Reason(int status) {
  switch (status) {
    case 400:
      return "Bad Request";
    case 401:
      return "Unauthorized";
    case 404:
      return "Not Found";
    case 408:
      return "Request Timeout";
    case 413:
      return "Payload Too Large";
    case 415:
      return "Unsupported Media Type";
    case 416:
      return "Range Not Satisfiable";
    case 429:
      return "Too Many Requests";
    case 414:
      return "URI Too Long";
    case 431:
      return "Request Header Fields Too Large";
    case 505:
      return "HTTP Version Not Supported";
    default:
      return "Error";
  }
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

// A connection and the bytes of its current request.
struct HttpFront::Conn {
  int fd = -1;
  std::string buf;         // received and not yet consumed
  size_t head_end = 0;     // past the head's "\r\n\r\n"; 0 while the head is incomplete
  size_t request_end = 0;  // past the body; 0 while the body is incomplete
  bool chunked = false;
  size_t content_length = 0;
  size_t chunk_pos = 0;     // the next chunk-size line
  size_t body_bytes = 0;    // payload of the chunks consumed so far
  bool health = false;      // GET /healthz or /metrics
  bool registered = false;  // in the epoll set
  std::string out;          // response bytes the socket has not taken yet, from out_pos
  size_t out_pos = 0;
  size_t out_reserved = 0;  // bytes of out counted in the front's pending_out_
  bool writing = false;     // the reactor sends `out` (watching EPOLLOUT), then reads again
  bool close_after_out = false;
  Clock::time_point deadline;
  int served = 0;
  size_t accounted = 0;       // bytes counted in the front's in-flight total
  bool head_started = false;  // a request's first bytes arrived (the head deadline runs)
  size_t discard = 0;         // closing: request bytes still to read and drop (lingering close)
  bool closing = false;
  bool close_asked = false;  // the request asked to close after its response (or is HTTP/1.0)
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

namespace {

// httplib's accept loop hands each socket to process_and_close_socket through this queue, at
// once: the front's reactor takes it from there without blocking the accept loop.
class InlineQueue : public httplib::TaskQueue {
 public:
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override {}
};

// A worker's view of a connection: the buffered request first, then the socket (with
// deadlines) should httplib read further.
class BufferedStream : public httplib::Stream {
 public:
  BufferedStream(HttpFront::Conn& c, size_t& consumed, Clock::duration write_timeout,
                 std::atomic<size_t>& pending_out, size_t max_pending_out)
      : c_(c),
        consumed_(consumed),
        write_timeout_(write_timeout),
        pending_out_(pending_out),
        max_pending_out_(max_pending_out) {}
  bool is_readable() const override { return consumed_ < c_.buf.size() || Poll(POLLIN, 1000); }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override;
  ssize_t write(const char* ptr, size_t size) override;
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    Address(&ip, &port, /*peer=*/true);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    Address(&ip, &port, /*peer=*/false);
  }
  // httplib only compares this with FD_SETSIZE (it select()s on sockets it reads itself, which
  // this stream never asks it to do): the reactor uses epoll, so any descriptor is fine.
  socket_t socket() const override { return c_.fd < FD_SETSIZE ? c_.fd : 0; }

 private:
  int Fd() const { return c_.fd; }
  bool Poll(short events, int ms) const {
    pollfd p{c_.fd, events, 0};
    return ::poll(&p, 1, ms) > 0 && (p.revents & events);
  }
  void Address(std::string* ip, int* port, bool peer) const {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    const int r = peer ? ::getpeername(c_.fd, reinterpret_cast<sockaddr*>(&addr), &len)
                       : ::getsockname(c_.fd, reinterpret_cast<sockaddr*>(&addr), &len);
    char host[INET6_ADDRSTRLEN] = "";
    *port = -1;
    if (r != 0) return;
    if (addr.ss_family == AF_INET) {
      auto* a = reinterpret_cast<sockaddr_in*>(&addr);
      ::inet_ntop(AF_INET, &a->sin_addr, host, sizeof host);
      *port = ntohs(a->sin_port);
    } else if (addr.ss_family == AF_INET6) {
      auto* a = reinterpret_cast<sockaddr_in6*>(&addr);
      ::inet_ntop(AF_INET6, &a->sin6_addr, host, sizeof host);
      *port = ntohs(a->sin6_port);
    }
    *ip = host;
  }

  // Counts `n` more bytes in the front's pending output, unless that would pass its bound.
  bool Reserve(size_t n) {
    size_t now = pending_out_.load();
    do {
      if (now + n > max_pending_out_) return false;
    } while (!pending_out_.compare_exchange_weak(now, now + n));
    c_.out_reserved += n;
    return true;
  }

  HttpFront::Conn& c_;
  size_t& consumed_;
  Clock::duration write_timeout_;
  std::atomic<size_t>& pending_out_;
  size_t max_pending_out_;
};

// What the socket takes now goes; the rest waits in the connection for the reactor, which sends
// it as the client reads. Past the front's bound on waiting bytes, the worker sends it itself,
// waiting for the socket up to the write timeout (what waited before it first).
ssize_t BufferedStream::write(const char* ptr, size_t size) {
  // httplib goes on from the count returned: all of `size` is taken, sent or kept.
  const auto taken = static_cast<ssize_t>(size);
  if (c_.out_pos == c_.out.size()) {
    size_t sent = 0;
    while (sent < size) {
      const ssize_t n = ::send(Fd(), ptr + sent, size - sent, MSG_NOSIGNAL);
      if (n > 0) {
        sent += static_cast<size_t>(n);
      } else if (n < 0 && errno == EINTR) {
        continue;
      } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
        break;
      } else {
        return -1;
      }
    }
    if (sent == size) return taken;
    c_.out.clear();
    c_.out_pos = 0;
    ptr += sent;
    size -= sent;
  }
  if (Reserve(size)) {
    c_.out.append(ptr, size);
    return taken;
  }
  if (!WriteAll(Fd(), c_.out.data() + c_.out_pos, c_.out.size() - c_.out_pos, write_timeout_)) {
    return -1;
  }
  pending_out_ -= c_.out_reserved;
  c_.out_reserved = 0;
  c_.out.clear();
  c_.out_pos = 0;
  return WriteAll(Fd(), ptr, size, write_timeout_) ? taken : -1;
}

ssize_t BufferedStream::read(char* ptr, size_t size) {
  if (consumed_ < c_.request_end) {
    // Never past the current request: what follows belongs to the next one.
    const size_t n = std::min(size, c_.request_end - consumed_);
    std::memcpy(ptr, c_.buf.data() + consumed_, n);
    consumed_ += n;
    return static_cast<ssize_t>(n);
  }
  return -1;  // the reactor read the whole request; httplib asking for more means bad framing
}

}  // namespace

HttpFront::HttpFront(HttpFrontOptions options, ErrorRenderer render_error,
                     FrontResponseObserver observe)
    : options_(options), render_error_(std::move(render_error)), observe_(std::move(observe)) {
  new_task_queue = [] { return new InlineQueue(); };
}

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

void HttpFront::Start() {
  // Debian's libcpp-httplib is a compiled library that listens with a backlog of 5: a burst of
  // connects (six plans and a health check at once) overflowed it while the accept loop waited
  // for a core, and the kernel dropped the SYN the client retries only after 1 s. listen() again
  // on the bound socket widens the queue (the kernel caps it at net.core.somaxconn).
  if (svr_sock_ != INVALID_SOCKET) ::listen(svr_sock_, SOMAXCONN);
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.fd = wake_fd_;
  ::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &ev);
  workers_ = std::make_unique<Pool>(options_.workers,
                                    [this](std::unique_ptr<Conn> c) { Serve(std::move(c)); });
  health_ = std::make_unique<Pool>(options_.health_workers,
                                   [this](std::unique_ptr<Conn> c) { Serve(std::move(c)); });
  reactor_ = std::thread([this] { Reactor(); });
}

void HttpFront::Shutdown() {
  if (stopping_.exchange(true)) return;
  Wake();
  if (reactor_.joinable()) reactor_.join();
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

bool HttpFront::process_and_close_socket(socket_t sock) {
  const int flags = ::fcntl(sock, F_GETFL, 0);
  ::fcntl(sock, F_SETFL, flags | O_NONBLOCK);
  // Responses go out as header and body writes: without TCP_NODELAY, Nagle's algorithm holds the
  // body until the client's delayed ACK (40 ms).
  const int one = 1;
  ::setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  auto c = std::make_unique<Conn>();
  c->fd = sock;
  c->view.fd = sock;
  c->deadline = Clock::now() + Seconds(options_.idle_timeout_s);
  if (stopping_ || open_connections_.fetch_add(1) >= options_.max_connections) {
    if (!stopping_) --open_connections_;
    const std::string body = render_error_(429, "too many open connections; retry later");
    const std::string reply =
        "HTTP/1.1 429 Too Many Requests\r\nContent-Type: application/json\r\n"
        "X-Content-Type-Options: nosniff\r\nRetry-After: 1\r\nConnection: close\r\n"
        "Content-Length: " +
        std::to_string(body.size()) + "\r\n\r\n" + body;
    WriteAll(sock, reply.data(), reply.size(), std::chrono::milliseconds(100));
    if (observe_) observe_(429);
    ::shutdown(sock, SHUT_RDWR);
    ::close(sock);
    return true;
  }
  {
    std::lock_guard<std::mutex> lock(incoming_mutex_);
    incoming_.push_back(std::move(c));
  }
  Wake();
  return true;
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
  size_t consumed = 0;
  bool keep = false, ok = false;
  {
    BufferedStream stream(*c, consumed, Seconds(options_.write_timeout_s), pending_out_,
                          options_.max_inflight_bytes);
    c->view.must_close = false;
    c->view.start = Clock::now();
    c->view.route = "-";
    current_connection = &c->view;
    const bool last = ++c->served >= options_.keep_alive_max || stopping_ || c->close_asked;
    bool closed = false;
    ok = process_request(stream, last, closed, nullptr);
    current_connection = nullptr;
    keep = ok && !closed && !last && !c->view.must_close && !stopping_;
  }
  if (c->out_pos < c->out.size() && ok && !stopping_) {
    // The reactor sends the rest as the client reads, then reads the next request or closes.
    c->close_after_out = !keep;
    c->writing = true;
  }
  if (!keep && !c->writing) return Close(std::move(c));
  // The next request may already be buffered (pipelining).
  ReleaseBytes(c.get(), c->request_end);
  c->buf.erase(0, c->request_end);
  c->head_end = c->request_end = 0;
  c->head_started = false;
  c->chunked = false;
  c->content_length = c->chunk_pos = c->body_bytes = 0;
  c->health = false;
  c->deadline = Clock::now() + Seconds(options_.idle_timeout_s);
  Return(std::move(c));
}

void HttpFront::Reactor() {
  std::map<int, std::unique_ptr<Conn>> conns;
  std::vector<epoll_event> events(64);

  // Answers an error itself and closes the connection after a lingering close: the client
  // may still be sending the request it is refused, and closing with unread bytes would reset
  // the connection and lose the answer, so what it sends is read and dropped for a while.
  // `drain` (and `drain_s`): how much of the request to read and drop, and for how long.
  auto refuse = [&](std::unique_ptr<Conn> c, int status, const std::string& message,
                    size_t drain = 4u << 20, double drain_s = 1.0) {
    const std::string body = render_error_(status, message);
    std::string reply = "HTTP/1.1 " + std::to_string(status) + " " + Reason(status) +
                        "\r\nContent-Type: application/json\r\nX-Content-Type-Options: "
                        "nosniff\r\nConnection: close\r\n";
    if (status == 429) reply += "Retry-After: 1\r\n";
    reply += "Content-Length: " + std::to_string(body.size()) + "\r\n\r\n" + body;
    WriteAll(c->fd, reply.data(), reply.size(), std::chrono::milliseconds(100));
    if (observe_) observe_(status);
    ::shutdown(c->fd, SHUT_WR);
    ReleaseBytes(c.get(), c->accounted);
    c->buf.clear();
    c->buf.shrink_to_fit();
    c->closing = true;
    c->discard = drain;
    c->deadline = Clock::now() + Seconds(drain_s);
    if (!c->registered) {
      epoll_event ev{};
      ev.events = EPOLLIN | EPOLLRDHUP;
      ev.data.fd = c->fd;
      if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, c->fd, &ev) != 0) return Close(std::move(c));
      c->registered = true;
    }
    const int fd = c->fd;
    conns[fd] = std::move(c);
  };

  // Advances a connection's request: 1 complete, 0 waiting for bytes, -1 refused (closed).
  auto advance = [&](std::unique_ptr<Conn>& c) -> int {
    if (c->head_end == 0) {
      // Empty lines before a request line are ignored (RFC 9112 2.2).
      size_t empty = 0;
      while (c->buf.compare(empty, 2, "\r\n") == 0) empty += 2;
      if (empty > 0) {
        ReleaseBytes(c.get(), empty);
        c->buf.erase(0, empty);
      }
      const size_t end = c->buf.find("\r\n\r\n");
      if (end == std::string::npos) {
        if (c->buf.size() > options_.max_head_bytes) {
          refuse(std::move(c), 431,
                 "the request head is larger than " + std::to_string(options_.max_head_bytes) +
                     " bytes");
          return -1;
        }
        return 0;
      }
      if (end + 4 > options_.max_head_bytes) {
        refuse(std::move(c), 431,
               "the request head is larger than " + std::to_string(options_.max_head_bytes) +
                   " bytes");
        return -1;
      }
      if (HasStrayLineBreakOrNul(std::string_view(c->buf).substr(0, end + 2))) {
        refuse(std::move(c), 400, "the request head holds a NUL, or a CR or LF outside a CRLF");
        return -1;
      }
      // Parse the head: request line, then "name: value" lines.
      size_t line_end = c->buf.find("\r\n");
      const std::string request_line = c->buf.substr(0, line_end);
      // httplib answered an unparsable request line with a 400 and kept the connection for a
      // next request that cannot be framed after it (the client waited for the idle timeout).
      if (!WellFormedRequestLine(request_line)) {
        refuse(std::move(c), 400,
               "a malformed request line: expected METHOD TARGET HTTP/1.1, separated by single "
               "spaces");
        return -1;
      }
      // HTTP/1.1 and HTTP/1.0 only (httplib answered others with a bare 400).
      const bool http10 = request_line.ends_with(" HTTP/1.0");
      if (!http10 && !request_line.ends_with(" HTTP/1.1")) {
        refuse(std::move(c), 505, "the HTTP version: only HTTP/1.1 and HTTP/1.0 are served");
        return -1;
      }
      // httplib's own bound on the request line (a bare 414), with a message that says which part.
      if (request_line.size() > kMaxRequestLine) {
        refuse(std::move(c), 414,
               "the request target (path and query) is too long: the request line holds at most " +
                   std::to_string(kMaxRequestLine) + " bytes");
        return -1;
      }
      // Origin form only: httplib takes the query of a target such as "?/v1/..." for its path.
      const std::string_view target = TargetOf(request_line);
      if (!target.starts_with('/')) {
        refuse(std::move(c), 400, "the request target must be a path starting with '/'");
        return -1;
      }
      // httplib decodes the path before routing: an encoded '/' or ':' would reach another route
      // than the one the raw path names (RFC 3986 2.2), past any proxy rule on the raw path.
      if (EncodesSeparator(target)) {
        refuse(std::move(c), 404,
               "no route for a path with an encoded '/' or ':' (%2F, %3A, %u...): send them as "
               "they are");
        return -1;
      }
      std::string content_length, transfer_encoding, authorization;
      bool encoded = false;  // a Content-Encoding other than identity
      bool authorization_seen = false;
      int content_length_count = 0;
      bool expect_continue = false, keep_alive_asked = false;
      c->close_asked = false;
      // Header lines httplib must not see: Expect (answered here) and Range (see below).
      std::vector<std::pair<size_t, size_t>> hidden;
      for (size_t pos = line_end + 2; pos < end + 2;) {
        const size_t next = c->buf.find("\r\n", pos);
        const std::string line = c->buf.substr(pos, next - pos);
        const size_t colon = line.find(':');
        if (line.size() + 2 > kMaxHeaderLine) {  // httplib counts the CRLF
          refuse(std::move(c), 431,
                 "a header line is longer than " + std::to_string(kMaxHeaderLine) + " bytes");
          return -1;
        }
        if (!line.empty() && (line[0] == ' ' || line[0] == '\t')) {
          refuse(std::move(c), 400, "a header line folded onto the next (obsolete line folding)");
          return -1;
        }
        if (colon == std::string::npos || !IsToken(line.substr(0, colon))) {
          refuse(std::move(c), 400,
                 colon == std::string::npos
                     ? "a header line without a colon"
                     : "a header name that is not a token (no spaces before the colon)");
          return -1;
        }
        const std::string name = Lower(line.substr(0, colon));
        const std::string value = Trim(line.substr(colon + 1));
        if (name == "content-length") {
          if (content_length_count++ > 0 && value != content_length) {
            refuse(std::move(c), 400, "conflicting Content-Length headers");
            return -1;
          }
          content_length = value;
        } else if (name == "transfer-encoding") {
          if (!transfer_encoding.empty()) transfer_encoding.push_back(',');
          transfer_encoding.append(Lower(value));
        } else if (name == "authorization" && !authorization_seen && !value.empty()) {
          // As httplib reads it for the server's check: the first non-empty value, decoded.
          authorization = httplib::detail::decode_url(value, false);
          authorization_seen = true;
        } else if (name == "content-encoding") {
          // Every value and every coding in it: httplib inflates by the first header alone, so
          // "gzip" then "identity" would pass a check of the last one. Hidden from httplib too.
          ForEachListItem(value, [&](const std::string& coding) {
            encoded = encoded || (!coding.empty() && coding != "identity");
          });
          hidden.emplace_back(pos, next + 2 - pos);
        } else if (name == "connection") {
          // A list of case-insensitive tokens (RFC 9110 7.6.1); httplib matches "close" alone.
          ForEachListItem(value, [&](const std::string& option) {
            c->close_asked = c->close_asked || option == "close";
            keep_alive_asked = keep_alive_asked || option == "keep-alive";
          });
        } else if (name == "expect" && Lower(value) == "100-continue") {
          expect_continue = true;
          hidden.emplace_back(pos, next + 2 - pos);
        } else if (name == "range") {
          // httplib 0.11.4 cuts every response to the ranges asked for, error bodies included,
          // and answers N ranges with N copies: several ranges are refused, one is ignored
          // (RFC 9110 14.2 allows it) and the whole response sent.
          if (value.find(',') != std::string::npos) {
            refuse(std::move(c), 416, "Range: at most one range, and it is ignored");
            return -1;
          }
          hidden.emplace_back(pos, next + 2 - pos);
        }
        pos = next + 2;
      }
      if (encoded) {
        refuse(std::move(c), 415,
               "Content-Encoding: only 'identity' is accepted; send the body as is");
        return -1;
      }
      if (!transfer_encoding.empty()) {
        if (transfer_encoding != "chunked") {
          refuse(std::move(c), 400, "Transfer-Encoding: only 'chunked' is accepted");
          return -1;
        }
        if (content_length_count > 0) {
          refuse(std::move(c), 400, "both Content-Length and Transfer-Encoding");
          return -1;
        }
        c->chunked = true;
      } else if (content_length_count > 0) {
        if (content_length.empty() || content_length.size() > 18 ||
            content_length.find_first_not_of("0123456789") != std::string::npos) {
          refuse(std::move(c), 400, "a malformed Content-Length");
          return -1;
        }
        c->content_length = std::stoull(content_length);
        if (c->content_length > options_.max_body_bytes) {
          refuse(std::move(c), 413,
                 "the body of " + content_length + " bytes is larger than " +
                     std::to_string(options_.max_body_bytes) + " bytes");
          return -1;
        }
      }
      // A body is read, counted and answered with 100 Continue only for a client with the
      // server's bearer token: without it, clients could hold the in-flight bound unauthenticated.
      if (!options_.body_authorization.empty() && (c->chunked || c->content_length > 0) &&
          !SameSecret(authorization, options_.body_authorization)) {
        // The body it announced is read and dropped, never kept, so that the client (a robot
        // with a mistyped key sending photos) reads the 401 instead of a reset connection.
        const size_t announced = c->chunked ? options_.max_body_bytes + 4096 : c->content_length;
        refuse(std::move(c), 401,
               "missing or wrong bearer token (Authorization header): a request body is read only "
               "from an authenticated client",
               announced, std::max(1.0, options_.head_timeout_s));
        return -1;
      }
      // Requests without Content-Length or Transfer-Encoding have no body (RFC 9112 6.3).
      size_t head_end = end + 4;
      // Not to HTTP/1.0 clients (RFC 9110 15.2), nor for a request without a body.
      if (expect_continue && !http10 && (c->chunked || c->content_length > 0)) {
        // The body is read here: answer the 100 here (httplib never sees the header).
        static const char kContinue[] = "HTTP/1.1 100 Continue\r\n\r\n";
        WriteAll(c->fd, kContinue, sizeof kContinue - 1, std::chrono::milliseconds(100));
      }
      for (auto it = hidden.rbegin(); it != hidden.rend(); ++it) {
        c->buf.erase(it->first, it->second);
        head_end -= it->second;
        ReleaseBytes(c.get(), it->second);  // no longer buffered
      }
      c->head_end = head_end;
      c->chunk_pos = head_end;
      // HTTP/1.0 closes unless the client asked to keep the connection (RFC 9112 9.3).
      if (http10 && !keep_alive_asked) c->close_asked = true;
      const std::string_view method =
          std::string_view(request_line).substr(0, request_line.find(' '));
      const std::string_view path = target.substr(0, target.find('?'));
      c->health =
          (method == "GET" || method == "HEAD") && (path == "/healthz" || path == "/metrics");
      c->deadline = Clock::now() + Seconds(options_.body_timeout_s);
    }
    if (!c->chunked) {
      if (c->buf.size() - c->head_end < c->content_length) return 0;
      c->request_end = c->head_end + c->content_length;
      return 1;
    }
    // Chunked: size line, data, CRLF; a zero size ends the body (no trailers).
    for (;;) {
      const size_t line_end = c->buf.find("\r\n", c->chunk_pos);
      if (line_end == std::string::npos) {
        if (c->buf.size() - c->chunk_pos > 256) {
          refuse(std::move(c), 400, "a malformed chunk size line");
          return -1;
        }
        return 0;
      }
      const std::string line = c->buf.substr(c->chunk_pos, line_end - c->chunk_pos);
      const std::string digits = Trim(line.substr(0, line.find(';')));
      if (digits.empty() || digits.size() > 15 ||
          digits.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos) {
        refuse(std::move(c), 400, "a malformed chunk size");
        return -1;
      }
      const size_t size = std::stoull(digits, nullptr, 16);
      if (size == 0) {
        if (c->buf.size() < line_end + 4) return 0;
        if (c->buf.compare(line_end + 2, 2, "\r\n") != 0) {
          refuse(std::move(c), 400, "chunked trailers are not accepted");
          return -1;
        }
        c->request_end = line_end + 4;
        return 1;
      }
      if (c->body_bytes + size > options_.max_body_bytes) {
        refuse(std::move(c), 413,
               "the chunked body is larger than " + std::to_string(options_.max_body_bytes) +
                   " bytes");
        return -1;
      }
      // Framing may at most double the wire size of the body (no floods of 1-byte chunks).
      if (line_end + 2 - c->head_end > 2 * (c->body_bytes + size) + 4096) {
        refuse(std::move(c), 400, "chunks too small");
        return -1;
      }
      if (c->buf.size() < line_end + 2 + size + 2) return 0;
      if (c->buf.compare(line_end + 2 + size, 2, "\r\n") != 0) {
        refuse(std::move(c), 400, "a chunk without its CRLF");
        return -1;
      }
      c->body_bytes += size;
      c->chunk_pos = line_end + 2 + size + 2;
    }
  };

  auto dispatch = [&](std::unique_ptr<Conn> c) {
    if (c->registered) {
      ::epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c->fd, nullptr);
      c->registered = false;
    }
    Pool* pool = c->health ? health_.get() : workers_.get();
    pool->Push(std::move(c));
  };

  // A connection whose response waits for the client to read: watched for EPOLLOUT until sent
  // (within the write timeout), then closed or read again.
  auto send_rest = [&](std::unique_ptr<Conn> c) -> std::unique_ptr<Conn> {
    const size_t before = c->out_pos;
    if (!FlushOut(c.get())) {
      Close(std::move(c));
      return nullptr;
    }
    if (c->writing) {
      // The write timeout runs between two sends that make progress (nginx's send_timeout).
      if (c->out_pos > before) c->deadline = Clock::now() + Seconds(options_.write_timeout_s);
      epoll_event ev{};
      ev.events = EPOLLOUT;
      ev.data.fd = c->fd;
      if (::epoll_ctl(epoll_fd_, c->registered ? EPOLL_CTL_MOD : EPOLL_CTL_ADD, c->fd, &ev) != 0) {
        Close(std::move(c));
        return nullptr;
      }
      c->registered = true;
      const int fd = c->fd;
      conns[fd] = std::move(c);
      return nullptr;
    }
    if (c->close_after_out) {
      Close(std::move(c));
      return nullptr;
    }
    c->deadline = Clock::now() + Seconds(options_.idle_timeout_s);
    if (c->registered) {  // read again
      epoll_event ev{};
      ev.events = EPOLLIN | EPOLLRDHUP;
      ev.data.fd = c->fd;
      if (::epoll_ctl(epoll_fd_, EPOLL_CTL_MOD, c->fd, &ev) != 0) {
        Close(std::move(c));
        return nullptr;
      }
    }
    return c;
  };

  // A connection's bytes so far: dispatched when complete, kept (and watched) otherwise.
  auto settle = [&](std::unique_ptr<Conn> c) {
    const int state = advance(c);
    if (state < 0) return;
    if (state > 0) {
      conns.erase(c->fd);
      return dispatch(std::move(c));
    }
    if (!c->registered) {
      epoll_event ev{};
      ev.events = EPOLLIN | EPOLLRDHUP;
      ev.data.fd = c->fd;
      if (::epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, c->fd, &ev) != 0) return Close(std::move(c));
      c->registered = true;
    }
    const int fd = c->fd;
    conns[fd] = std::move(c);
  };

  while (!stopping_) {
    auto now = Clock::now();
    Clock::time_point next = now + std::chrono::milliseconds(200);
    for (const auto& [fd, c] : conns) next = std::min(next, c->deadline);
    const int timeout = static_cast<int>(std::max<int64_t>(
        0, std::chrono::duration_cast<std::chrono::milliseconds>(next - now).count() + 1));
    const int n = ::epoll_wait(epoll_fd_, events.data(), static_cast<int>(events.size()), timeout);
    for (int i = 0; i < n; ++i) {
      const int fd = events[i].data.fd;
      if (fd == wake_fd_) {
        uint64_t value;
        while (::read(wake_fd_, &value, sizeof value) > 0) {
        }
        continue;
      }
      auto it = conns.find(fd);
      if (it == conns.end()) continue;
      std::unique_ptr<Conn> c = std::move(it->second);
      conns.erase(it);
      if (c->writing) {
        if (auto ready = send_rest(std::move(c))) settle(std::move(ready));
        continue;
      }
      char chunk[16384];
      if (c->closing) {
        ssize_t got = 0;
        while ((got = ::recv(fd, chunk, sizeof chunk, 0)) > 0 && c->discard > 0) {
          c->discard -= std::min(c->discard, static_cast<size_t>(got));
        }
        const bool again = got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
        if (again && c->discard > 0) {
          conns[fd] = std::move(c);
        } else {
          Close(std::move(c));
        }
        continue;
      }
      bool eof = false, over = false;
      for (;;) {
        const ssize_t got = ::recv(fd, chunk, sizeof chunk, 0);
        if (got > 0) {
          if (inflight_ + static_cast<size_t>(got) > options_.max_inflight_bytes) {
            over = true;
            break;
          }
          c->buf.append(chunk, static_cast<size_t>(got));
          inflight_ += static_cast<size_t>(got);
          c->accounted += static_cast<size_t>(got);
          // Enough to decide: advance() refuses heads and bodies past their limits.
          if (c->head_end == 0 && c->buf.size() > options_.max_head_bytes + sizeof chunk) break;
          if (c->buf.size() > 2 * options_.max_body_bytes + options_.max_head_bytes + 8192) break;
          continue;
        }
        if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
        if (got < 0 && errno == EINTR) continue;
        eof = true;  // end of stream or a reset
        break;
      }
      if (over) {
        refuse(std::move(c), 429, "too many request bytes in flight; retry later");
        continue;
      }
      if (c->head_end == 0) {
        if (c->buf.find_first_not_of("\r\n") == std::string::npos) {
          ReleaseBytes(c.get(), c->buf.size());
          c->buf.clear();  // nothing of a request yet: the connection stays idle
        } else if (!c->head_started) {
          c->head_started = true;
          c->deadline = Clock::now() + Seconds(options_.head_timeout_s);
        }
      }
      if (eof) {
        // A client that closed its side after a complete request still gets the answer.
        if (advance(c) > 0) {
          dispatch(std::move(c));
        } else if (c) {
          Close(std::move(c));
        }
        continue;
      }
      settle(std::move(c));
    }
    // New and returning connections.
    std::vector<std::unique_ptr<Conn>> incoming;
    {
      std::lock_guard<std::mutex> lock(incoming_mutex_);
      incoming.swap(incoming_);
    }
    for (auto& c : incoming) {
      if (c->writing) {
        c->deadline = Clock::now() + Seconds(options_.write_timeout_s);
        c = send_rest(std::move(c));
        if (!c) continue;
      }
      if (c->buf.find_first_not_of("\r\n") == std::string::npos) {
        ReleaseBytes(c.get(), c->buf.size());
        c->buf.clear();
      } else if (!c->head_started) {
        c->head_started = true;
        c->deadline = Clock::now() + Seconds(options_.head_timeout_s);
      }
      settle(std::move(c));
    }
    // Deadlines: an idle connection closes quietly, a slow request gets 408.
    now = Clock::now();
    for (auto it = conns.begin(); it != conns.end();) {
      if (it->second->deadline > now) {
        ++it;
        continue;
      }
      std::unique_ptr<Conn> c = std::move(it->second);
      it = conns.erase(it);
      if (c->buf.empty() || c->closing || c->writing) {
        Close(std::move(c));
      } else {
        refuse(std::move(c), 408,
               c->head_end == 0 ? "the request head did not arrive in time"
                                : "the request body did not arrive in time");
      }
    }
  }
  for (auto& [fd, c] : conns) Close(std::move(c));
}

}  // namespace npfkct::server
