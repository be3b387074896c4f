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

}  // namespace npfkct::server
