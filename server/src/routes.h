// The server's routes: one table of path templates ("/v1/sessions/{id}:plan"); a request's route
// matched once (method and path, its {id} taken out), which the checks every route shares (path
// length, method, browser refusal, API key), the metrics and the handler all use; and the
// handlers, free functions from a typed request and the server's state to a typed response.
//
// The HTTP front (http_front.h) calls Respond() on a worker thread for each complete request;
// unit tests call Respond(), or a handler, without a socket. Request and reply bodies are the API
// layer's business (npfkct/api).
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "admission.h"
#include "http_message.h"
#include "npfkct/server/metrics.h"
#include "npfkct/server/server.h"
#include "registry.h"

namespace npfkct::server {

/// What the handlers work on: a server's settings and state.
struct RouteContext {
  /// `options` as Resolved() gives them.
  explicit RouteContext(const ServerOptions& options);

  ServerOptions options;
  SamplerFactory samplers;
  std::string default_model;  ///< Of sessions that name none; empty when there is none.
  Metrics metrics;
  Registry registry;
  Admission admission;
};

/// A request as its route's handler gets it.
struct RouteRequest {
  const HttpRequest& http;
  std::string id;  ///< The path's {id} (or {file}); empty for a route without one.
};

/// A route's handler.
using RouteHandler = HttpResponse (*)(const RouteRequest& request, RouteContext& context);

/// A route: a method and a path template.
struct Route {
  const char* method;
  /// The path: literal, with at most one "{id}" (or "{file}") standing for one non-empty segment
  /// without '/' or ':'. Also the route's name in the metrics.
  const char* path;
  /// An API route: it needs the API key, and a browser's page of another site is refused it.
  bool api;
  RouteHandler handler;
};

/// Every route of the server; a method and a path match one at most.
std::span<const Route> Routes();

/// The route of a request, matched once.
struct RouteMatch {
  /// The route of the method and path (HEAD matches GET); null when there is none.
  const Route* route = nullptr;
  std::string id;     ///< The path's {id} or {file}.
  std::string allow;  ///< The methods of the routes the path fits ("GET, DELETE"); empty: none.
};
RouteMatch MatchRoute(std::string_view method, std::string_view path);

/// The route a request no route fits probably meant (a slash for the colon of a custom verb, a
/// missing "/v1", a trailing slash, a misspelt or bare verb such as "/plan"); null when none is
/// close. Only the first 200 characters of the path are read.
const Route* NearestRoute(std::string_view method, std::string_view path);

/// Answers a request: a method the server does not know or an ambiguous target 400, a path over
/// 1,024 characters 414, a path no route fits 404, a method no route of the path has 405 (with
/// Allow), a browser's refused request 403, a multipart body 415, an API route without the API
/// key 401; else its handler answers (bad_alloc: 429; any other exception: 500). Every answer is
/// nosniff, and counted in the metrics (method, route, status, time) before the front writes it.
HttpResponse Respond(const HttpRequest& request, RouteContext& context);

/// The body of an error answer, with its Retry-After: UNAVAILABLE is worth retrying in a second;
/// a 429 of the server's resources in 5 s unless `retry_after` says otherwise.
HttpResponse ErrorResponse(const Status& status, int http_status = 0, int retry_after = 0);

// The handlers, each of one route of Routes().
HttpResponse Health(const RouteRequest& request, RouteContext& context);
HttpResponse MetricsText(const RouteRequest& request, RouteContext& context);
HttpResponse CreateSession(const RouteRequest& request, RouteContext& context);
HttpResponse ListSessions(const RouteRequest& request, RouteContext& context);
HttpResponse ListPlanners(const RouteRequest& request, RouteContext& context);
HttpResponse GetSession(const RouteRequest& request, RouteContext& context);
HttpResponse DeleteSession(const RouteRequest& request, RouteContext& context);
HttpResponse PlanSession(const RouteRequest& request, RouteContext& context);
HttpResponse ObserveSession(const RouteRequest& request, RouteContext& context);
HttpResponse GetBelief(const RouteRequest& request, RouteContext& context);
HttpResponse GetSteps(const RouteRequest& request, RouteContext& context);
HttpResponse GetConsoleFile(const RouteRequest& request, RouteContext& context);

}  // namespace npfkct::server
