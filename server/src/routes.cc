#include "routes.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <optional>
#include <random>
#include <vector>

#include "console.h"
#include "http_front.h"
#include "npfkct/api/api.h"
#include "npfkct/common/version.h"
#include "npfkct/filter/filter.h"
#include "options.h"

namespace npfkct::server {
namespace {

// Bodies larger than this may hold images (target photos, an observation's frame), which are
// decoded as the body is parsed: such requests take a planning slot before they are parsed.
constexpr size_t kAdmittedBodyBytes = size_t{64} << 10;

// The longest path routed.
constexpr size_t kMaxPath = 1024;

constexpr Route kRoutes[] = {
    {"GET", "/healthz", false, &Health},
    {"GET", "/metrics", false, &MetricsText},
    {"POST", "/v1/sessions", true, &CreateSession},
    {"GET", "/v1/sessions", true, &ListSessions},
    {"GET", "/v1/planners", true, &ListPlanners},
    {"GET", "/v1/sessions/{id}", true, &GetSession},
    {"DELETE", "/v1/sessions/{id}", true, &DeleteSession},
    {"POST", "/v1/sessions/{id}:plan", true, &PlanSession},
    {"POST", "/v1/sessions/{id}:observe", true, &ObserveSession},
    {"GET", "/v1/sessions/{id}/belief", true, &GetBelief},
    {"GET", "/v1/sessions/{id}/steps", true, &GetSteps},
    {"GET", "/ui", false, &GetConsoleFile},
    {"GET", "/ui/", false, &GetConsoleFile},
    {"GET", "/ui/{file}", false, &GetConsoleFile},
};

HttpResponse Json(int status, std::string body) {
  HttpResponse res;
  res.status = status;
  res.SetContent(std::move(body), "application/json");
  return res;
}

// Whether `path` fits a route template, and the segment its "{id}" (or "{file}") stands for.
bool Fits(std::string_view route, std::string_view path, std::string* id) {
  const size_t hole = route.find('{'), close = route.find('}');
  if (hole == std::string_view::npos || close < hole) return route == path;
  const std::string_view prefix = route.substr(0, hole), suffix = route.substr(close + 1);
  if (path.size() <= prefix.size() + suffix.size() || !path.starts_with(prefix) ||
      !path.ends_with(suffix)) {
    return false;
  }
  const std::string_view segment =
      path.substr(prefix.size(), path.size() - prefix.size() - suffix.size());
  if (segment.find_first_of("/:") != std::string_view::npos) return false;
  *id = segment;
  return true;
}

// The session of the path, held or (fleet mode) loaded from the store, and touched: its TTL
// counts from the last request on it, whatever the request and its outcome.
StatusOr<std::shared_ptr<Session>> Find(const RouteRequest& req, RouteContext& ctx) {
  auto s = ctx.registry.Acquire(req.id);
  if (s.ok()) (*s)->Touch();
  return s;
}

// A planning slot for a request's CPU work, held in `*ticket` (kept if it holds one already)
// until the handler returns; the 429 to answer when none comes.
std::optional<HttpResponse> Admit(RouteContext& ctx, std::optional<Admission::Ticket>* ticket) {
  if (*ticket) return std::nullopt;
  auto t = ctx.admission.Enter([] { return HttpFront::ClientGone(); });
  if (!t.ok()) return ErrorResponse(t.status(), 0, 1);
  *ticket = std::move(t).value();
  return std::nullopt;
}

// A 400 for a method the server does not know, naming it (its letters, digits, '-' and '_').
HttpResponse UnknownMethod(std::string_view method) {
  std::string name;
  for (char c : method.substr(0, 16)) {
    name += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '?';
  }
  return Json(400, api::RenderError(InvalidArgumentError("method " + name +
                                                         " is not supported (GET, HEAD, POST, "
                                                         "DELETE)"),
                                    400));
}

// Runs a route's handler: bad_alloc is an exhausted resource, anything else a bug (never a
// crash).
HttpResponse Invoke(const Route& route, const RouteRequest& req, RouteContext& ctx) {
  try {
    return route.handler(req, ctx);
  } catch (const std::bad_alloc&) {
    return ErrorResponse(ResourceExhaustedError("the server is out of memory; retry later"), 0, 5);
  } catch (const std::exception& e) {
    spdlog::error("{} {}: {}", req.http.method, route.path, e.what());
    return ErrorResponse(InternalError("unexpected error"));
  }
}

// Routes a request and runs the checks every route shares before its handler; `route_name` gets
// the name the metrics count it under.
HttpResponse Answer(const HttpRequest& req, RouteContext& ctx, const char** route_name) {
  const ServerOptions& o = ctx.options;
  if (!IsKnownMethod(req.method)) return UnknownMethod(req.method);
  if (req.ambiguous_query) {
    return ErrorResponse(InvalidArgumentError(
        "a request target with a second '?': a '?' in the query is sent as %3F"));
  }
  if (req.path.size() > kMaxPath) {
    return ErrorResponse(InvalidArgumentError("the path is longer than 1024 characters"), 414);
  }
  RouteMatch match = MatchRoute(req.method, req.path);
  *route_name = match.route ? match.route->path : match.allow.empty() ? "unknown" : "other";
  if (match.allow.empty()) {
    std::string message = "no route for " + req.method + " " + req.path.substr(0, 200);
    if (const Route* meant = NearestRoute(req.method, req.path)) {
      message += "; did you mean " + std::string(meant->method) + " " + meant->path + "?";
    }
    return ErrorResponse(NotFoundError(message));
  }
  if (!match.route) {
    HttpResponse res =
        ErrorResponse(Status(StatusCode::kUnimplemented, req.method + " is not allowed here"), 405);
    res.AddHeader("Allow", match.allow);
    return res;
  }
  if (const std::string refusal =
          BrowserRefusal(o, match.route->api, req.Header("Host"), req.Header("Origin"),
                         req.Header("Sec-Fetch-Site"));
      !refusal.empty()) {
    return ErrorResponse(Status(StatusCode::kPermissionDenied, refusal)
                             .WithFieldViolation(refusal.substr(0, refusal.find(':')), "refused"),
                         403);
  }
  // Every body is one JSON document: a multipart one is refused, and its connection closed.
  if (req.Header("Content-Type").starts_with("multipart/form-data")) {
    if (Connection* conn = HttpFront::Current()) conn->must_close = true;
    return ErrorResponse(
        InvalidArgumentError("Content-Type: expected application/json, not multipart"), 415);
  }
  if (match.route->api && !o.api_key.empty() &&
      !SameSecret(req.Header("Authorization"), "Bearer " + o.api_key)) {
    return ErrorResponse(Status(StatusCode::kUnauthenticated,
                                "missing or wrong bearer token (Authorization header)"));
  }
  return Invoke(*match.route, RouteRequest{req, std::move(match.id)}, ctx);
}

}  // namespace

RouteContext::RouteContext(const ServerOptions& o)
    : options(o), registry(o, &metrics), admission(o.plan_slots, o.plan_queue) {}

std::span<const Route> Routes() { return kRoutes; }

RouteMatch MatchRoute(std::string_view method, std::string_view path) {
  RouteMatch match;
  for (const Route& r : kRoutes) {
    std::string id;
    if (!Fits(r.path, path, &id)) continue;
    const std::string_view m = r.method;
    match.allow += (match.allow.empty() ? "" : ", ") + std::string(m);
    if (!match.route && (method == m || (method == "HEAD" && m == "GET"))) {
      match.route = &r;
      match.id = std::move(id);
    }
  }
  return match;
}

namespace {

// Edits (insertions, deletions, substitutions) that turn a into b.
size_t EditDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] != b[j - 1])});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// What follows the last '/' or ':' of a path.
std::string_view LastToken(std::string_view path) {
  const size_t at = path.find_last_of("/:");
  return at == std::string_view::npos ? path : path.substr(at + 1);
}

}  // namespace

