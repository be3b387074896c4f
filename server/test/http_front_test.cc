// The HTTP front over raw sockets: bodies in every framing against the limit, refused encodings,
// deadlines for slow clients, health that slow clients cannot starve, pipelining, hang-ups; and
// its one reading of a request head, without a socket (ReadRequestHead).
#include "http_front.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

namespace npfkct::server {
namespace {

using Clock = std::chrono::steady_clock;

double Since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

class HttpFrontTest : public ::testing::Test {
 protected:
  void Start(HttpFrontOptions o) {
    front_ = std::make_unique<HttpFront>(
        o, [this](const HttpRequest& req) { return Handle(req); },
        [](int code, const std::string& m) { return std::to_string(code) + " " + m; },
        [this](int code) { front_codes_.push_back(code); });
    port_ = front_->Bind("127.0.0.1", 0);
    ASSERT_GT(port_, 0);
    front_->Start();
  }
  // The routes of the tests: GET /healthz, POST /echo (the body's size and start), GET /wait.
  HttpResponse Handle(const HttpRequest& req) {
    HttpResponse res;
    const bool get = req.method == "GET" || req.method == "HEAD";
    if (get && req.path == "/healthz") {
      res.SetContent("ok", "text/plain");
    } else if (req.method == "POST" && req.path == "/echo") {
      res.SetContent(std::to_string(req.body.size()) + ":" + req.body.substr(0, 16), "text/plain");
    } else if (get && req.path == "/wait") {
      // A long handler that notices its client hanging up.
      const auto t0 = Clock::now();
      while (!HttpFront::ClientGone() && Since(t0) < 5.0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      gone_after_ = Since(t0);
      res.SetContent("done", "text/plain");
    } else {
      res.status = 404;
    }
    return res;
  }
  void TearDown() override {
    if (front_) front_->Shutdown();
  }
  int Connect() {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port_));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    timeval tv{5, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return fd;
  }
  static void Send(int fd, const std::string& s) {
    ASSERT_EQ(::send(fd, s.data(), s.size(), MSG_NOSIGNAL), static_cast<ssize_t>(s.size()));
  }
  // Reads until the peer closes or `until` appears.
  static std::string Read(int fd, const std::string& until = "") {
    std::string out;
    char buf[4096];
    for (;;) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) break;
      out.append(buf, static_cast<size_t>(n));
      if (!until.empty() && out.find(until) != std::string::npos) break;
    }
    return out;
  }
  // One request on a fresh connection; the whole answer.
  std::string Exchange(const std::string& request) {
    const int fd = Connect();
    Send(fd, request);
    std::string reply = Read(fd);
    ::close(fd);
    return reply;
  }

  std::unique_ptr<HttpFront> front_;
  int port_ = 0;
  std::vector<int> front_codes_;
  std::atomic<double> gone_after_{-1.0};
};

