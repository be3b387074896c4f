// The server: a route table of named handlers (llama.cpp style), authentication and protocol
// limits in one pre-routing hook, planning admitted through bounded slots, the HTTP front of
// http_front.h underneath. Request and reply bodies are the API layer's business (npfkct/api).
#include "npfkct/server/server.h"

#include <spdlog/spdlog.h>
#include <sys/socket.h>

#include <algorithm>
#include <random>
#include <string_view>
#include <system_error>
#include <thread>

#include "admission.h"
#include "console.h"
#include "http_front.h"
#include "npfkct/api/api.h"
#include "npfkct/filter/filter.h"
#include "options.h"
#include "registry.h"

namespace npfkct::server {
namespace {

using Request = httplib::Request;
using Response = httplib::Response;

// Bodies larger than this may hold images (target photos, an observation's frame), which are
// decoded as the body is parsed: such requests take a planning slot before they are parsed.
constexpr size_t kAdmittedBodyBytes = size_t{64} << 10;

void Json(Response& res, int status, std::string body) {
  res.status = status;
  res.set_content(std::move(body), "application/json");
}

// Whether `path` matches a route template: literal, with "{id}" (or "{file}") standing for one
// non-empty segment without '/' or ':' (the `([^/:]+)` of the route's pattern).
bool Matches(std::string_view route, std::string_view path) {
  const size_t hole = route.find('{'), close = route.find('}');
  if (hole == std::string_view::npos || close < hole) return route == path;
  const std::string_view prefix = route.substr(0, hole), suffix = route.substr(close + 1);
  if (path.size() <= prefix.size() + suffix.size() || path.substr(0, prefix.size()) != prefix ||
      path.substr(path.size() - suffix.size()) != suffix) {
    return false;
  }
  const std::string_view id =
      path.substr(prefix.size(), path.size() - prefix.size() - suffix.size());
  return id.find_first_of("/:") == std::string_view::npos;
}

// UNAVAILABLE (the session store did not answer) is worth retrying in a second; a 429 of the
// server's resources names when to retry (5 s unless the caller knows better: the heap bound, a
// full store). A 429 naming a field is the request's own limit (a session's planning budget),
// which no retry clears: it names no time.
void Fail(Response& res, const Status& s, int http_status = 0, int retry_after = 0) {
  if (retry_after == 0 && s.code() == StatusCode::kUnavailable) retry_after = 1;
  const int code = http_status > 0 ? http_status : api::HttpStatusOf(s.code());
  if (retry_after == 0 && code == 429 && s.field_violations().empty()) retry_after = 5;
  Json(res, code, api::RenderError(s, code, retry_after));
  if (retry_after > 0) res.set_header("Retry-After", std::to_string(retry_after));
}

}  // namespace

struct Server::Impl {
  using Handler = void (Impl::*)(const Request&, Response&, const std::string& body);
  struct Route {
    const char* method;
    const char* name;     // the route template, for metrics and logs
    const char* pattern;  // the path's regular expression, for httplib's dispatch
    bool auth;
    bool body;  // reads a request body (POST, DELETE)
    Handler handler;
  };

  ServerOptions options;
  SamplerFactory samplers;
  Metrics metrics;
  Registry registry;
  Admission admission;
  std::unique_ptr<HttpFront> http;
  std::vector<Route> routes;
  std::thread serve_thread;
  std::string default_model;  // of sessions that name none; empty when not in the model folder

  explicit Impl(const ServerOptions& o)
      : options(o), registry(o, &metrics), admission(o.plan_slots, o.plan_queue) {}

  // ---- handlers ----

  // Answers from what the store last said (never waits for it): 503 while it is unavailable.
  void Health(const Request&, Response& res, const std::string&) {
    const StoreHealth store = registry.store_health();
    const api::HealthView h{registry.store()->backend(), store.ok, store.message, registry.size()};
    Json(res, store.ok ? 200 : 503, api::RenderHealth(h));
    if (!store.ok) res.set_header("Retry-After", "1");
  }

