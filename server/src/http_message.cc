#include "http_message.h"

#include <brotli/encode.h>
#include <zlib.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <set>
#include <utility>

namespace npfkct::server {
namespace {

bool IsSpaceOrTab(char c) { return c == ' ' || c == '\t'; }

// `s` without the spaces and tabs at either end.
std::string_view TrimSpaces(std::string_view s) {
  while (!s.empty() && IsSpaceOrTab(s.front())) s.remove_prefix(1);
  while (!s.empty() && IsSpaceOrTab(s.back())) s.remove_suffix(1);
  return s;
}

// Calls f with each part of `s` between the separators `d`, trimmed, skipping empty parts (as
// httplib split a target and its query).
template <typename F>
void ForEachPart(std::string_view s, char d, F f) {
  for (size_t a = 0; a <= s.size();) {
    const size_t b = std::min(s.find(d, a), s.size());
    const std::string_view part = TrimSpaces(s.substr(a, b - a));
    if (!part.empty()) f(part);
    a = b + 1;
  }
}

// The value of `count` hex digits of `s` from `i`; false when one is missing or not a digit.
bool HexValue(std::string_view s, size_t i, size_t count, int* value) {
  if (i + count > s.size()) return false;
  *value = 0;
  for (size_t k = i; k < i + count; ++k) {
    const char c = s[k];
    int v;
    if (c >= '0' && c <= '9') {
      v = c - '0';
    } else if (c >= 'A' && c <= 'F') {
      v = c - 'A' + 10;
    } else if (c >= 'a' && c <= 'f') {
      v = c - 'a' + 10;
    } else {
      return false;
    }
    *value = *value * 16 + v;
  }
  return true;
}

// Appends the UTF-8 of a code point below 0x10000 (nothing for a surrogate).
void AppendUtf8(int code, std::string* out) {
  if (code < 0x80) {
    out->push_back(static_cast<char>(code));
  } else if (code < 0x800) {
    out->push_back(static_cast<char>(0xC0 | ((code >> 6) & 0x1F)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
  } else if (code < 0xD800 || code >= 0xE000) {
    out->push_back(static_cast<char>(0xE0 | ((code >> 12) & 0xF)));
    out->push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3F)));
    out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
  }
}

// Whether a response of this Content-Type is worth compressing (httplib's list).
bool Compressible(std::string_view type) {
  static constexpr std::string_view kTypes[] = {"image/svg+xml",        "application/javascript",
                                                "application/json",     "application/xml",
                                                "application/protobuf", "application/xhtml+xml"};
  if (std::find(std::begin(kTypes), std::end(kTypes), type) != std::end(kTypes)) return true;
  return type.starts_with("text/") && type != "text/event-stream";
}

bool Gzip(const std::string& in, std::string* out) {
  z_stream z{};
  if (deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 31, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    return false;
  }
  out->resize(deflateBound(&z, static_cast<uLong>(in.size())));
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out->data());
  z.avail_out = static_cast<uInt>(out->size());
  const int ret = deflate(&z, Z_FINISH);
  out->resize(z.total_out);
  deflateEnd(&z);
  return ret == Z_STREAM_END;
}

bool Brotli(const std::string& in, std::string* out) {
  size_t size = BrotliEncoderMaxCompressedSize(in.size());
  if (size == 0) return false;
  out->resize(size);
  if (!BrotliEncoderCompress(BROTLI_DEFAULT_QUALITY, BROTLI_DEFAULT_WINDOW, BROTLI_DEFAULT_MODE,
                             in.size(), reinterpret_cast<const uint8_t*>(in.data()), &size,
                             reinterpret_cast<uint8_t*>(out->data()))) {
    return false;
  }
  out->resize(size);
  return true;
}