const Route* NearestRoute(std::string_view method, std::string_view path) {
  // The path as a template: lower case, no trailing slash, "/v1" in front of an API path without
  // it, and the segment after "/sessions/" as "{id}".
  std::string p;
  for (char c : path.substr(0, 200)) {
    p += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  }
  while (p.size() > 1 && p.back() == '/') p.pop_back();
  if (p.starts_with("/sessions") || p.starts_with("/planners")) p = "/v1" + p;
  if (const size_t at = p.find("/sessions/"); at != std::string::npos) {
    const size_t begin = at + 10;
    const size_t end = std::min(p.find_first_of("/:", begin), p.size());
    if (end > begin) p.replace(begin, end - begin, "{id}");
  }
  const std::string_view token = LastToken(p);
  const size_t near = std::min<size_t>(3, p.size() / 3);  // farther is not a near miss
  const Route* best = nullptr;
  size_t best_distance = 0;
  for (const Route& r : kRoutes) {
    const std::string_view route = r.path, verb = LastToken(route);
    size_t d = EditDistance(p, route);
    // A bare or misspelt verb ("/plan", "/v1/observation"): the route of that verb, the same
    // word before a longer one.
    if (verb.size() >= 4 && token.size() >= 4 && verb != "{id}" &&
        (token.starts_with(verb.substr(0, 4)) || verb.starts_with(token))) {
      d = std::min<size_t>(d, token == verb ? near : near + 1);
    } else if (d > near) {
      continue;
    }
    if (!best || d < best_distance ||
        (d == best_distance && r.method == method && std::string_view(best->path) == route)) {
      best = &r;
      best_distance = d;
    }
  }
  return best;
}

