// The HTTP front of npfkct-server: it accepts connections, frames and reads each request once into
// a typed HttpRequest (http_message.h), hands complete requests to a handler on a worker thread,
// and writes the typed HttpResponse the handler returns.
//
// An epoll reactor owns every connection while it is idle or still sending its request: it reads
// the request head and the whole body (Content-Length or chunked, counted against the body limit
// as it streams in) with deadlines for the head, the body and keep-alive idleness, answers
// `Expect: 100-continue`, and refuses what it cannot frame without doubt (a body past the limit
// in any framing, compressed bodies, Content-Length with Transfer-Encoding, any other transfer
// coding, obsolete line folding, stray CR, LF or NUL). Only complete requests reach a worker
// thread, and a response the socket does not take at once goes back to the reactor to be sent as
// the client reads it, so slow or idle clients, sending or reading, hold a file descriptor, never
// a thread. GET /healthz and GET /metrics go to their own workers, which nothing else can occupy.
// While a handler runs, Current() gives its connection, so a long handler can notice that the
// client went away (ClientGone()).
//
// The framing and the reading of a head are the front's own, bounded as it reads, not a parser
// library's: Debian 12's libhttp-parser (nodejs/http-parser 2.9.4) has been unmaintained since
// 2020 (its successor, llhttp, is not packaged), and it takes what the front refuses (bare LF
// line ends, folded header lines, chunk trailers; an 80 KiB head), so every refusal would have
// needed a second reading of the head beside it.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "http_message.h"

namespace npfkct::server {

/// Settings of the front.
struct HttpFrontOptions {
  int workers = 16;        ///< Threads running request handlers.
  int health_workers = 2;  ///< Threads serving only GET /healthz and GET /metrics.
  /// Open connections. A newcomer past it closes an idle, lingering or head-sending connection
  /// that never carried the bearer token (oldest first), and is refused (429) only when every
  /// connection is authenticated or busy with a request.
  int max_connections = 512;
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
  /// Set by a handler when the connection must close after its response (which then says
  /// `Connection: close`).
  bool must_close = false;
};

/// How a request's body is framed and what its head asks of the connection, as read from it.
struct RequestFraming {
  bool chunked = false;
  size_t content_length = 0;  ///< Without chunking; 0 also when there is no body.
  bool expect_continue = false;
  bool close = false;  ///< Close after the response (asked, or HTTP/1.0 without keep-alive).
  bool has_body() const { return chunked || content_length > 0; }
};

/// A request head the front answers itself: the status and the message of its error body.
struct HeadRefusal {
  int status = 0;  ///< 0: not refused.
  std::string message;
};

/// Reads a complete request head (`head`: the request line and header lines, each ending in CRLF,
/// without the blank line) into `request` (all but its body) and `framing`; a refusal when the
/// front must answer it itself (malformed lines, an unsupported version or coding, a target the
/// routes cannot serve, a body past `max_body_bytes`). Every header line is read once, here.
HeadRefusal ReadRequestHead(std::string_view head, size_t max_body_bytes, HttpRequest* request,
                            RequestFraming* framing);

/// The front. Bind(), then Start(); Shutdown() before destruction.
class HttpFront {
 public:
  /// Answers a complete request (on a worker thread, Current() set).
  using Handler = std::function<HttpResponse(const HttpRequest& request)>;
  /// Renders the body of an error the front answers itself (408, 413, 415, 429, 431, 400).
  using ErrorRenderer = std::function<std::string(int http_status, const std::string& message)>;
  /// Called for every response the front writes itself (status code), for metrics.
  using FrontResponseObserver = std::function<void(int http_status)>;

  HttpFront(HttpFrontOptions options, Handler handler, ErrorRenderer render_error,
            FrontResponseObserver observe);
  ~HttpFront();
  HttpFront(const HttpFront&) = delete;
  HttpFront& operator=(const HttpFront&) = delete;

  /// Binds and listens on `host` (a name or an address) and `port` (0: any free port); the port
  /// bound, or -1.
  int Bind(const std::string& host, int port);
  /// Starts the reactor (which accepts connections) and the worker threads. Throws
  /// std::system_error when a thread cannot be started.
  void Start();
  /// Stops accepting, closes every connection and joins the threads.
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
  class Pool;
  class Reactor;

  // Takes a new connection (from accept), or refuses it past the connection limit.
  void Admit(int fd);
  void Serve(std::unique_ptr<Conn> conn);
  // Writes a response: what the socket does not take goes to the connection's pending output.
  bool Send(Conn* conn, const char* data, size_t size);
  void Return(std::unique_ptr<Conn> conn);
  void Close(std::unique_ptr<Conn> conn);
  void ReleaseBytes(Conn* conn, size_t n);
  // Sends what the connection's pending response the socket takes now; false on an error.
  bool FlushOut(Conn* conn);
  // Counts `n` more bytes in the front's pending output, unless that would pass its bound.
  bool Reserve(Conn* conn, size_t n);
  void Wake();

  HttpFrontOptions options_;
  Handler handler_;
  ErrorRenderer render_error_;
  FrontResponseObserver observe_;
  int listen_fd_ = -1;
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
