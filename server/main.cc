// npfkct-server: the planning server (see docs/api.md and
// schemas/openapi.yaml).
#include <malloc.h>
#include <pthread.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "npfkct/common/version.h"
#include "npfkct/server/server.h"

namespace {

// The shipped models: <prefix>/share/npfkct/models beside an installed binary, else the source
// tree's folder (a binary run from its build directory).
std::string DefaultModelDir() {
  std::error_code error;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", error);
  if (!error) {
    const std::filesystem::path installed = exe.parent_path() / NPFKCT_INSTALLED_MODEL_DIR;
    if (std::filesystem::is_directory(installed, error)) return installed.lexically_normal();
  }
  return NPFKCT_MODEL_DIR;
}

pthread_t main_thread;

// SIGINT/SIGTERM that reached a thread other than main's (async-signal-safe: pthread_kill only).
extern "C" void ForwardToMainThread(int sig) { pthread_kill(main_thread, sig); }

// The flags that are not ServerOptions fields as they are.
struct Flags {
  std::string log_level = "info";
  double max_body_mb = 32;
  double max_inflight_mb = 128;
};

// npfkct-server's flags, into `o` and `extra`.
void AddFlags(CLI::App* app, npfkct::server::ServerOptions* o, Flags* extra) {
  app->add_option("--host", o->host, "address to bind");
  app->add_option("--port", o->port, "port to bind (0: any free port, printed on stdout)");
  app->add_option("--state-dir", o->state_dir,
                  "directory for session snapshots; sessions survive restarts");
  app->add_option("--store", o->store_url,
                  "fleet mode: PostgreSQL URL of the session store the replicas share, "
                  "postgresql://user@host:5432/db (or the NPFKCT_STORE environment variable)")
      ->envname("NPFKCT_STORE");
  app->add_option("--store-pool", o->store_pool, "connections to the store (fleet mode)");
  app->add_option("--store-timeout", o->store_timeout_seconds,
                  "seconds one store call may take before the request gets 503 (fleet mode)");
  app->add_option("--store-wait", o->store_wait_seconds,
                  "seconds to wait for the store at start-up (fleet mode)");
  app->add_option("--max-stored-sessions", o->max_stored_sessions,
                  "most sessions the store may hold (fleet mode)");
  app->add_option("--evict-idle", o->evict_idle_seconds,
                  "seconds unused before a session is dropped from memory (fleet mode)");
  app->add_option("--api-key", o->api_key,
                  "require 'Authorization: Bearer KEY' on /v1; needed on a --host other than "
                  "loopback unless --insecure")
      ->envname("NPFKCT_API_KEY");
  app->add_flag("--insecure", o->insecure,
                "allow a --host other than loopback without --api-key: anyone who reaches the "
                "port may use the API");
  app->add_option("--session-ttl", o->session_ttl_seconds, "idle seconds before a session expires");
  app->add_option("--max-sessions", o->max_sessions, "most sessions held at once");
  app->add_option("--threads", o->threads, "request threads (health and metrics have their own)");
  app->add_option("--plan-slots", o->plan_slots, "plans running at once (0: one per core)");
  app->add_option("--plan-queue", o->plan_queue, "plans waiting for a slot (0: twice the slots)");
  app->add_option("--max-body-mb", extra->max_body_mb,
                  "largest request body in MiB, in any framing");
  app->add_option("--max-inflight-mb", extra->max_inflight_mb,
                  "request bytes buffered across all connections, in MiB");
  app->add_option("--max-connections", o->max_connections, "open connections");
  app->add_option("--head-timeout", o->head_timeout_seconds, "seconds to send a request's head");
  app->add_option("--body-timeout", o->body_timeout_seconds, "seconds to send a request's body");
  app->add_option("--idle-timeout", o->idle_timeout_seconds, "keep-alive seconds between requests");
  app->add_option("--default-plan-ms", o->limits.default_plan_ms,
                  "budget of a :plan that gives none");
  app->add_option("--max-plan-ms", o->limits.max_plan_ms,
                  "largest wall-clock or CPU budget one :plan may ask for (ms)");
  app->add_option("--max-plan-simulations", o->limits.max_plan_simulations,
                  "largest simulation budget one :plan may ask for");
  app->add_option("--max-session-plan-seconds", o->limits.max_session_plan_seconds,
                  "planning (wall-clock seconds) one session may spend over its life");
  app->add_option("--max-heap-mb", o->limits.max_heap_mb,
                  "heap (MiB) past which a running plan stops with its best action so far");
  app->add_option("--max-particles", o->limits.max_particles, "largest planner.particles");
  app->add_option("--model-dir", o->model_dir,
                  "folder of the neural filter models clients may name (planner.model)");
  app->add_option("--default-model", o->default_model,
                  "model of the sessions whose planner takes one and that name none (\"\": uniform "
                  "candidates)");
  app->add_option("--max-models", o->max_models, "models kept loaded at once");
  app->add_option("--log-level", extra->log_level, "trace | debug | info | warn | error");
}

// SIGINT and SIGTERM, blocked here to be taken by sigwait in this thread. Threads that libraries
// start before main (OpenBLAS's pool) do not block them, and the kernel delivers a process
// signal to a thread that does not: there the handler passes it on to this thread, where it
// stays pending until sigwait takes it (without it, SIGTERM killed the process at once when it
// landed there).
sigset_t TakeSignals() {
  main_thread = pthread_self();
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  struct sigaction forward {};
  forward.sa_handler = ForwardToMainThread;
  sigemptyset(&forward.sa_mask);
  sigaction(SIGINT, &forward, nullptr);
  sigaction(SIGTERM, &forward, nullptr);
  signal(SIGPIPE, SIG_IGN);

  return signals;
}

}  // namespace

int main(int argc, char** argv) {
  npfkct::server::ServerOptions o;
  o.model_dir = DefaultModelDir();
  Flags extra;
  CLI::App app{"npfkct-server: an embeddable planning server for robot object search"};
  app.set_version_flag("--version", std::string("npfkct-server ") + npfkct::kVersion);
  AddFlags(&app, &o, &extra);
  CLI11_PARSE(app, argc, argv);
  o.max_body_bytes = static_cast<size_t>(extra.max_body_mb * (1 << 20));
  o.max_inflight_bytes = static_cast<size_t>(extra.max_inflight_mb * (1 << 20));
  // The log goes to stderr; stdout carries only "listening on HOST:PORT" for scripts.
  spdlog::set_default_logger(spdlog::stderr_color_mt("npfkct"));
  spdlog::set_level(spdlog::level::from_str(extra.log_level));
  // One malloc arena per thread would reserve 64 MiB of address space each: a few arenas keep
  // the server's address space small enough to run under a cap (prlimit --as).
  if (std::getenv("MALLOC_ARENA_MAX") == nullptr) mallopt(M_ARENA_MAX, 4);
  const sigset_t signals = TakeSignals();

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
