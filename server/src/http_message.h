// Typed HTTP/1.1 messages of the server: a request as the front (http_front.h) reads it, once,
// from the bytes it framed, and a response as a handler makes it, written by the front.
//
// They keep the reading and writing of cpp-httplib 0.11.4, which served the API before, so that
// clients see the same answers: header names compare case-insensitively; header values are
// trimmed and percent-decoded, and empty ones dropped; the path and the query parameters are
// percent-decoded; a response carries Content-Length, Connection: close or Keep-Alive, and a body
// compressed (brotli or gzip) when its type is text and the request's Accept-Encoding names one.
#pragma once

#include <cstddef>
#include <map>
#include <string>
#include <string_view>

namespace npfkct::server {

/// Orders header names without regard to case (RFC 9110 5.1).
struct CaseInsensitiveLess {
  using is_transparent = void;
  bool operator()(std::string_view a, std::string_view b) const;
};
/// Header fields in name order, any number of each name, in the order they came.
using HttpHeaders = std::multimap<std::string, std::string, CaseInsensitiveLess>;
/// Query parameters, any number of each name.
using HttpParams = std::multimap<std::string, std::string, std::less<>>;

/// A request, read once from its head and body.
struct HttpRequest {
  std::string method;   ///< As sent: a token, not necessarily a method the server knows.
  std::string target;   ///< As sent (origin form: a path and a query).
  std::string version;  ///< "HTTP/1.1" or "HTTP/1.0".
  std::string path;     ///< The target's path, percent-decoded, without query and fragment.
  HttpParams params;    ///< The query's parameters, percent-decoded ('+' read as a space).
  /// The target holds a second query ('?' in the query): refused (400), as httplib did.
  bool ambiguous_query = false;
  HttpHeaders headers;  ///< Trimmed and percent-decoded values; empty values are dropped.
  std::string body;     ///< The body, de-chunked; empty without Content-Length or chunking.

  /// Whether a header of that name has a value.
  bool HasHeader(std::string_view name) const;
  /// The first value of a header; empty when there is none.
  std::string Header(std::string_view name) const;
  bool HasParam(std::string_view name) const;
  /// The first value of a query parameter; empty when there is none.
  std::string Param(std::string_view name) const;
};

/// A response, as a handler makes it; the front adds what the connection needs.
struct HttpResponse {
  int status = 200;
  HttpHeaders headers;
  std::string body;

  bool HasHeader(std::string_view name) const;
  std::string Header(std::string_view name) const;
  /// Adds a header (another value for a name already there); a name or value holding CR or LF
  /// is dropped.
  void AddHeader(std::string name, std::string value);
  /// Sets the body and its Content-Type (replacing any).
  void SetContent(std::string content, std::string content_type);
};

/// The reason phrase of a status code ("Internal Server Error" for codes it does not know).
const char* ReasonPhrase(int status);

/// Percent-decodes `s`: %XX, and %uXXXX as UTF-8; with `plus_as_space`, '+' is a space.
/// Malformed escapes are kept as they are.
std::string DecodeUrl(std::string_view s, bool plus_as_space);

/// Fills the path, query parameters and ambiguous_query of `request` from `target` (the fragment
/// dropped; parameters repeated with the same name and value kept once).
void ReadTarget(std::string_view target, HttpRequest* request);

/// How a response is written on its connection.
struct ResponseFraming {
  bool close = false;          ///< Connection: close (else a Keep-Alive header).
  int keep_alive_timeout = 5;  ///< Keep-Alive: timeout=..., in seconds.
  int keep_alive_max = 100;    ///< ..., max=... (requests per connection).
};

/// Prepares `response` to be written as the answer to `request`: compresses its body when the
/// request accepts it (brotli, else gzip) and its type is text (text/*, JSON, JavaScript, XML,
/// SVG); adds Content-Length, Content-Type (text/plain for an untyped body), Connection: close
/// or Keep-Alive, and Accept-Ranges to an answer to HEAD.
void FinishResponse(const HttpRequest& request, const ResponseFraming& framing,
                    HttpResponse* response);

/// The status line and header lines of a response, up to and including the blank line.
std::string ResponseHead(const HttpResponse& response);

/// Whether a method is one httplib read (GET, HEAD, POST, PUT, DELETE, CONNECT, OPTIONS, TRACE,
/// PATCH, PRI); the server answers others 400.
bool IsKnownMethod(std::string_view method);

}  // namespace npfkct::server
