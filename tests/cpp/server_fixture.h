// The test fixture of the server tests: the real server on a loopback port and an HTTP client.
#pragma once

#include <gtest/gtest.h>
#include <httplib.h>

#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "npfkct/server/server.h"

namespace npfkct::server {

using nlohmann::json;

/// The prior-map part of a scenario file in scenarios.
inline json WorldOf(const std::string& scenario) {
  std::ifstream in(std::string(NPFKCT_SCENARIO_DIR) + "/" + scenario + ".json");
  std::stringstream buffer;
  buffer << in.rdbuf();
  json s = json::parse(buffer.str());
  json world;
  for (const char* key :
       {"robot", "room", "mapResolution", "furniture", "baseRegions", "discretePoses", "start"}) {
    if (s.contains(key)) world[key] = s[key];
  }
  return world;
}

/// A reply: status, body parsed as JSON (discarded on error) and raw.
struct Reply {
  int status = 0;
  json body;
  std::string raw;
};

/// Starts a server per test; Post/Get/Delete talk to it.
class ServerTest : public ::testing::Test {
 protected:
  void Start(ServerOptions o = {}) {
    o.port = 0;
    if (o.model_dir.empty()) o.model_dir = std::string(NPFKCT_MODEL_DIR);
    server_ = std::make_unique<Server>(o);
    ASSERT_TRUE(server_->Start().ok());
    client_ = std::make_unique<httplib::Client>("127.0.0.1", server_->port());
    client_->set_read_timeout(60, 0);
  }
  void TearDown() override {
    if (server_) server_->Stop();
  }
  static Reply Wrap(const httplib::Result& r) {
    Reply out;
    if (!r) return out;
    out.status = r->status;
    out.raw = r->body;
    out.body = json::parse(r->body, nullptr, false);
    return out;
  }
  Reply Post(const std::string& path, const json& body, const httplib::Headers& h = {}) {
    return Wrap(client_->Post(path.c_str(), h, body.dump(), "application/json"));
  }
  Reply PostRaw(const std::string& path, const std::string& body) {
    return Wrap(client_->Post(path.c_str(), body, "application/json"));
  }
  Reply Get(const std::string& path, const httplib::Headers& h = {}) {
    return Wrap(client_->Get(path.c_str(), h));
  }
  Reply Delete(const std::string& path) { return Wrap(client_->Delete(path.c_str())); }

  std::string Create(json extra = json::object()) {
    json body = {{"world", WorldOf("loose1")},
                 {"seed", 7},
                 {"planner", {{"name", "npfkct"}, {"particles", 100}}}};
    body.update(extra);
    Reply r = Post("/v1/sessions", body);
    EXPECT_EQ(r.status, 200) << r.raw;
    return r.body.value("id", "");
  }

  std::unique_ptr<Server> server_;
  std::unique_ptr<httplib::Client> client_;
};

}  // namespace npfkct::server
