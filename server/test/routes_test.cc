// The route table and the checks every route shares, without a socket: each request's route is
// matched once (method and template, its {id} taken out), wrong methods are answered as always,
// and the API key, browser and method checks answer before any handler runs.
#include "routes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "options.h"

namespace npfkct::server {
namespace {

HttpRequest Request(const std::string& method, const std::string& target,
                    std::initializer_list<std::pair<const char*, const char*>> headers = {},
                    std::string body = "") {
  HttpRequest req;
  req.method = method;
  req.target = target;
  req.version = "HTTP/1.1";
  ReadTarget(target, &req);
  for (const auto& [name, value] : headers) req.headers.emplace(name, value);
  req.body = std::move(body);
  return req;
}

class RoutesTest : public ::testing::Test {
 protected:
  void Open(ServerOptions o = {}) {
    o.plan_slots = 1;
    ctx_ = std::make_unique<RouteContext>(Resolved(o));
    ASSERT_TRUE(ctx_->registry.Open(ctx_->samplers).ok());
  }
  // How often the metrics counted (method, route, code).
  int Counted(const std::string& method, const std::string& route, int code) {
    const std::string line = "npfkct_http_requests_total{method=\"" + method + "\",route=\"" +
                             route + "\",code=\"" + std::to_string(code) + "\"} ";
    const std::string text = ctx_->metrics.Render(0, 0);
    const size_t at = text.find(line);
    return at == std::string::npos ? 0 : std::stoi(text.substr(at + line.size()));
  }
  std::unique_ptr<RouteContext> ctx_;
};

// A path of a template: "{id}" as `id`.
std::string PathOf(std::string_view route, const std::string& id) {
  std::string path(route);
  const size_t hole = path.find('{');
  if (hole != std::string::npos) path.replace(hole, path.find('}') - hole + 1, id);
  return path;
}

TEST(RouteTable, EveryRouteIsMatchedByItsOwnMethodAndTemplateOnly) {
  std::set<std::pair<std::string, std::string>> seen;
  for (const Route& r : Routes()) {
    EXPECT_TRUE(seen.insert({r.method, r.path}).second) << r.method << " " << r.path;
    const std::string path = PathOf(r.path, "abc");
    const RouteMatch m = MatchRoute(r.method, path);
    ASSERT_EQ(m.route, &r) << r.method << " " << path;
    EXPECT_EQ(m.id, std::string_view(r.path).find('{') == std::string_view::npos ? "" : "abc");
    EXPECT_NE(m.allow.find(r.method), std::string::npos) << m.allow;
    // `allow` names the method of every route the path fits: no other route of this method.
    int same_method = 0;
    for (size_t at = 0; at <= m.allow.size();) {
      const size_t end = std::min(m.allow.find(", ", at), m.allow.size());
      same_method += m.allow.substr(at, end - at) == r.method;
      at = end + 2;
    }
    EXPECT_EQ(same_method, 1) << path << ": " << m.allow;
  }
  // HEAD is GET without the body.
  EXPECT_EQ(std::string(MatchRoute("HEAD", "/v1/sessions/x/belief").route->path),
            "/v1/sessions/{id}/belief");
  // An {id} is one non-empty segment without '/' or ':'.
  for (const char* path : {"/v1/sessions/", "/v1/sessions/a/b", "/v1/sessions/a:b", "/ui/a/b",
                           "/v1/sessions/abc/plan", "//v1/sessions"}) {
    const RouteMatch m = MatchRoute("GET", path);
    EXPECT_EQ(m.route, nullptr) << path;
    EXPECT_EQ(m.allow, "") << path;
  }
  EXPECT_EQ(MatchRoute("PUT", "/v1/sessions").allow, "POST, GET");
  EXPECT_EQ(MatchRoute("PUT", "/v1/sessions/abc").allow, "GET, DELETE");
  EXPECT_EQ(MatchRoute("GET", "/v1/sessions/abc:plan").allow, "POST");
}

TEST(RouteTable, ANearMissNamesTheRouteItProbablyMeant) {
  const std::pair<const char*, const char*> cases[][2] = {
      {{"POST", "/v1/sessions/0123abcd/plan"}, {"POST", "/v1/sessions/{id}:plan"}},
      {{"POST", "/v1/sessions/x/observe"}, {"POST", "/v1/sessions/{id}:observe"}},
      {{"POST", "/plan"}, {"POST", "/v1/sessions/{id}:plan"}},
      {{"POST", "/v1/observation"}, {"POST", "/v1/sessions/{id}:observe"}},
      {{"GET", "/sessions"}, {"GET", "/v1/sessions"}},
      {{"POST", "/v1/session"}, {"POST", "/v1/sessions"}},
      {{"GET", "/v1/sessions/abc/"}, {"GET", "/v1/sessions/{id}"}},
      {{"DELETE", "/sessions/abc"}, {"DELETE", "/v1/sessions/{id}"}},
      {{"GET", "/v1/Sessions/abc/Belief"}, {"GET", "/v1/sessions/{id}/belief"}},
      {{"GET", "/health"}, {"GET", "/healthz"}},
      {{"GET", "/v1/planner"}, {"GET", "/v1/planners"}},
  };
  for (const auto& [request, meant] : cases) {
    const Route* r = NearestRoute(request.first, request.second);
    ASSERT_NE(r, nullptr) << request.second;
    EXPECT_EQ(std::string(r->method) + " " + r->path, std::string(meant.first) + " " + meant.second)
        << request.first << " " << request.second;
  }
  for (const char* far : {"/", "/favicon.ico", "/wp-login.php", "/v2/things/abc", "/x"}) {
    EXPECT_EQ(NearestRoute("GET", far), nullptr) << far;
  }
  // Only the first 200 characters are read.
  EXPECT_EQ(NearestRoute("GET", std::string(100000, 'a')), nullptr);
}

TEST_F(RoutesTest, WrongMethodsAndUnknownPathsAreAnsweredAsAlways) {
  Open();
  HttpResponse res = Respond(Request("PUT", "/v1/sessions"), *ctx_);
  EXPECT_EQ(res.status, 405);
  EXPECT_EQ(res.Header("Allow"), "POST, GET");
  EXPECT_NE(res.body.find("\"PUT is not allowed here\""), std::string::npos) << res.body;
  EXPECT_NE(res.body.find("UNIMPLEMENTED"), std::string::npos) << res.body;
  res = Respond(Request("POST", "/v1/sessions/abc/plan", {}, "{}"), *ctx_);
  EXPECT_EQ(res.status, 404);
  EXPECT_NE(res.body.find("no route for POST /v1/sessions/abc/plan; did you mean POST "
                          "/v1/sessions/{id}:plan?"),
            std::string::npos)
      << res.body;
  res = Respond(Request("BREW", "/healthz"), *ctx_);
  EXPECT_EQ(res.status, 400);
  EXPECT_NE(res.body.find("method BREW is not supported (GET, HEAD, POST, DELETE)"),
            std::string::npos);
  res = Respond(Request("GET", "/v1/sessions?a=1?b=2"), *ctx_);
  EXPECT_EQ(res.status, 400);
  res = Respond(Request("GET", "/" + std::string(1100, 'a')), *ctx_);
  EXPECT_EQ(res.status, 414);
  // Every answer is nosniff JSON, counted once under its route's name.
  EXPECT_EQ(res.Header("X-Content-Type-Options"), "nosniff");
  EXPECT_EQ(res.Header("Content-Type"), "application/json");
  EXPECT_EQ(Counted("PUT", "other", 405), 1);
  EXPECT_EQ(Counted("POST", "unknown", 404), 1);
  EXPECT_EQ(Counted("other", "-", 400), 1);  // a label never carries client bytes
  EXPECT_EQ(Counted("GET", "-", 414), 1);
}

TEST_F(RoutesTest, AMalformedSessionIdIsNotFound) {
  Open();
  const HttpResponse res = Respond(Request("GET", "/v1/sessions/bad!id"), *ctx_);
  EXPECT_EQ(res.status, 404);
  EXPECT_NE(res.body.find("sessions/bad!id not found"), std::string::npos) << res.body;
  EXPECT_EQ(Counted("GET", "/v1/sessions/{id}", 404), 1);
  // The handler alone, as the route calls it.
  const HttpRequest http = Request("GET", "/v1/sessions/" + std::string(32, '0'));
  EXPECT_EQ(GetSession(RouteRequest{http, std::string(32, '0')}, *ctx_).status, 404);
  EXPECT_EQ(Respond(Request("GET", "/v1/sessions"), *ctx_).body, "{\"sessions\":[]}");
}

TEST_F(RoutesTest, TheApiKeyIsCheckedBeforeAnyHandler) {
  ServerOptions o;
  o.host = "0.0.0.0";
  o.api_key = "k3y";
  Open(o);
  // A create without the key never reaches its handler (which would answer the empty body 400).
  HttpResponse res = Respond(Request("POST", "/v1/sessions", {}, "{}"), *ctx_);
  EXPECT_EQ(res.status, 401);
  EXPECT_NE(res.body.find("bearer token"), std::string::npos);
  res = Respond(Request("POST", "/v1/sessions", {{"Authorization", "Bearer k3z"}}, "{}"), *ctx_);
  EXPECT_EQ(res.status, 401);
  res = Respond(Request("POST", "/v1/sessions", {{"authorization", "Bearer k3y"}}, "{}"), *ctx_);
  EXPECT_EQ(res.status, 400);  // the handler's: the body names no world
  // Health, metrics and the console need no key.
  EXPECT_EQ(Respond(Request("GET", "/healthz"), *ctx_).status, 200);
  EXPECT_EQ(Respond(Request("HEAD", "/metrics"), *ctx_).status, 200);
  EXPECT_EQ(Respond(Request("GET", "/ui"), *ctx_).status, 200);
  EXPECT_EQ(Counted("POST", "/v1/sessions", 401), 2);
  EXPECT_EQ(Counted("POST", "/v1/sessions", 400), 1);
}

TEST_F(RoutesTest, BrowsersAndMultipartBodiesAreRefusedBeforeAnyHandler) {
  Open();
  HttpResponse res =
      Respond(Request("GET", "/v1/sessions", {{"Origin", "http://evil.example"}}), *ctx_);
  EXPECT_EQ(res.status, 403);
  EXPECT_NE(res.body.find("Origin"), std::string::npos);
  // A page's DNS rebinding: any route of a keyless loopback server, the console included.
  res = Respond(Request("GET", "/ui/", {{"Host", "evil.example"}}), *ctx_);
  EXPECT_EQ(res.status, 403);
  res = Respond(
      Request("POST", "/v1/sessions", {{"Content-Type", "multipart/form-data; boundary=x"}}, "{}"),
      *ctx_);
  EXPECT_EQ(res.status, 415);
}

}  // namespace
}  // namespace npfkct::server
