// The server: the route table and its handlers (routes.h) behind the HTTP front (http_front.h),
// planning admitted through bounded slots. Request and reply bodies are the API layer's business
// (npfkct/api).
#include "npfkct/server/server.h"

#include <spdlog/spdlog.h>

#include <system_error>

#include "http_front.h"
#include "options.h"
#include "routes.h"

namespace npfkct::server {

struct Server::Impl {
  explicit Impl(const ServerOptions& o) : context(o) {}

  RouteContext context;
  std::unique_ptr<HttpFront> http;
};

Server::Server(ServerOptions options) : options_(std::move(options)) {}

Server::~Server() { Stop(); }

Status Server::Start() {
  if (Status s = options_.Validate(); !s.ok()) return s;
  const ServerOptions o = Resolved(options_);
  impl_ = std::make_unique<Impl>(o);
  RouteContext& ctx = impl_->context;
  auto models = ModelRegistry::Open(o.model_dir, o.max_models);
  ctx.default_model = samplers_ ? o.default_model : models->DefaultModel(o.default_model);
  ctx.samplers = samplers_ ? samplers_ : FilterSamplerFactory(models);
  auto restored = ctx.registry.Open(ctx.samplers);
  if (!restored.ok()) return restored.status();
  restored_ = *restored;
  if (restored_ > 0) spdlog::info("restored {} sessions from {}", restored_, o.state_dir);
  // Reads what the process holds outside the heap before any plan: later calls give back what
  // the allocator holds free beyond it.
  ReleaseFreedMemory();

  impl_->http = std::make_unique<HttpFront>(
      FrontOptions(o), [&ctx](const HttpRequest& request) { return Respond(request, ctx); },
      FrontErrors(), [&ctx](int code) { ctx.metrics.ObserveRequest("-", "-", code, 0.0); });
  port_ = impl_->http->Bind(o.host, o.port);
  if (port_ < 0) {
    return Status(StatusCode::kUnavailable, "cannot bind " + o.host + ":" + std::to_string(o.port));
  }
  try {
    impl_->http->Start();
  } catch (const std::system_error& e) {
    return Status(
        StatusCode::kUnavailable,
        "cannot start " + std::to_string(o.threads) +
            " request threads (--threads, raised to the plan slots and queue + 4): " + e.what());
  }
  ctx.registry.StartReaper();
  spdlog::info("npfkct-server listening on {}:{} ({} planning slots, queue {})", o.host, port_,
               o.plan_slots, o.plan_queue);
  return OkStatus();
}

void Server::Stop() {
  if (!impl_) return;
  impl_->context.registry.StopReaper();
  impl_->context.registry.CancelAll();
  if (impl_->http) impl_->http->Shutdown();
  impl_.reset();
}

}  // namespace npfkct::server