// Compresses the body as the request accepts (httplib looked for "br", then "gzip", anywhere in
// the first Accept-Encoding value, q=0 or not).
void Compress(const HttpRequest& request, HttpResponse* response) {
  if (response->body.empty() || !Compressible(response->Header("Content-Type"))) return;
  const std::string accept = request.Header("Accept-Encoding");
  std::string compressed;
  // Bodies past zlib's 32-bit counts are sent as they are.
  if (response->body.size() >= (size_t{1} << 31)) return;
  if (accept.find("br") != std::string::npos) {
    if (Brotli(response->body, &compressed)) {
      response->body.swap(compressed);
      response->AddHeader("Content-Encoding", "br");
    }
  } else if (accept.find("gzip") != std::string::npos) {
    if (Gzip(response->body, &compressed)) {
      response->body.swap(compressed);
      response->AddHeader("Content-Encoding", "gzip");
    }
  }
}

template <typename Map>
std::string FirstValue(const Map& map, std::string_view name) {
  const auto it = map.find(name);
  return it == map.end() ? std::string() : it->second;
}

// The reason phrases httplib wrote, which clients saw before the front wrote responses.
constexpr std::pair<int, const char*> kPhrases[] = {{100, "Continue"},
                                                    {101, "Switching Protocol"},
                                                    {102, "Processing"},
                                                    {103, "Early Hints"},
                                                    {200, "OK"},
                                                    {201, "Created"},
                                                    {202, "Accepted"},
                                                    {203, "Non-Authoritative Information"},
                                                    {204, "No Content"},
                                                    {205, "Reset Content"},
                                                    {206, "Partial Content"},
                                                    {207, "Multi-Status"},
                                                    {208, "Already Reported"},
                                                    {226, "IM Used"},
                                                    {300, "Multiple Choice"},
                                                    {301, "Moved Permanently"},
                                                    {302, "Found"},
                                                    {303, "See Other"},
                                                    {304, "Not Modified"},
                                                    {305, "Use Proxy"},
                                                    {306, "unused"},
                                                    {307, "Temporary Redirect"},
                                                    {308, "Permanent Redirect"},
                                                    {400, "Bad Request"},
                                                    {401, "Unauthorized"},
                                                    {402, "Payment Required"},
                                                    {403, "Forbidden"},
                                                    {404, "Not Found"},
                                                    {405, "Method Not Allowed"},
                                                    {406, "Not Acceptable"},
                                                    {407, "Proxy Authentication Required"},
                                                    {408, "Request Timeout"},
                                                    {409, "Conflict"},
                                                    {410, "Gone"},
                                                    {411, "Length Required"},
                                                    {412, "Precondition Failed"},
                                                    {413, "Payload Too Large"},
                                                    {414, "URI Too Long"},
                                                    {415, "Unsupported Media Type"},
                                                    {416, "Range Not Satisfiable"},
                                                    {417, "Expectation Failed"},
                                                    {418, "I'm a teapot"},
                                                    {421, "Misdirected Request"},
                                                    {422, "Unprocessable Entity"},
                                                    {423, "Locked"},
                                                    {424, "Failed Dependency"},
                                                    {425, "Too Early"},
                                                    {426, "Upgrade Required"},
                                                    {428, "Precondition Required"},
                                                    {429, "Too Many Requests"},
                                                    {431, "Request Header Fields Too Large"},
                                                    {451, "Unavailable For Legal Reasons"},
                                                    {501, "Not Implemented"},
                                                    {502, "Bad Gateway"},
                                                    {503, "Service Unavailable"},
                                                    {504, "Gateway Timeout"},
                                                    {505, "HTTP Version Not Supported"},
                                                    {506, "Variant Also Negotiates"},
                                                    {507, "Insufficient Storage"},
                                                    {508, "Loop Detected"},
                                                    {510, "Not Extended"},
                                                    {511, "Network Authentication Required"}};

}  // namespace

bool CaseInsensitiveLess::operator()(std::string_view a, std::string_view b) const {
  return std::lexicographical_compare(
      a.begin(), a.end(), b.begin(), b.end(),
      [](unsigned char x, unsigned char y) { return std::tolower(x) < std::tolower(y); });
}

bool HttpRequest::HasHeader(std::string_view name) const {
  return headers.find(name) != headers.end();
}
std::string HttpRequest::Header(std::string_view name) const { return FirstValue(headers, name); }
bool HttpRequest::HasParam(std::string_view name) const {
  return params.find(name) != params.end();
}
std::string HttpRequest::Param(std::string_view name) const { return FirstValue(params, name); }

