// The web console (GET /ui): static files from server/console/, compiled into the server at
// build time (cmake/npfkct_embed.cmake), so that an installed server carries its console and the
// page can never drift from the server it talks to. The files are public: the page asks for the
// API key and sends it with its own requests.
#pragma once

// server.h first: Eigen must come before httplib, which pulls in <resolv.h> and its `_res` macro.
#include "npfkct/server/server.h"
// clang-format off
#include <httplib.h>
// clang-format on

#include <string_view>

namespace npfkct::server {

/// One static file of the console.
struct ConsoleFile {
  std::string_view name;          ///< File name under /ui/ ("index.html", "console.js", ...).
  std::string_view content_type;  ///< From the file's extension.
  std::string_view body;
};

/// The console file a request path names ("/ui" and "/ui/" are index.html); null when none.
const ConsoleFile* FindConsoleFile(std::string_view path);

/// Answers a GET of the console: the file with a strict Content-Security-Policy (scripts and
/// styles from the server only, no inline code), or 404 NOT_FOUND.
void ServeConsole(const httplib::Request& req, httplib::Response& res);

}  // namespace npfkct::server
