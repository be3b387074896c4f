// The server's settings as the server runs with them: machine-dependent defaults resolved, and
// the HTTP front's share of them.
#pragma once

// server.h first: Eigen must come before httplib, which pulls in <resolv.h> and its `_res` macro.
#include "npfkct/server/server.h"
// clang-format off
#include "http_front.h"
// clang-format on

namespace npfkct::server {

/// `o` with the defaults that depend on the machine filled in (plan slots: one per core; the
/// queue: twice the slots; request threads: enough for every slot and queued plan, plus four).
ServerOptions Resolved(ServerOptions o);

/// The HTTP front's settings of a server.
HttpFrontOptions FrontOptions(const ServerOptions& o);

/// The bodies of the errors the front answers itself: the API's error body with the canonical
/// status of each HTTP status (408 DEADLINE_EXCEEDED, 413/429/431 RESOURCE_EXHAUSTED, 416
/// OUT_OF_RANGE, else INVALID_ARGUMENT).
HttpFront::ErrorRenderer FrontErrors();

/// httplib's error handler: the errors httplib answers itself (a malformed request line, a URI
/// too long) get the API's error body too.
httplib::Server::HandlerWithResponse HttpErrorBodies();

}  // namespace npfkct::server