bool HttpResponse::HasHeader(std::string_view name) const {
  return headers.find(name) != headers.end();
}
std::string HttpResponse::Header(std::string_view name) const { return FirstValue(headers, name); }
void HttpResponse::AddHeader(std::string name, std::string value) {
  if (name.find_first_of("\r\n") != std::string::npos ||
      value.find_first_of("\r\n") != std::string::npos) {
    return;
  }
  headers.emplace(std::move(name), std::move(value));
}
void HttpResponse::SetContent(std::string content, std::string content_type) {
  body = std::move(content);
  headers.erase("Content-Type");
  AddHeader("Content-Type", std::move(content_type));
}

const char* ReasonPhrase(int status) {
  for (const auto& [code, phrase] : kPhrases) {
    if (code == status) return phrase;
  }
  return "Internal Server Error";
}

std::string DecodeUrl(std::string_view s, bool plus_as_space) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    int value = 0;
    if (s[i] == '%' && i + 1 < s.size() && s[i + 1] == 'u') {
      if (HexValue(s, i + 2, 4, &value)) {
        AppendUtf8(value, &out);
        i += 5;
      } else {
        out.push_back('%');
      }
    } else if (s[i] == '%' && i + 1 < s.size()) {
      if (HexValue(s, i + 1, 2, &value)) {
        out.push_back(static_cast<char>(value));
        i += 2;
      } else {
        out.push_back('%');
      }
    } else if (plus_as_space && s[i] == '+') {
      out.push_back(' ');
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

void ReadTarget(std::string_view target, HttpRequest* request) {
  target = target.substr(0, target.find('#'));
  int part = 0;
  ForEachPart(target, '?', [&](std::string_view s) {
    if (part == 0) {
      request->path = DecodeUrl(s, false);
    } else if (part == 1) {
      std::set<std::string_view> seen;  // a repeated "name=value" counts once
      ForEachPart(s, '&', [&](std::string_view pair) {
        if (!seen.insert(pair).second) return;
        // The first part is the name, the last the value ("a=b=c": a is c).
        std::string_view name, value;
        ForEachPart(pair, '=', [&](std::string_view p) { (name.empty() ? name : value) = p; });
        if (!name.empty()) {
          request->params.emplace(DecodeUrl(name, true), DecodeUrl(value, true));
        }
      });
    }
    ++part;
  });
  request->ambiguous_query = part > 2;
}

void FinishResponse(const HttpRequest& request, const ResponseFraming& framing,
                    HttpResponse* response) {
  Compress(request, response);
  if (framing.close) {
    response->AddHeader("Connection", "close");
  } else {
    response->AddHeader("Keep-Alive", "timeout=" + std::to_string(framing.keep_alive_timeout) +
                                          ", max=" + std::to_string(framing.keep_alive_max));
  }
  if (!response->HasHeader("Content-Type") && !response->body.empty()) {
    response->AddHeader("Content-Type", "text/plain");
  }
  if (!response->HasHeader("Content-Length")) {
    response->AddHeader("Content-Length", std::to_string(response->body.size()));
  }
  if (request.method == "HEAD" && !response->HasHeader("Accept-Ranges")) {
    response->AddHeader("Accept-Ranges", "bytes");
  }
}

std::string ResponseHead(const HttpResponse& response) {
  std::string head =
      "HTTP/1.1 " + std::to_string(response.status) + " " + ReasonPhrase(response.status) + "\r\n";
  for (const auto& [name, value] : response.headers) head += name + ": " + value + "\r\n";
  head += "\r\n";
  return head;
}

bool IsKnownMethod(std::string_view method) {
  static constexpr std::string_view kMethods[] = {"GET",     "HEAD",    "POST",  "PUT",   "DELETE",
                                                  "CONNECT", "OPTIONS", "TRACE", "PATCH", "PRI"};
  return std::find(std::begin(kMethods), std::end(kMethods), method) != std::end(kMethods);
}

}  // namespace npfkct::server