  void MetricsText(const Request&, Response& res, const std::string&) {
    res.status = 200;
    res.set_content(metrics.Render(admission.running(), admission.waiting()),
                    "text/plain; version=0.0.4; charset=utf-8");
  }

  // The session of the path, held or (fleet mode) loaded from the store, and touched: its TTL
  // counts from the last request on it, whatever the request and its outcome.
  std::shared_ptr<Session> Find(const Request& req, Response& res) {
    auto s = registry.Acquire(req.matches[1]);
    if (!s.ok()) {
      Fail(res, s.status());
      return nullptr;
    }
    (*s)->Touch();
    return *s;
  }

  // A planning slot for a request's CPU work, held in `*ticket` (kept if it holds one already)
  // until the handler returns; false, with the 429 answered, when none comes.
  bool Admit(Response& res, std::optional<Admission::Ticket>* ticket) {
    if (*ticket) return true;
    auto t = admission.Enter([] { return HttpFront::ClientGone(); });
    if (!t.ok()) {
      Fail(res, t.status(), 0, 1);
      return false;
    }
    *ticket = std::move(t).value();
    return true;
  }

  void Create(const Request&, Response& res, const std::string& body) {
    // Target photos are decoded while the body is parsed: CPU work (a 400 kB body of photos took
    // 1.7 s), admitted like a plan.
    std::optional<Admission::Ticket> ticket;
    if (body.size() > kAdmittedBodyBytes && !Admit(res, &ticket)) return;
    auto req = api::ParseCreateSession(body, options.limits, options.planners);
    if (!req.ok()) return Fail(res, req.status());
    if (req->ttl_seconds && *req->ttl_seconds > options.session_ttl_seconds) {
      return Fail(res, InvalidFieldError("ttlSeconds", "must be <= " +
                                                           std::to_string(static_cast<int64_t>(
                                                               options.session_ttl_seconds)) +
                                                           " (the server's --session-ttl)"));
    }
    if (Status full = registry.CheckCapacity(); !full.ok()) return Fail(res, full, 0, 5);
    auto world = api::BuildWorld(req->world, options.limits);
    if (!world.ok()) return Fail(res, world.status());
    // A planner that takes a filter model plans with the server's default model unless the
    // request names one ("": none).
    if (req->planner.takes_model && !req->planner.model_given) {
      req->planner.model = default_model;
    }
    SessionConfig config{
        Registry::NewId(),
        req->display_name,
        req->planner,
        req->target,
        req->seed.value_or(std::random_device{}()) ^ (uint64_t{std::random_device{}()} << 32),
        req->ttl_seconds.value_or(options.session_ttl_seconds)};
    if (req->seed) config.seed = *req->seed;
    auto session = Session::Create(std::move(config), std::move(world).value(), samplers,
                                   options.planners, registry.session_limits());
    if (!session.ok()) return Fail(res, api::ToWire(session.status()));
    auto added = registry.Add(std::move(session).value());
    if (!added.ok()) return Fail(res, added.status(), 0, 5);
    spdlog::info("session {} created (planner {})", (*added)->id(), req->planner.name);
    Json(res, 200, api::RenderSession((*added)->View()));
  }

  void List(const Request& req, Response& res, const std::string&) {
    auto param = [&](const char* key) -> std::optional<std::string> {
      if (!req.has_param(key)) return std::nullopt;
      return req.get_param_value(key);
    };
    auto list = api::ParseList(param("pageSize"), param("pageToken"));
    if (!list.ok()) return Fail(res, list.status());
    std::string next;
    auto views = registry.Page(list->page_token, list->page_size, &next);
    if (!views.ok()) return Fail(res, views.status());
    Json(res, 200, api::RenderSessionList(*views, next));
  }

  void Get(const Request& req, Response& res, const std::string&) {
    auto s = Find(req, res);
    if (!s) return;
    Json(res, 200, api::RenderSession(s->View()));
  }

