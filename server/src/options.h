// The server's settings as the server runs with them: machine-dependent defaults resolved, and
// the HTTP front's share of them.
#pragma once

#include <string>
#include <string_view>

#include "http_front.h"
#include "npfkct/server/server.h"

namespace npfkct::server {

/// `o` with the defaults that depend on the machine filled in (plan slots: one per core; the
/// queue: twice the slots; request threads: enough for every slot and queued plan, plus four).
ServerOptions Resolved(ServerOptions o);

/// Whether `host` (as `--host` takes it) accepts connections from this machine only: "localhost",
/// an IPv4 address in 127.0.0.0/8 or the IPv6 loopback.
bool IsLoopbackHost(const std::string& host);

/// Why a request must be refused as one a web page made on a browser's behalf (empty: it may go
/// on). Any route of a server without an API key bound to loopback: a `Host` header that names
/// neither localhost nor a loopback address (a page's DNS rebinding). An API route: a
/// `Sec-Fetch-Site` of cross-site or same-site, or an `Origin` whose host name is not the `Host`
/// header's (cross-site request forgery; ports are not compared, since a proxy's `Host` may drop
/// them). Clients that are not browsers send neither `Origin` nor `Sec-Fetch-Site`.
std::string BrowserRefusal(const ServerOptions& o, bool api_route, std::string_view host_header,
                           std::string_view origin, std::string_view fetch_site);

/// The HTTP front's settings of a server.
HttpFrontOptions FrontOptions(const ServerOptions& o);

/// The bodies of the errors the front answers itself: the API's error body with the canonical
/// status of each HTTP status (401 UNAUTHENTICATED, 404 NOT_FOUND, 408 DEADLINE_EXCEEDED,
/// 413/429/431 RESOURCE_EXHAUSTED, 416 OUT_OF_RANGE, 500 INTERNAL, else INVALID_ARGUMENT).
HttpFront::ErrorRenderer FrontErrors();

}  // namespace npfkct::server