HttpResponse Respond(const HttpRequest& req, RouteContext& ctx) {
  const auto start = std::chrono::steady_clock::now();
  const char* route_name = "-";
  HttpResponse res;
  try {
    res = Answer(req, ctx, &route_name);
  } catch (...) {
    res = ErrorResponse(InternalError("unexpected error"));
  }
  // No response is to be read as anything but its Content-Type (a JSON error echoing a field
  // path is not HTML).
  if (!res.HasHeader("X-Content-Type-Options")) res.AddHeader("X-Content-Type-Options", "nosniff");
  // Counted before it is written, so that a client that reads /metrics next sees its previous
  // request.
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ctx.metrics.ObserveRequest(req.method.empty() ? "-" : req.method.substr(0, 16), route_name,
                             res.status, seconds);
  return res;
}

HttpResponse ErrorResponse(const Status& s, int http_status, int retry_after) {
  if (retry_after == 0 && s.code() == StatusCode::kUnavailable) retry_after = 1;
  const int code = http_status > 0 ? http_status : api::HttpStatusOf(s.code());
  // A 429 naming a field is the request's own limit (a session's planning budget), which no
  // retry clears: it names no time.
  if (retry_after == 0 && code == 429 && s.field_violations().empty()) retry_after = 5;
  HttpResponse res = Json(code, api::RenderError(s, code, retry_after));
  if (retry_after > 0) res.AddHeader("Retry-After", std::to_string(retry_after));
  return res;
}

// Answers from what the store last said (never waits for it): 503 while it is unavailable.
HttpResponse Health(const RouteRequest&, RouteContext& ctx) {
  const StoreHealth store = ctx.registry.store_health();
  const api::HealthView h{ctx.registry.store()->backend(), store.ok, store.message,
                          ctx.registry.size(), kVersion};
  HttpResponse res = Json(store.ok ? 200 : 503, api::RenderHealth(h));
  if (!store.ok) res.AddHeader("Retry-After", "1");
  return res;
}

HttpResponse MetricsText(const RouteRequest&, RouteContext& ctx) {
  HttpResponse res;
  res.SetContent(ctx.metrics.Render(ctx.admission.running(), ctx.admission.waiting()),
                 "text/plain; version=0.0.4; charset=utf-8");
  return res;
}