TEST_F(HttpFrontTest, BodiesInEveryFramingAreCountedAgainstTheLimit) {
  HttpFrontOptions o;
  o.max_body_bytes = 1000;
  Start(o);
  EXPECT_NE(Exchange("POST /echo HTTP/1.1\r\nContent-Length: 5\r\nConnection: close\r\n\r\nhello")
                .find("5:hello"),
            std::string::npos);
  // Chunked within the limit is delivered whole.
  EXPECT_NE(Exchange("POST /echo HTTP/1.1\r\nTransfer-Encoding: chunked\r\nConnection: close\r\n"
                     "\r\n5\r\nhello\r\n6\r\n world\r\n0\r\n\r\n")
                .find("11:hello world"),
            std::string::npos);
  // A declared length past the limit: 413 before a byte of the body is read.
  EXPECT_EQ(Exchange("POST /echo HTTP/1.1\r\nContent-Length: 2147483648\r\n\r\n")
                .rfind("HTTP/1.1 413", 0),
            0u);
  // Chunked past the limit: 413 as soon as the count passes it (the rest is never read).
  const int fd = Connect();
  Send(fd, "POST /echo HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n");
  for (int i = 0; i < 3; ++i) Send(fd, "200\r\n" + std::string(512, 'x') + "\r\n");
  EXPECT_EQ(Read(fd).rfind("HTTP/1.1 413", 0), 0u);
  ::close(fd);
  // Floods of tiny chunks (framing many times the payload) are refused.
  std::string tiny = "POST /echo HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n";
  for (int i = 0; i < 2000; ++i) tiny += "1;padpadpadpadpadpad\r\nx\r\n";
  EXPECT_EQ(Exchange(tiny).rfind("HTTP/1.1 4", 0), 0u);
  // Compressed bodies, ambiguous framing and other codings are refused.
  EXPECT_EQ(
      Exchange("POST /echo HTTP/1.1\r\nContent-Encoding: gzip\r\nContent-Length: 3\r\n\r\nabc")
          .rfind("HTTP/1.1 415", 0),
      0u);
  EXPECT_EQ(
      Exchange("POST /echo HTTP/1.1\r\nContent-Length: 3\r\nTransfer-Encoding: chunked\r\n\r\n")
          .rfind("HTTP/1.1 400", 0),
      0u);
  EXPECT_EQ(Exchange("POST /echo HTTP/1.1\r\nTransfer-Encoding: gzip, chunked\r\n\r\n")
                .rfind("HTTP/1.1 400", 0),
            0u);
  EXPECT_EQ(Exchange("POST /echo HTTP/1.1\r\nContent-Length: 3\r\nContent-Length: 4\r\n\r\nabcd")
                .rfind("HTTP/1.1 400", 0),
            0u);
  // No length and no chunking: no body (not "read until the connection closes").
  const auto t0 = Clock::now();
  const int open = Connect();
  Send(open, "POST /echo HTTP/1.1\r\n\r\n");
  EXPECT_NE(Read(open, "0:").find("0:"), std::string::npos);
  EXPECT_LT(Since(t0), 1.0);
  ::close(open);
}

