// npfkct-server: the planning server (see README.md and schemas/openapi.yaml).
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>

#include "npfkct/server/server.h"

int main(int argc, char** argv) {
  npfkct::server::ServerOptions o;
  std::string log_level = "info";
  double max_body_mb = 64;
  CLI::App app{"npfkct-server: an embeddable planning server for robot object search"};
  app.add_option("--host", o.host, "address to bind");
  app.add_option("--port", o.port, "port to bind (0: any free port, printed on stdout)");
  app.add_option("--state-dir", o.state_dir,
                 "directory for session snapshots; sessions survive restarts");
  app.add_option("--api-key", o.api_key, "require 'Authorization: Bearer KEY' on /v1");
  app.add_option("--session-ttl", o.session_ttl_seconds, "idle seconds before a session expires");
  app.add_option("--max-sessions", o.max_sessions, "most sessions held at once");
  app.add_option("--threads", o.threads, "request worker threads");
  app.add_option("--max-body-mb", max_body_mb, "largest request body in MiB");
  app.add_option("--default-plan-ms", o.default_plan_ms, "budget of a :plan that gives none");
  app.add_option("--max-plan-ms", o.max_plan_ms, "largest budget a :plan may ask for");
  app.add_option("--log-level", log_level, "trace | debug | info | warn | error");
  CLI11_PARSE(app, argc, argv);
  o.max_body_bytes = static_cast<size_t>(max_body_mb * (1 << 20));
  spdlog::set_level(spdlog::level::from_str(log_level));

  // Signals are taken by sigwait in this thread, not by handlers.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  npfkct::server::Server server(o);
  if (npfkct::Status s = server.Start(); !s.ok()) {
    std::fprintf(stderr, "npfkct-server: %s\n", s.ToString().c_str());
    return 1;
  }
  std::printf("listening on %s:%d\n", o.host.c_str(), server.port());
  std::fflush(stdout);
  int sig = 0;
  sigwait(&signals, &sig);
  spdlog::info("signal {}: shutting down", sig);
  server.Stop();
  return 0;
}
