// ServerOptions::Validate: the API is not opened to the network without a key unless asked; and
// BrowserRefusal: web pages of other sites cannot use it through a browser.
#include "options.h"

#include <gtest/gtest.h>

#include <string>

namespace npfkct::server {
namespace {

// Options listening on `host` with `api_key` (strings built first: GCC 12 at -O3 warns falsely
// about assigning a short literal to a std::string member, -Wrestrict).
ServerOptions Listening(std::string host, std::string api_key = std::string()) {
  ServerOptions o;
  o.host = std::move(host);
  o.api_key = std::move(api_key);
  return o;
}

TEST(ServerOptions, LoopbackHostNeedsNoKey) {
  for (const char* host : {"127.0.0.1", "127.0.0.53", "localhost", "::1"}) {
    EXPECT_TRUE(Listening(host).Validate().ok()) << host;
  }
}

TEST(ServerOptions, NetworkHostWithoutKeyIsRefusedNamingTheFlags) {
  for (const char* host : {"0.0.0.0", "::", "192.0.2.7", "npfkct.example"}) {
    const Status s = Listening(host).Validate();
    ASSERT_FALSE(s.ok()) << host;
    ASSERT_EQ(s.field_violations().size(), 1u);
    EXPECT_EQ(s.field_violations()[0].field, "api-key");
    EXPECT_NE(s.message().find("--api-key"), std::string::npos) << s.message();
    EXPECT_NE(s.message().find("--insecure"), std::string::npos) << s.message();
  }
}

TEST(ServerOptions, KeysHttplibWouldDecodeOrTrimAreRefused) {
  // httplib percent-decodes and trims the Authorization header: such a key never matched.
  for (const char* key : {"ab%41cd", "k ", "two words", "tab\tkey"}) {
    const Status s = Listening("0.0.0.0", key).Validate();
    EXPECT_FALSE(s.ok()) << key;
    EXPECT_NE(s.message().find("api-key"), std::string::npos) << s.message();
  }
  EXPECT_TRUE(Listening("0.0.0.0", "s3cr-t_~+/=").Validate().ok());
}

TEST(ServerOptions, NetworkHostWithKeyOrInsecureIsAccepted) {
  EXPECT_TRUE(Listening("0.0.0.0", "a-key").Validate().ok());
  ServerOptions open = Listening("0.0.0.0");
  open.insecure = true;
  EXPECT_TRUE(open.Validate().ok());
}

// Each queued plan holds a request thread: a queue of 100,000 started 100,006 threads and
// aborted the server.
TEST(ServerOptions, PlanQueueIsBoundedByTheThreadsItNeeds) {
  ServerOptions o = Listening("127.0.0.1");
  o.plan_queue = 2048;
  EXPECT_TRUE(o.Validate().ok());
  o.plan_queue = 100000;
  const Status s = o.Validate();
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.field_violations()[0].field, "plan-slots");
}

// A fleet's store adds the TTL to its clock: --session-ttl 1e15 made every create that gave no
// ttlSeconds a 500 ("interval out of range"). The flag has the API's maximum.
TEST(ServerOptions, SessionTtlHasTheApisMaximum) {
  ServerOptions o = Listening("127.0.0.1");
  o.session_ttl_seconds = 1e9;
  EXPECT_TRUE(o.Validate().ok());
  for (double ttl : {1e15, 0.0, -1.0}) {
    o.session_ttl_seconds = ttl;
    const Status s = o.Validate();
    ASSERT_FALSE(s.ok()) << ttl;
    EXPECT_EQ(s.field_violations()[0].field, "session-ttl");
  }
}

TEST(BrowserRefusal, ClientsThatAreNotBrowsersAreServed) {
  for (const char* host : {"127.0.0.1", "0.0.0.0"}) {
    EXPECT_EQ(BrowserRefusal(Listening(host, "k"), true, "", "", ""), "") << host;
    EXPECT_EQ(BrowserRefusal(Listening(host, "k"), true, "planner.example:8080", "", ""), "");
  }
  for (const char* name : {"127.0.0.1:8080", "localhost", "LocalHost.:1", "[::1]:8080", "::1",
                           "127.9.9.9", "robot.localhost:80", ""}) {
    EXPECT_EQ(BrowserRefusal(Listening("127.0.0.1"), true, name, "", ""), "") << name;
  }
}

TEST(BrowserRefusal, OtherHostNamesOfAnUnauthenticatedLoopbackServerAreRefused) {
  for (const char* name : {"evil.example", "evil.example:8080", "127.0.0.1.evil.example",
                           "localhost.evil.example", "[::2]:80", "10.0.0.1", "0x7f000001"}) {
    for (bool api : {true, false}) {
      const std::string why = BrowserRefusal(Listening("127.0.0.1"), api, name, "", "");
      EXPECT_EQ(why.rfind("Host:", 0), 0u) << name << ": " << why;
    }
  }
  // With a key a rebinding page cannot authenticate; a server on the network has many names.
  EXPECT_EQ(BrowserRefusal(Listening("127.0.0.1", "k"), true, "evil.example", "", ""), "");
  ServerOptions open = Listening("0.0.0.0");
  open.insecure = true;
  EXPECT_EQ(BrowserRefusal(open, true, "planner.example", "", ""), "");
}

TEST(BrowserRefusal, PagesOfOtherSitesAreRefusedOnTheApi) {
  const ServerOptions o = Listening("0.0.0.0", "k");
  const char* host = "planner.example:8080";
  EXPECT_EQ(BrowserRefusal(o, true, host, "", "cross-site").rfind("Sec-Fetch-Site:", 0), 0u);
  EXPECT_EQ(BrowserRefusal(o, true, host, "", "Same-Site").rfind("Sec-Fetch-Site:", 0), 0u);
  for (const char* origin : {"http://evil.example", "https://planner.example.evil:8080", "null",
                             "planner.example", "http://planner.exampl"}) {
    EXPECT_EQ(BrowserRefusal(o, true, host, origin, "").rfind("Origin:", 0), 0u) << origin;
  }
  // The console's own calls, also behind a proxy whose Host drops the port.
  EXPECT_EQ(BrowserRefusal(o, true, host, "http://planner.example:8080", "same-origin"), "");
  EXPECT_EQ(BrowserRefusal(o, true, "planner.example", "https://PLANNER.example:8443", ""), "");
  EXPECT_EQ(BrowserRefusal(o, true, host, "", "none"), "");
  // A link from another site to a page that is not the API (the console) is followed.
  EXPECT_EQ(BrowserRefusal(o, false, host, "http://evil.example", "cross-site"), "");
}

}  // namespace
}  // namespace npfkct::server
