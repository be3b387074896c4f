// ServerOptions::Validate: the API is not opened to the network without a key unless asked.
#include <gtest/gtest.h>

#include <string>

#include "npfkct/server/server.h"

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

TEST(ServerOptions, NetworkHostWithKeyOrInsecureIsAccepted) {
  EXPECT_TRUE(Listening("0.0.0.0", "a-key").Validate().ok());
  ServerOptions open = Listening("0.0.0.0");
  open.insecure = true;
  EXPECT_TRUE(open.Validate().ok());
}

}  // namespace
}  // namespace npfkct::server