  void Delete(const Request& req, Response& res, const std::string&) {
    const std::string id = req.matches[1];
    if (Status st = registry.Remove(id); !st.ok()) return Fail(res, st);
    spdlog::info("session {} deleted", id);
    Json(res, 200, api::RenderEmpty());
  }

  void Plan(const Request& req, Response& res, const std::string& body) {
    const auto start = std::chrono::steady_clock::now();
    auto plan = api::ParsePlan(body, options.limits);
    if (!plan.ok()) return Fail(res, plan.status());
    auto s = Find(req, res);
    if (!s) return;
    // The budget as used: the request's, the default when it gives none, and never without a
    // wall-clock cap (a budget of simulations or CPU time alone is capped at the maximum).
    Budget budget{plan->time_ms.value_or(0.0), plan->simulations.value_or(0),
                  plan->cpu_ms.value_or(0.0)};
    if (!plan->time_ms && !plan->cpu_ms && !plan->simulations) {
      budget.time_ms = options.limits.default_plan_ms;
    }
    if (budget.time_ms == 0.0) budget.time_ms = options.limits.max_plan_ms;
    // The session admits itself once it is claimed (a second plan on it is refused at once, and
    // a session waiting in the queue is in use, not idle); a plan of several search threads
    // takes a slot for each (at most all of them).
    bool queue_full = false;
    Session::Admit admit = [this, &queue_full](const std::function<bool()>& give_up,
                                               int threads) -> StatusOr<Session::SlotHold> {
      auto ticket = admission.Enter(give_up, threads);
      queue_full = ticket.status().code() == StatusCode::kResourceExhausted;
      if (!ticket.ok()) return ticket.status();
      return Session::SlotHold(std::make_shared<Admission::Ticket>(std::move(ticket).value()));
    };
    StatusOr<api::PlanReply> reply = Status(StatusCode::kInternal, "not planned");
    {
      BatchScheduling batch;
      // The search's own threads poll this too: the connection is captured, not the
      // handler thread's.
      const Connection* connection = HttpFront::Current();
      reply = s->Plan(
          budget, [connection] { return HttpFront::ClientGone(connection); }, registry.store(),
          admit);
    }
    if (!reply.ok()) {
      // Another replica saved the session first (or the save failed): this plan's time still
      // counts against the session's lifetime budget, racing replicas included.
      if (s->stale()) registry.KeepUsageOf(s);
      return Fail(res, api::ToWire(reply.status()), 0, queue_full ? 1 : 0);
    }
    reply->summary.budget_given = Budget{plan->time_ms.value_or(0.0), plan->simulations.value_or(0),
                                         plan->cpu_ms.value_or(0.0)};
    const double total =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double planning = reply->stats.elapsed_ms / 1000.0;
    metrics.ObservePlan(planning, std::max(0.0, total - planning), reply->stats.simulations);
    Json(res, 200, api::RenderPlan(*reply));
  }

  void Observe(const Request& req, Response& res, const std::string& body) {
    // The session first: parsing decodes raw images, CPU work not spent on a session that
    // does not exist.
    auto s = Find(req, res);
    if (!s) return;
    // Raw sensor data run perception, and their images are decoded while the body is parsed
    // (before the action id is checked): CPU work, admitted like a plan, a large body before it
    // is parsed.
    std::optional<Admission::Ticket> ticket;
    if (body.size() > kAdmittedBodyBytes && !Admit(res, &ticket)) return;
    auto observe = api::ParseObserve(body, options.limits);
    if (!observe.ok()) return Fail(res, observe.status());
    if (observe->frame && !Admit(res, &ticket)) return;
    auto reply = s->Observe(std::move(observe).value(), registry.store());
    if (!reply.ok()) return Fail(res, api::ToWire(reply.status()));
    Json(res, 200, api::RenderObserve(*reply));
    ReleaseFreedMemory();  // the planner kept only the subtree of what was observed
  }