HttpResponse CreateSession(const RouteRequest& request, RouteContext& ctx) {
  const std::string& body = request.http.body;
  const ServerOptions& o = ctx.options;
  // Target photos are decoded while the body is parsed: CPU work (a 400 kB body of photos took
  // 1.7 s), admitted like a plan.
  std::optional<Admission::Ticket> ticket;
  if (body.size() > kAdmittedBodyBytes) {
    if (auto refused = Admit(ctx, &ticket)) return *refused;
  }
  auto req = api::ParseCreateSession(body, o.limits, o.planners);
  if (!req.ok()) return ErrorResponse(req.status());
  if (req->ttl_seconds && *req->ttl_seconds > o.session_ttl_seconds) {
    return ErrorResponse(InvalidFieldError(
        "ttlSeconds", "must be <= " + std::to_string(static_cast<int64_t>(o.session_ttl_seconds)) +
                          " (the server's --session-ttl)"));
  }
  if (Status full = ctx.registry.CheckCapacity(); !full.ok()) return ErrorResponse(full, 0, 5);
  auto world = api::BuildWorld(req->world, o.limits);
  if (!world.ok()) return ErrorResponse(world.status());
  // A planner that takes a filter model plans with the server's default model unless the request
  // names one ("": none).
  if (req->planner.takes_model && !req->planner.model_given) {
    req->planner.model = ctx.default_model;
  }
  SessionConfig config{
      Registry::NewId(),
      req->display_name,
      req->planner,
      req->target,
      req->seed.value_or(std::random_device{}()) ^ (uint64_t{std::random_device{}()} << 32),
      req->ttl_seconds.value_or(o.session_ttl_seconds)};
  if (req->seed) config.seed = *req->seed;
  auto session = Session::Create(std::move(config), std::move(world).value(), ctx.samplers,
                                 o.planners, ctx.registry.session_limits());
  if (!session.ok()) return ErrorResponse(api::ToWire(session.status()));
  auto added = ctx.registry.Add(std::move(session).value());
  if (!added.ok()) return ErrorResponse(added.status(), 0, 5);
  spdlog::info("session {} created (planner {})", (*added)->id(), req->planner.name);
  return Json(200, api::RenderSession((*added)->View()));
}

HttpResponse ListSessions(const RouteRequest& request, RouteContext& ctx) {
  auto param = [&](const char* key) -> std::optional<std::string> {
    if (!request.http.HasParam(key)) return std::nullopt;
    return request.http.Param(key);
  };
  auto list = api::ParseList(param("pageSize"), param("pageToken"));
  if (!list.ok()) return ErrorResponse(list.status());
  std::string next;
  auto views = ctx.registry.Page(list->page_token, list->page_size, &next);
  if (!views.ok()) return ErrorResponse(views.status());
  return Json(200, api::RenderSessionList(*views, next));
}

