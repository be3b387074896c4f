// The HTTP front of npfkct-server: cpp-httplib (Debian's 0.11.4) parses requests and routes them,
// but connections are served by this front instead of httplib's one-thread-per-connection loop.
//
// An epoll reactor owns every connection while it is idle or still sending its request: it reads
// the request head and the whole body (Content-Length or chunked, counted against the body limit
// as it streams in) with deadlines for the head, the body and keep-alive idleness, answers
// `Expect: 100-continue`, and refuses what httplib 0.11.4 would let through (a body past the
// limit in any framing, compressed bodies, Content-Length with Transfer-Encoding, any other
// transfer coding). Only complete requests reach a worker thread, and a response the socket
// does not take at once goes back to the reactor to be sent as the client reads it, so slow or
// idle clients, sending or reading, hold a file descriptor, never a thread. GET /healthz and GET
// /metrics go to their own workers, which nothing else can occupy. While a handler runs, Current()
// gives its connection, so a long handler can notice that the client went away (ClientGone()).
#pragma once

#include <httplib.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

namespace npfkct::server {

/// Settings of the front.
struct HttpFrontOptions {
  int workers = 16;                  ///< Threads running request handlers.
  int health_workers = 2;            ///< Threads serving only GET /healthz and GET /metrics.
  int max_connections = 512;         ///< Open connections; more are refused (429).
  double head_timeout_s = 10.0;      ///< From the first byte of a request to the end of its head.
  double body_timeout_s = 60.0;      ///< From the end of the head to the end of the body.
  double idle_timeout_s = 5.0;       ///< Keep-alive: between requests on one connection.
  double write_timeout_s = 10.0;     ///< Sending a response.
  size_t max_head_bytes = 16384;     ///< Request line and headers.
  size_t max_body_bytes = 32 << 20;  ///< Request body, in any framing.
  /// Request bytes buffered across all connections (read but not yet answered); a request that
  /// would go past it is refused (429). Response bytes waiting for slow readers have a bound of
  /// the same size of their own: within it a worker hands what the socket does not take to the
  /// reactor and goes on; past it the worker waits for the socket (up to write_timeout_s).
  size_t max_inflight_bytes = 128 << 20;
  int keep_alive_max = 100;  ///< Requests per connection.
  /// When set, the whole Authorization header a request with a body must carry ("Bearer KEY"):
  /// the body of any other is neither read nor counted, and the request is refused (401).
  std::string body_authorization;
};

/// Whether two secrets are equal, in a time that depends on their lengths only (a comparison that
/// stops at the first difference tells a timing client how much of its guess was right).
bool SameSecret(std::string_view a, std::string_view b);

/// One client connection, as a handler sees it.
struct Connection {
  int fd = -1;
  /// Set by a handler when the connection must close after its response.
  bool must_close = false;
  /// When the current request started being served, and its route's name (set by the server's
  /// routing, for metrics).
  std::chrono::steady_clock::time_point start;
  const char* route = "-";
};

/// The front. Configure handlers on it as on any httplib::Server, then Start(), bind and
/// listen_after_bind(); Shutdown() before destruction.
class HttpFront : public httplib::Server {
 public:
  /// Renders the body of an error the front answers itself (408, 413, 415, 429, 431, 400).
  using ErrorRenderer = std::function<std::string(int http_status, const std::string& message)>;
  /// Called for every response the front writes itself (status code), for metrics.
  using FrontResponseObserver = std::function<void(int http_status)>;

  HttpFront(HttpFrontOptions options, ErrorRenderer render_error, FrontResponseObserver observe);
  ~HttpFront() override;

  /// Starts the reactor and the worker threads, and widens the bound socket's listen backlog.
  void Start();
  /// Stops accepting, closes every connection the reactor holds and joins the threads (after
  /// httplib's stop()).
  void Shutdown();

  /// The connection the calling worker thread is serving; null outside a handler.
  static Connection* Current();
  /// Whether the client of the current connection closed or reset it (false outside a handler).
  static bool ClientGone();
  /// Whether the client of `connection` (Current() of a handler) closed or reset it; any thread
  /// may ask while the handler runs (e.g. a plan's search threads).
  static bool ClientGone(const Connection* connection);
  /// Connections accepted and not closed yet (those refused at the limit never count).
  int open_connections() const { return open_connections_.load(); }
  /// Request bytes buffered across all connections (read but not yet answered).
  size_t inflight_bytes() const { return inflight_.load(); }

  struct Conn;  // a connection and its buffered bytes (http_front.cc)

 private:
  bool process_and_close_socket(socket_t sock) override;
  void Reactor();
  void Serve(std::unique_ptr<Conn> conn);
  void Return(std::unique_ptr<Conn> conn);
  void Close(std::unique_ptr<Conn> conn);
  void ReleaseBytes(Conn* conn, size_t n);
  // Sends what the connection's pending response the socket takes now; false on an error.
  bool FlushOut(Conn* conn);
  void Wake();

  class Pool;
  HttpFrontOptions options_;
  ErrorRenderer render_error_;
  FrontResponseObserver observe_;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;
  std::atomic<bool> stopping_{false};
  std::atomic<int> open_connections_{0};
  std::atomic<size_t> inflight_{0};
  std::atomic<size_t> pending_out_{0};  // response bytes the reactor still has to send
  std::mutex incoming_mutex_;
  std::vector<std::unique_ptr<Conn>> incoming_;
  std::thread reactor_;
  std::unique_ptr<Pool> workers_;
  std::unique_ptr<Pool> health_;
};

}  // namespace npfkct::server