  void Belief(const Request& req, Response& res, const std::string&) {
    std::optional<std::string> format;
    if (req.has_param("format")) format = req.get_param_value("format");
    auto f = api::ParseBeliefFormat(format);
    if (!f.ok()) return Fail(res, f.status());
    auto s = Find(req, res);
    if (!s) return;
    const auto world = s->Belief();
    const api::SessionView view = s->View();
    if (*f == api::BeliefFormat::kJson) return Json(res, 200, api::RenderBelief(*world, &view));
    // Rendering a picture is CPU work (up to half a second for a large world): admitted like a
    // plan, so that pictures cannot occupy every request thread.
    std::optional<Admission::Ticket> ticket;
    if (!Admit(res, &ticket)) return;
    auto png = api::RenderBeliefPng(*world, &view);
    if (!png.ok()) return Fail(res, png.status());
    res.status = 200;
    res.set_content(std::move(png).value(), "image/png");
  }

  void Steps(const Request& req, Response& res, const std::string&) {
    if (auto s = Find(req, res)) Json(res, 200, api::RenderSteps(s->Steps()));
  }

  // The planners sessions may use, with every option's default (a planner that takes a filter
  // model lists Net_sam's filter.* options too).
  void Planners(const Request&, Response& res, const std::string&) {
    std::vector<api::PlannerView> views;
    const object_search::SearchParams params;
    for (const object_search::PlannerEntry& e : options.planners.entries()) {
      if (e.needs_truth) continue;
      api::PlannerView v{e.name, e.summary, e.takes_sampler, e.defaults(params)};
      if (e.takes_sampler) {
        for (const auto& [key, value] : filter::OptionValues(filter::FilterOptions{})) {
          v.defaults.emplace_back("filter." + key, value);
        }
        std::sort(v.defaults.begin(), v.defaults.end());
      }
      views.push_back(std::move(v));
    }
    Json(res, 200, api::RenderPlanners(views));
  }

  void Console(const Request& req, Response& res, const std::string&) { ServeConsole(req, res); }

  // ---- routing ----

  // Runs a handler: bad_alloc is an exhausted resource, anything else a bug (never a crash).
  void Invoke(const Route& route, const Request& req, Response& res, const std::string& body) {
    try {
      (this->*route.handler)(req, res, body);
    } catch (const std::bad_alloc&) {
      Fail(res, ResourceExhaustedError("the server is out of memory; retry later"), 0, 5);
    } catch (const std::exception& e) {
      spdlog::error("{} {}: {}", req.method, route.name, e.what());
      Fail(res, InternalError("unexpected error"));
    }
  }

  void AddRoute(const char* method, const char* name, const char* pattern, bool auth, Handler h) {
    routes.push_back({method, name, pattern, auth, std::string(method) != "GET", h});
  }