// The planners sessions may use, with every option's default (a planner that takes a filter model
// lists Net_sam's filter.* options too).
HttpResponse ListPlanners(const RouteRequest&, RouteContext& ctx) {
  std::vector<api::PlannerView> views;
  const object_search::SearchParams params;
  for (const object_search::PlannerEntry& e : ctx.options.planners.entries()) {
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
  return Json(200, api::RenderPlanners(views));
}

HttpResponse GetSession(const RouteRequest& request, RouteContext& ctx) {
  auto s = Find(request, ctx);
  if (!s.ok()) return ErrorResponse(s.status());
  return Json(200, api::RenderSession((*s)->View()));
}

HttpResponse DeleteSession(const RouteRequest& request, RouteContext& ctx) {
  if (Status st = ctx.registry.Remove(request.id); !st.ok()) return ErrorResponse(st);
  spdlog::info("session {} deleted", request.id);
  return Json(200, api::RenderEmpty());
}

HttpResponse PlanSession(const RouteRequest& request, RouteContext& ctx) {
  const ServerOptions& o = ctx.options;
  const auto start = std::chrono::steady_clock::now();
  auto plan = api::ParsePlan(request.http.body, o.limits);
  if (!plan.ok()) return ErrorResponse(plan.status());
  auto found = Find(request, ctx);
  if (!found.ok()) return ErrorResponse(found.status());
  const std::shared_ptr<Session>& s = *found;
  // The budget as used: the request's, the default when it gives none, and never without a
  // wall-clock cap (a budget of simulations or CPU time alone is capped at the maximum).
  Budget budget{plan->time_ms.value_or(0.0), plan->simulations.value_or(0),
                plan->cpu_ms.value_or(0.0)};
  if (!plan->time_ms && !plan->cpu_ms && !plan->simulations) {
    budget.time_ms = o.limits.default_plan_ms;
  }
  if (budget.time_ms == 0.0) budget.time_ms = o.limits.max_plan_ms;
  // The session admits itself once it is claimed (a second plan on it is refused at once, and a
  // session waiting in the queue is in use, not idle); a plan of several search threads takes a
  // slot for each (at most all of them).
  bool queue_full = false;
  Session::Admit admit = [&ctx, &queue_full](const std::function<bool()>& give_up,
                                             int threads) -> StatusOr<Session::SlotHold> {
    auto ticket = ctx.admission.Enter(give_up, threads);
    queue_full = ticket.status().code() == StatusCode::kResourceExhausted;
    if (!ticket.ok()) return ticket.status();
    return Session::SlotHold(std::make_shared<Admission::Ticket>(std::move(ticket).value()));
  };
  StatusOr<api::PlanReply> reply = Status(StatusCode::kInternal, "not planned");
  {
    BatchScheduling batch;
    // The search's own threads poll this too: the connection is captured, not the handler
    // thread's.
    const Connection* connection = HttpFront::Current();
    reply = s->Plan(
        budget, [connection] { return HttpFront::ClientGone(connection); }, ctx.registry.store(),
        admit);
  }
  if (!reply.ok()) {
    // Another replica saved the session first (or the save failed): this plan's time still
    // counts against the session's lifetime budget, racing replicas included.
    if (s->stale()) ctx.registry.KeepUsageOf(s);
    return ErrorResponse(api::ToWire(reply.status()), 0, queue_full ? 1 : 0);
  }
  reply->summary.budget_given = Budget{plan->time_ms.value_or(0.0), plan->simulations.value_or(0),
                                       plan->cpu_ms.value_or(0.0)};
  const double total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double planning = reply->stats.elapsed_ms / 1000.0;
  ctx.metrics.ObservePlan(planning, std::max(0.0, total - planning), reply->stats.simulations);
  return Json(200, api::RenderPlan(*reply));
}

HttpResponse ObserveSession(const RouteRequest& request, RouteContext& ctx) {
  const std::string& body = request.http.body;
  // The session first: parsing decodes raw images, CPU work not spent on a session that does not
  // exist.
  auto s = Find(request, ctx);
  if (!s.ok()) return ErrorResponse(s.status());
  // Raw sensor data run perception, and their images are decoded while the body is parsed
  // (before the action id is checked): CPU work, admitted like a plan, a large body before it is
  // parsed.
  std::optional<Admission::Ticket> ticket;
  if (body.size() > kAdmittedBodyBytes) {
    if (auto refused = Admit(ctx, &ticket)) return *refused;
  }
  auto observe = api::ParseObserve(body, ctx.options.limits);
  if (!observe.ok()) return ErrorResponse(observe.status());
  if (observe->frame) {
    if (auto refused = Admit(ctx, &ticket)) return *refused;
  }
  auto reply = (*s)->Observe(std::move(observe).value(), ctx.registry.store());
  if (!reply.ok()) return ErrorResponse(api::ToWire(reply.status()));
  HttpResponse res = Json(200, api::RenderObserve(*reply));
  ReleaseFreedMemory();  // the planner kept only the subtree of what was observed
  return res;
}

HttpResponse GetBelief(const RouteRequest& request, RouteContext& ctx) {
  std::optional<std::string> format;
  if (request.http.HasParam("format")) format = request.http.Param("format");
  auto f = api::ParseBeliefFormat(format);
  if (!f.ok()) return ErrorResponse(f.status());
  auto s = Find(request, ctx);
  if (!s.ok()) return ErrorResponse(s.status());
  const auto world = (*s)->Belief();
  const api::SessionView view = (*s)->View();
  if (*f == api::BeliefFormat::kJson) return Json(200, api::RenderBelief(*world, &view));
  // Rendering a picture is CPU work (up to half a second for a large world): admitted like a
  // plan, so that pictures cannot occupy every request thread.
  std::optional<Admission::Ticket> ticket;
  if (auto refused = Admit(ctx, &ticket)) return *refused;
  auto png = api::RenderBeliefPng(*world, &view);
  if (!png.ok()) return ErrorResponse(png.status());
  HttpResponse res;
  res.SetContent(std::move(png).value(), "image/png");
  return res;
}

HttpResponse GetSteps(const RouteRequest& request, RouteContext& ctx) {
  auto s = Find(request, ctx);
  if (!s.ok()) return ErrorResponse(s.status());
  return Json(200, api::RenderSteps((*s)->Steps(), (*s)->Belief().get()));
}

HttpResponse GetConsoleFile(const RouteRequest& request, RouteContext&) {
  return ServeConsole(request.http.path);
}

}  // namespace npfkct::server
