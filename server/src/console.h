// The web console (GET /ui): static files from server/console/, compiled into the server at
// build time (cmake/npfkct_embed.cmake), so that an installed server carries its console and the
// page can never drift from the server it talks to. The files are public: the page asks for the
// API key and sends it with its own requests.
#pragma once

#include <string_view>

#include "http_message.h"

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
HttpResponse ServeConsole(std::string_view path);

}  // namespace npfkct::server