  void Register() {
    AddRoute("GET", "/healthz", "/healthz", false, &Impl::Health);
    AddRoute("GET", "/metrics", "/metrics", false, &Impl::MetricsText);
    AddRoute("POST", "/v1/sessions", "/v1/sessions", true, &Impl::Create);
    AddRoute("GET", "/v1/sessions", "/v1/sessions", true, &Impl::List);
    AddRoute("GET", "/v1/planners", "/v1/planners", true, &Impl::Planners);
    AddRoute("GET", "/v1/sessions/{id}", R"(/v1/sessions/([^/:]+))", true, &Impl::Get);
    AddRoute("DELETE", "/v1/sessions/{id}", R"(/v1/sessions/([^/:]+))", true, &Impl::Delete);
    AddRoute("POST", "/v1/sessions/{id}:plan", R"(/v1/sessions/([^/:]+):plan)", true, &Impl::Plan);
    AddRoute("POST", "/v1/sessions/{id}:observe", R"(/v1/sessions/([^/:]+):observe)", true,
             &Impl::Observe);
    AddRoute("GET", "/v1/sessions/{id}/belief", R"(/v1/sessions/([^/:]+)/belief)", true,
             &Impl::Belief);
    AddRoute("GET", "/v1/sessions/{id}/steps", R"(/v1/sessions/([^/:]+)/steps)", true,
             &Impl::Steps);
    for (const char* ui : {"/ui", "/ui/"}) AddRoute("GET", ui, ui, false, &Impl::Console);
    AddRoute("GET", "/ui/{file}", R"(/ui/([^/:]+))", false, &Impl::Console);
    for (const Route& route : routes) {
      const Route* r = &route;
      if (!r->body) {
        http->Get(r->pattern, [this, r](const Request& req, Response& res) {
          Invoke(*r, req, res, std::string());
        });
        continue;
      }
      auto with_body = [this, r](const Request& req, Response& res,
                                 const httplib::ContentReader& reader) {
        std::string body;
        // No Content-Length and no Transfer-Encoding: no body (RFC 9112 6.3). The front has
        // read and counted the body already; this bound is a second line.
        if (req.has_header("Content-Length") || req.has_header("Transfer-Encoding")) {
          const bool complete = reader([&](const char* data, size_t n) {
            if (body.size() + n > options.max_body_bytes) return false;
            body.append(data, n);
            return true;
          });
          if (!complete) {
            if (Connection* c = HttpFront::Current()) c->must_close = true;
            return Fail(res, ResourceExhaustedError("the body is larger than the limit"), 413);
          }
        }
        Invoke(*r, req, res, body);
      };
      if (std::string(r->method) == "POST") {
        http->Post(r->pattern, with_body);
      } else {
        http->Delete(r->pattern, with_body);
      }
    }
    // Authentication and protocol limits, for every route, before any body is looked at.
    http->set_pre_routing_handler([this](const Request& req, Response& res) {
      using R = httplib::Server::HandlerResponse;
      Connection* conn = HttpFront::Current();
      if (req.path.size() > 1024) {
        Fail(res, InvalidArgumentError("the path is longer than 1024 characters"), 414);
        return R::Handled;
      }
      const Route* route = nullptr;
      std::string allow;
      for (const Route& r : routes) {
        if (!Matches(r.name, req.path)) continue;
        allow += (allow.empty() ? "" : ", ") + std::string(r.method);
        if (req.method == r.method || (req.method == "HEAD" && std::string(r.method) == "GET")) {
          route = &r;
        }
      }
      if (conn) conn->route = route ? route->name : allow.empty() ? "unknown" : "other";
      if (allow.empty()) {
        Fail(res, NotFoundError("no route for " + req.method + " " + req.path.substr(0, 200)));
        return R::Handled;
      }
      if (!route) {
        Fail(res, Status(StatusCode::kUnimplemented, req.method + " is not allowed here"), 405);
        res.set_header("Allow", allow);
        return R::Handled;
      }
      if (const std::string refusal = BrowserRefusal(
              options, route->auth, req.get_header_value("Host"), req.get_header_value("Origin"),
              req.get_header_value("Sec-Fetch-Site"));
          !refusal.empty()) {
        Fail(res,
             Status(StatusCode::kPermissionDenied, refusal)
                 .WithFieldViolation(refusal.substr(0, refusal.find(':')), "refused"),
             403);
        return R::Handled;
      }
      // httplib reads a multipart body only through its multipart reader (the plain one
      // throws); no route takes one.
      if (req.is_multipart_form_data()) {
        if (conn) conn->must_close = true;
        Fail(res, InvalidArgumentError("Content-Type: expected application/json, not multipart"),
             415);
        return R::Handled;
      }
      if (route->auth && !options.api_key.empty() &&
          !SameSecret(req.get_header_value("Authorization"), "Bearer " + options.api_key)) {
        Fail(res, Status(StatusCode::kUnauthenticated,
                         "missing or wrong bearer token (Authorization header)"));
        return R::Handled;
      }
      return R::Unhandled;
    });
    // Errors httplib answers itself (a malformed request line, a URI too long): JSON too.
    http->set_error_handler(HttpErrorBodies());
    http->set_exception_handler([](const Request&, Response& res, std::exception_ptr) {
      Fail(res, InternalError("unexpected error"));
    });
    // Every response, with its real status code, counted before it is written (so that a client
    // that reads /metrics next sees its previous request).
    http->set_post_routing_handler([this](const Request& req, Response& res) {
      // No response is to be read as anything but its Content-Type (a JSON error echoing a
      // field path is not HTML).
      if (!res.has_header("X-Content-Type-Options")) {
        res.set_header("X-Content-Type-Options", "nosniff");
      }
      const Connection* c = HttpFront::Current();
      const double seconds =
          c ? std::chrono::duration<double>(std::chrono::steady_clock::now() - c->start).count()
            : 0.0;
      metrics.ObserveRequest(req.method.empty() ? "-" : req.method.substr(0, 16),
                             c ? c->route : "-", res.status, seconds);
    });
  }
};

Server::Server(ServerOptions options) : options_(std::move(options)) {}

Server::~Server() { Stop(); }

Status Server::Start() {
  if (Status s = options_.Validate(); !s.ok()) return s;
  const ServerOptions o = Resolved(options_);
  impl_ = std::make_unique<Impl>(o);
  Impl& im = *impl_;
  auto models = ModelRegistry::Open(o.model_dir, o.max_models);
  im.default_model = samplers_ ? o.default_model : models->DefaultModel(o.default_model);
  im.samplers = samplers_ ? samplers_ : FilterSamplerFactory(models);
  auto restored = im.registry.Open(im.samplers);
  if (!restored.ok()) return restored.status();
  restored_ = *restored;
  if (restored_ > 0) spdlog::info("restored {} sessions from {}", restored_, o.state_dir);
  // Reads what the process holds outside the heap before any plan: later calls give back what
  // the allocator holds free beyond it.
  ReleaseFreedMemory();

  const HttpFrontOptions front = FrontOptions(o);
  im.http = std::make_unique<HttpFront>(
      front, FrontErrors(), [&im](int code) { im.metrics.ObserveRequest("-", "-", code, 0.0); });
  im.http->set_payload_max_length(o.max_body_bytes);
  im.http->set_keep_alive_max_count(front.keep_alive_max);
  im.http->set_keep_alive_timeout(static_cast<time_t>(std::max(1.0, o.idle_timeout_seconds)));
  // httplib's default sets SO_REUSEPORT alone: a second server (or any process of the same user)
  // could bind the same port and take a share of the connections. SO_REUSEADDR only lets a
  // restart bind while the old connections linger in TIME_WAIT.
  im.http->set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
  });
  im.Register();
  port_ = o.port == 0 ? im.http->bind_to_any_port(o.host)
                      : (im.http->bind_to_port(o.host, o.port) ? o.port : -1);
  if (port_ < 0) {
    return Status(StatusCode::kUnavailable, "cannot bind " + o.host + ":" + std::to_string(o.port));
  }
  try {
    im.http->Start();
  } catch (const std::system_error& e) {
    return Status(
        StatusCode::kUnavailable,
        "cannot start " + std::to_string(o.threads) +
            " request threads (--threads, raised to the plan slots and queue + 4): " + e.what());
  }
  im.serve_thread = std::thread([&im] { im.http->listen_after_bind(); });
  im.registry.StartReaper();
  spdlog::info("npfkct-server listening on {}:{} ({} planning slots, queue {})", o.host, port_,
               o.plan_slots, o.plan_queue);
  return OkStatus();
}

void Server::Stop() {
  if (!impl_) return;
  impl_->registry.StopReaper();
  impl_->registry.CancelAll();
  if (impl_->http) {
    impl_->http->stop();
    if (impl_->serve_thread.joinable()) impl_->serve_thread.join();
    impl_->http->Shutdown();
  }
  impl_.reset();
}

}  // namespace npfkct::server