TEST_F(HttpFrontTest, SlowClientsHoldNoThreadAndHealthAnswersThroughout) {
  HttpFrontOptions o;
  o.workers = 2;
  o.head_timeout_s = 1.5;
  Start(o);
  // 64 slow clients (more than every thread of the front), one byte of a head every 100 ms.
  std::vector<int> slow;
  for (int i = 0; i < 64; ++i) {
    slow.push_back(Connect());
    Send(slow.back(), "G");
  }
  double worst = 0.0;
  const auto t0 = Clock::now();
  while (Since(t0) < 1.0) {
    for (int fd : slow) ::send(fd, "E", 1, MSG_NOSIGNAL);
    const auto t1 = Clock::now();
    const std::string reply = Exchange("GET /healthz HTTP/1.1\r\nConnection: close\r\n\r\n");
    worst = std::max(worst, Since(t1));
    EXPECT_NE(reply.find("ok"), std::string::npos);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_LT(worst, 0.1);
  // The head deadline passes: each slow client gets 408 and is closed.
  for (int fd : slow) {
    EXPECT_EQ(Read(fd).rfind("HTTP/1.1 408", 0), 0u);
    ::close(fd);
  }
}

TEST_F(HttpFrontTest, HeadsTooLargeKeepAliveAndPipelining) {
  HttpFrontOptions o;
  o.max_head_bytes = 2048;
  Start(o);
  EXPECT_EQ(Exchange("GET /healthz HTTP/1.1\r\nX: " + std::string(4000, 'a') + "\r\n\r\n")
                .rfind("HTTP/1.1 431", 0),
            0u);
  // Two requests in one write on one connection: both answered, in order.
  const int fd = Connect();
  Send(fd,
       "POST /echo HTTP/1.1\r\nContent-Length: 3\r\n\r\nabc"
       "POST /echo HTTP/1.1\r\nContent-Length: 2\r\nConnection: close\r\n\r\nde");
  const std::string both = Read(fd);
  EXPECT_NE(both.find("3:abc"), std::string::npos);
  EXPECT_NE(both.find("2:de"), std::string::npos);
  EXPECT_LT(both.find("3:abc"), both.find("2:de"));
  ::close(fd);
  // Expect: 100-continue is answered before the body is sent.
  const int e = Connect();
  Send(e,
       "POST /echo HTTP/1.1\r\nContent-Length: 4\r\nExpect: 100-continue\r\nConnection: close"
       "\r\n\r\n");
  EXPECT_EQ(Read(e, "\r\n\r\n").rfind("HTTP/1.1 100", 0), 0u);
  Send(e, "wxyz");
  EXPECT_NE(Read(e).find("4:wxyz"), std::string::npos);
  ::close(e);
}

TEST_F(HttpFrontTest, AMalformedRequestLineIsAnsweredAndTheConnectionClosed) {
  // httplib answered these with a 400 and kept the connection open until its idle timeout (5 s
  // of the client's wait for a close): nothing after an unparsable request line can be framed.
  Start(HttpFrontOptions{});
  for (const std::string& line :
       {std::string("GARBAGE"), std::string("GET /healthz HTTP/1.1 extra"),
        std::string("GET  /healthz HTTP/1.1"), std::string("GET /healthz"),
        std::string("GET /healthz HTTX/1.1"), std::string("G@T /healthz HTTP/1.1")}) {
    const auto t0 = Clock::now();
    const std::string reply = Exchange(line + "\r\nHost: localhost\r\n\r\n");
    EXPECT_EQ(reply.rfind("HTTP/1.1 400", 0), 0u) << line << ": " << reply;
    EXPECT_NE(reply.find("Connection: close"), std::string::npos) << line;
    EXPECT_NE(reply.find("malformed request line"), std::string::npos) << line;
    EXPECT_LT(Since(t0), 2.0) << line;
  }
  // Well-formed lines, an unknown method and HTTP/1.0 included, reach the routes.
  EXPECT_EQ(Exchange("GET /healthz HTTP/1.0\r\n\r\n").rfind("HTTP/1.1 200", 0), 0u);
  EXPECT_EQ(Exchange("BREW /healthz HTTP/1.1\r\nConnection: close\r\n\r\n").find("malformed"),
            std::string::npos);
}

TEST_F(HttpFrontTest, VersionsTargetsAndEncodedSeparatorsTheRoutesCannotServeAreNamed) {
  // httplib answered these with a bare "HTTP 400" or "HTTP 414", or decoded %2F and %3A before
  // routing, so that /v1/sessions/ID%2Fsteps reached the steps route.
  Start(HttpFrontOptions{});
  std::string reply = Exchange("GET /healthz HTTP/2.0\r\n\r\n");
  EXPECT_EQ(reply.rfind("HTTP/1.1 505", 0), 0u) << reply;
  EXPECT_NE(reply.find("HTTP version"), std::string::npos) << reply;
  reply = Exchange("GET /healthz?q=" + std::string(9000, 'a') + " HTTP/1.1\r\n\r\n");
  EXPECT_EQ(reply.rfind("HTTP/1.1 414", 0), 0u) << reply.substr(0, 200);
  EXPECT_NE(reply.find("request target"), std::string::npos) << reply.substr(0, 200);
  for (const char* path :
       {"/x%2Fhealthz", "/x%2fhealthz", "/v1/sessions/ab%3Aplan", "/x%u002Fhealthz", "/x%U003a"}) {
    reply = Exchange(std::string("GET ") + path + "?a=%2F HTTP/1.1\r\n\r\n");
    EXPECT_EQ(reply.rfind("HTTP/1.1 404", 0), 0u) << path << ": " << reply;
    EXPECT_NE(reply.find("encoded '/' or ':'"), std::string::npos) << reply;
  }
  // A target that is not a path: httplib took the query of "?/healthz" for its path.
  reply = Exchange("GET ?/x%2Fhealthz HTTP/1.1\r\n\r\n");
  EXPECT_EQ(reply.rfind("HTTP/1.1 400", 0), 0u) << reply;
  EXPECT_NE(reply.find("starting with '/'"), std::string::npos) << reply;
  // An encoded separator in the query, and other encodings in the path, are routed as before.
  EXPECT_EQ(Exchange("GET /healthz?a=%2F%3A HTTP/1.1\r\nConnection: close\r\n\r\n")
                .rfind("HTTP/1.1 200", 0),
            0u);
  EXPECT_EQ(
      Exchange("GET /health%7A HTTP/1.1\r\nConnection: close\r\n\r\n").rfind("HTTP/1.1 200", 0),
      0u);
}

TEST_F(HttpFrontTest, HeaderLinesTheFrontRemovesAreNoLongerCountedInFlight) {
  // Range and Expect lines were cut from the buffer before httplib read it, and stayed counted
  // in the in-flight total until their connection closed. Every byte of a request is released
  // once it is answered.
  HttpFrontOptions o;
  o.idle_timeout_s = 30.0;  // the connection stays open throughout
  Start(o);
  const int fd = Connect();
  const std::string range = "Range: bytes=0-" + std::string(8000, '1') + "\r\n";
  for (int i = 0; i < 20; ++i) {
    Send(fd, "GET /healthz HTTP/1.1\r\n" + range + range + "\r\n");
    ASSERT_NE(Read(fd, "ok").find("200"), std::string::npos) << i;
  }
  Send(fd,
       "POST /echo HTTP/1.1\r\nContent-Length: 3\r\nExpect: 100-continue\r\n" + range + "\r\nabc");
  EXPECT_NE(Read(fd, "3:abc").find("3:abc"), std::string::npos);
  // Nothing is buffered now that every request is answered (the reactor may lag a little).
  const auto deadline = Clock::now() + std::chrono::seconds(3);
  while (front_->inflight_bytes() > 0 && Clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_EQ(front_->inflight_bytes(), 0u);
  ::close(fd);
}

TEST_F(HttpFrontTest, ABodyIsReadOnlyFromAClientWithTheBearerToken) {
  // With a key, keyless clients held the in-flight bound with bodies read before the key check.
  HttpFrontOptions o;
  o.max_body_bytes = 100'000;
  o.max_inflight_bytes = 150'000;
  o.body_authorization = "Bearer k3y";
  Start(o);
  const int keyless = Connect();
  Send(keyless, "POST /echo HTTP/1.1\r\nContent-Length: 100000\r\nExpect: 100-continue\r\n\r\n");
  std::string reply = Read(keyless);
  EXPECT_EQ(reply.rfind("HTTP/1.1 401", 0), 0u) << reply;  // no 100 Continue first
  EXPECT_NE(reply.find("bearer token"), std::string::npos) << reply;
  ::close(keyless);
  reply = Exchange(
      "POST /echo HTTP/1.1\r\nAuthorization: Bearer k3z\r\nTransfer-Encoding: "
      "chunked\r\n\r\n3\r\nabc\r\n0\r\n\r\n");
  EXPECT_EQ(reply.rfind("HTTP/1.1 401", 0), 0u) << reply;
  // The token as the routes read it (as httplib did): the first non-empty value, percent-decoded.
  reply = Exchange(
      "POST /echo HTTP/1.1\r\nAuthorization:\r\nAuthorization: Bearer k%33y\r\n"
      "Content-Length: 3\r\nConnection: close\r\n\r\nabc");
  EXPECT_NE(reply.find("3:abc"), std::string::npos) << reply;
  // With the token the body is read; requests without a body are the routes' to judge.
  reply = Exchange(
      "POST /echo HTTP/1.1\r\nAuthorization: Bearer k3y\r\nContent-Length: 3\r\n"
      "Connection: close\r\n\r\nabc");
  EXPECT_NE(reply.find("3:abc"), std::string::npos) << reply;
  EXPECT_EQ(Exchange("GET /healthz HTTP/1.1\r\nConnection: close\r\n\r\n").rfind("HTTP/1.1 200", 0),
            0u);
}

TEST_F(HttpFrontTest, AKeylessClientSendingALargeBodyReadsTheRefusal) {
  // The refusal's lingering close dropped 4 MiB, then reset the connection: a robot with a
  // mistyped key sending 24 MB of photos saw a broken pipe, not the 401.
  HttpFrontOptions o;
  o.max_body_bytes = 32 << 20;
  o.body_authorization = "Bearer k3y";
  Start(o);
  const int fd = Connect();
  const std::string chunk(64 << 10, 'x');
  Send(fd,
       "POST /echo HTTP/1.1\r\nContent-Length: " + std::to_string(384 * chunk.size()) + "\r\n\r\n");
  bool sent = true;
  for (int i = 0; i < 384 && sent; ++i) {
    sent =
        ::send(fd, chunk.data(), chunk.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(chunk.size());
  }
  EXPECT_TRUE(sent);
  const std::string reply = Read(fd);
  EXPECT_EQ(reply.rfind("HTTP/1.1 401", 0), 0u) << reply.substr(0, 200);
  ::close(fd);
}

TEST_F(HttpFrontTest, ContinueOnlyForHttp11RequestsWithABodyAndHeaderLinesAsHttplibCounts) {
  Start(HttpFrontOptions{});
  // RFC 9110 15.2: no 1xx to an HTTP/1.0 client; and none for a request without a body.
  std::string reply = Exchange(
      "POST /echo HTTP/1.0\r\nContent-Length: 3\r\n"
      "Expect: 100-continue\r\n\r\nabc");
  EXPECT_EQ(reply.find("100 Continue"), std::string::npos) << reply;
  EXPECT_NE(reply.find("3:abc"), std::string::npos) << reply;
  reply = Exchange("GET /healthz HTTP/1.1\r\nExpect: 100-continue\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(reply.rfind("HTTP/1.1 200", 0), 0u) << reply;
  reply = Exchange(
      "POST /echo HTTP/1.1\r\nContent-Length: 3\r\nExpect: 100-continue\r\n"
      "Connection: close\r\n\r\nabc");
  EXPECT_EQ(reply.rfind("HTTP/1.1 100 Continue", 0), 0u) << reply;
  // httplib's header line bound counts the CRLF: 8,191 bytes and more are the front's 431.
  for (size_t size : {8190u, 8191u}) {
    const std::string line = "X-Pad: " + std::string(size - 7, 'p');
    reply = Exchange("GET /healthz HTTP/1.1\r\n" + line + "\r\nConnection: close\r\n\r\n");
    EXPECT_EQ(reply.rfind(size == 8190 ? "HTTP/1.1 200" : "HTTP/1.1 431", 0), 0u)
        << size << ": " << reply.substr(0, 120);
  }
}

TEST_F(HttpFrontTest, AHandlerSeesItsClientHangUp) {
  Start(HttpFrontOptions());
  const int fd = Connect();
  Send(fd, "GET /wait HTTP/1.1\r\n\r\n");
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const auto t0 = Clock::now();
  ::close(fd);
  while (gone_after_ < 0 && Since(t0) < 5.0) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_GT(gone_after_, 0.15);
  EXPECT_LT(Since(t0), 0.05);
}

TEST_F(HttpFrontTest, BytesInFlightAndConnectionsAreBounded) {
  HttpFrontOptions o;
  o.max_body_bytes = 100'000;
  o.max_inflight_bytes = 150'000;
  o.max_connections = 8;
  Start(o);
  // Two incomplete bodies of 90 kB each cannot both be buffered.
  const int a = Connect(), b = Connect();
  Send(a, "POST /echo HTTP/1.1\r\nContent-Length: 100000\r\n\r\n" + std::string(90'000, 'a'));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  Send(b, "POST /echo HTTP/1.1\r\nContent-Length: 100000\r\n\r\n" + std::string(90'000, 'b'));
  EXPECT_EQ(Read(b).rfind("HTTP/1.1 429", 0), 0u);
  ::close(b);
  Send(a, std::string(10'000, 'a'));
  EXPECT_NE(Read(a, "100000:").find("100000:aaaa"), std::string::npos);
  ::close(a);
  // Past the connection limit a newcomer takes the place of the oldest idle connection. First
  // the reactor must have seen a and b close (under load it may lag, and the limit would then
  // count them).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (front_->open_connections() > 0 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  ASSERT_EQ(front_->open_connections(), 0);
  std::vector<int> many;
  for (int i = 0; i < 8; ++i) {
    many.push_back(Connect());
    while (front_->open_connections() < i + 1 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  ASSERT_EQ(front_->open_connections(), 8);
  const int extra = Connect();
  Send(extra, "GET /healthz HTTP/1.1\r\nConnection: close\r\n\r\n");
  EXPECT_EQ(Read(extra).rfind("HTTP/1.1 200", 0), 0u);
  ::close(extra);
  EXPECT_EQ(Read(many[0]), "");  // the oldest, closed without a word
  for (int fd : many) ::close(fd);
}

TEST_F(HttpFrontTest, ANewcomerIsRefusedOnlyWhenEveryConnectionCarriedTheToken) {
  HttpFrontOptions o;
  o.max_connections = 6;
  o.body_authorization = "Bearer k";
  Start(o);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  // Six clients with the token, each served once and kept alive.
  std::vector<int> trusted;
  for (int i = 0; i < 6; ++i) {
    trusted.push_back(Connect());
    Send(trusted.back(), "GET /healthz HTTP/1.1\r\nAuthorization: Bearer k\r\n\r\n");
    EXPECT_NE(Read(trusted.back(), "ok").find("ok"), std::string::npos);
  }
  while (front_->open_connections() < 6 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const int extra = Connect();
  EXPECT_EQ(Read(extra).rfind("HTTP/1.1 429", 0), 0u);
  ::close(extra);
  // They are all still served.
  for (int fd : trusted) {
    Send(fd, "GET /healthz HTTP/1.1\r\nAuthorization: Bearer k\r\n\r\n");
    EXPECT_NE(Read(fd, "ok").find("ok"), std::string::npos);
    ::close(fd);
  }
}

// The head of a request: its lines, each with its CRLF (no blank line).
HeadRefusal ReadHead(const std::string& head, HttpRequest* req, RequestFraming* framing,
                     size_t max_body = 1000) {
  return ReadRequestHead(head, max_body, req, framing);
}

TEST(ReadRequestHead, FillsTheRequestOnce) {
  HttpRequest req;
  RequestFraming framing;
  const HeadRefusal r = ReadHead(
      "POST /v1/sessions/abc:plan?x=%31 HTTP/1.1\r\nHost: h\r\nauthorization: Bearer k%33y  \r\n"
      "Authorization: second\r\nX-Empty:\r\nContent-Length: 12\r\nConnection: Keep-Alive, "
      "CLOSE\r\nExpect: 100-continue\r\n",
      &req, &framing);
  ASSERT_EQ(r.status, 0) << r.message;
  EXPECT_EQ(req.method, "POST");
  EXPECT_EQ(req.target, "/v1/sessions/abc:plan?x=%31");
  EXPECT_EQ(req.version, "HTTP/1.1");
  EXPECT_EQ(req.path, "/v1/sessions/abc:plan");
  EXPECT_EQ(req.Param("x"), "1");
  EXPECT_EQ(req.Header("Authorization"), "Bearer k3y");  // the first, trimmed and decoded
  EXPECT_FALSE(req.HasHeader("X-Empty"));
  EXPECT_FALSE(framing.chunked);
  EXPECT_EQ(framing.content_length, 12u);
  EXPECT_TRUE(framing.close);
  EXPECT_TRUE(framing.expect_continue);

  HttpRequest old;
  RequestFraming old_framing;
  ASSERT_EQ(ReadHead("GET / HTTP/1.0\r\nTransfer-Encoding: Chunked\r\n", &old, &old_framing).status,
            0);
  EXPECT_TRUE(old_framing.chunked);
  EXPECT_TRUE(old_framing.close);  // HTTP/1.0 without keep-alive
  HttpRequest kept;
  RequestFraming kept_framing;
  ASSERT_EQ(ReadHead("GET / HTTP/1.0\r\nConnection: keep-alive\r\n", &kept, &kept_framing).status,
            0);
  EXPECT_FALSE(kept_framing.close);
}

TEST(ReadRequestHead, RefusesWhatItCannotFrameWithoutDoubt) {
  const std::pair<std::string, int> refused[] = {
      {"GET / HTTP/1.1\r\nX: a\nb\r\n", 400},                   // a bare LF
      {"GET / HTTP/1.1\r\nX: a\rb\r\n", 400},                   // a bare CR
      {std::string("GET / HTTP/1.1\r\nX: a\0b\r\n", 25), 400},  // a NUL
      {"GET  / HTTP/1.1\r\n", 400},
      {"G@T / HTTP/1.1\r\n", 400},
      {"GET / HTTP/2.0\r\n", 505},
      {"GET /" + std::string(8000, 'a') + " HTTP/1.1\r\n", 414},
      {"GET http://h/ HTTP/1.1\r\n", 400},  // absolute form
      {"OPTIONS * HTTP/1.1\r\n", 400},
      {"GET /v1/sessions/a%2Fsteps HTTP/1.1\r\n", 404},
      {"GET / HTTP/1.1\r\nX: " + std::string(8200, 'a') + "\r\n", 431},
      {"GET / HTTP/1.1\r\nX: a\r\n b\r\n", 400},  // obsolete line folding
      {"GET / HTTP/1.1\r\nX : a\r\n", 400},
      {"GET / HTTP/1.1\r\n: a\r\n", 400},
      {"GET / HTTP/1.1\r\nno colon\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Length: 3\r\nContent-Length: 4\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Length: 3, 3\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Length: +3\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Length: 1001\r\n", 413},
      {"POST / HTTP/1.1\r\nContent-Length: 3\r\nTransfer-Encoding: chunked\r\n", 400},
      {"POST / HTTP/1.1\r\nTransfer-Encoding: chunked\r\nTransfer-Encoding: chunked\r\n", 400},
      {"POST / HTTP/1.1\r\nTransfer-Encoding: gzip, chunked\r\n", 400},
      {"POST / HTTP/1.1\r\nContent-Encoding: identity\r\nContent-Encoding: gzip\r\n", 415},
      {"GET / HTTP/1.1\r\nRange: bytes=0-1,2-3\r\n", 416},
  };
  for (const auto& [head, status] : refused) {
    HttpRequest req;
    RequestFraming framing;
    const HeadRefusal r = ReadHead(head, &req, &framing);
    EXPECT_EQ(r.status, status) << head.substr(0, 80) << ": " << r.message;
    EXPECT_FALSE(r.message.empty());
  }
  // Repeated equal lengths and an identity coding are no doubt.
  HttpRequest req;
  RequestFraming framing;
  EXPECT_EQ(ReadHead("POST / HTTP/1.1\r\nContent-Length: 3\r\nContent-Length: 3\r\n"
                     "Content-Encoding: identity\r\nContent-Encoding:\r\nRange: bytes=0-1\r\n",
                     &req, &framing)
                .status,
            0);
  EXPECT_EQ(framing.content_length, 3u);
}

}  // namespace
}  // namespace npfkct::server
