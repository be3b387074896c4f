// The typed messages without a socket: the target's path and query as the routes read them,
// percent-decoding, and responses as they are written (headers, compression).
#include "http_message.h"

#include <gtest/gtest.h>
#include <zlib.h>

namespace npfkct::server {
namespace {

TEST(ReadTarget, PathAndQueryAreDecodedAsTheRoutesHaveAlwaysReadThem) {
  HttpRequest req;
  ReadTarget("/v1/sessi%6Fns?pageSize=1&pageSize=2&pageToken=a+b%2F&x=1=2#frag", &req);
  EXPECT_EQ(req.path, "/v1/sessions");
  EXPECT_FALSE(req.ambiguous_query);
  EXPECT_EQ(req.Param("pageSize"), "1");  // the first of two
  EXPECT_EQ(req.params.count("pageSize"), 2u);
  EXPECT_EQ(req.Param("pageToken"), "a b/");
  EXPECT_EQ(req.Param("x"), "2");  // "x=1=2": the last part is the value
  EXPECT_FALSE(req.HasParam("frag"));

  HttpRequest repeated;
  ReadTarget("/p?a=1&a=1&a=2", &repeated);
  EXPECT_EQ(repeated.params.count("a"), 2u);  // the same pair counts once

  HttpRequest ambiguous;
  ReadTarget("/v1/sessions?a=1?b=2", &ambiguous);
  EXPECT_TRUE(ambiguous.ambiguous_query);
  HttpRequest empty_parts;
  ReadTarget("/v1/sessions??pageSize=x", &empty_parts);  // an empty part is skipped
  EXPECT_FALSE(empty_parts.ambiguous_query);
  EXPECT_EQ(empty_parts.Param("pageSize"), "x");
}

TEST(DecodeUrl, EscapesPlusAndMalformedEscapes) {
  EXPECT_EQ(DecodeUrl("a%41%u0042%u00e9+", false), "aAB\xc3\xa9+");
  EXPECT_EQ(DecodeUrl("a+b", true), "a b");
  EXPECT_EQ(DecodeUrl("%", false), "%");
  EXPECT_EQ(DecodeUrl("%4", false), "%4");
  EXPECT_EQ(DecodeUrl("%zz%u12", false), "%zz%u12");
  EXPECT_EQ(DecodeUrl("%00", false), std::string(1, '\0'));
  EXPECT_EQ(DecodeUrl("%uD800x", false), "x");  // a lone surrogate decodes to nothing
}

std::string Gunzip(const std::string& in) {
  z_stream z{};
  inflateInit2(&z, 31);
  std::string out(1 << 16, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  inflate(&z, Z_FINISH);
  out.resize(z.total_out);
  inflateEnd(&z);
  return out;
}

TEST(FinishResponse, AddsTheHeadersOfTheConnectionAndCompressesText) {
  HttpRequest req;
  req.method = "GET";
  req.headers.emplace("Accept-Encoding", "gzip, deflate");
  HttpResponse json;
  json.SetContent(std::string(2000, 'x'), "application/json");
  FinishResponse(req, {false, 5, 100}, &json);
  EXPECT_EQ(json.Header("Content-Encoding"), "gzip");
  EXPECT_EQ(Gunzip(json.body), std::string(2000, 'x'));
  EXPECT_EQ(json.Header("Content-Length"), std::to_string(json.body.size()));
  EXPECT_EQ(json.Header("Keep-Alive"), "timeout=5, max=100");
  EXPECT_FALSE(json.HasHeader("Connection"));
  const std::string head = ResponseHead(json);
  EXPECT_EQ(head.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << head;
  EXPECT_TRUE(head.ends_with("\r\n\r\n")) << head;

  HttpResponse png;  // not text: as it is
  png.status = 404;
  png.SetContent("\x89PNG", "image/png");
  FinishResponse(req, {true, 5, 100}, &png);
  EXPECT_FALSE(png.HasHeader("Content-Encoding"));
  EXPECT_EQ(png.Header("Connection"), "close");
  EXPECT_FALSE(png.HasHeader("Keep-Alive"));
  EXPECT_EQ(ResponseHead(png).rfind("HTTP/1.1 404 Not Found\r\n", 0), 0u);

  HttpRequest head_req;
  head_req.method = "HEAD";
  HttpResponse empty;
  FinishResponse(head_req, {false, 1, 3}, &empty);
  EXPECT_EQ(empty.Header("Content-Length"), "0");
  EXPECT_EQ(empty.Header("Accept-Ranges"), "bytes");
  EXPECT_FALSE(empty.HasHeader("Content-Type"));

  HttpRequest br;
  br.headers.emplace("accept-encoding", "gzip, deflate, br");
  HttpResponse page;
  page.SetContent("<!doctype html>", "text/html; charset=utf-8");
  FinishResponse(br, {false, 5, 100}, &page);
  EXPECT_EQ(page.Header("Content-Encoding"), "br");
}

TEST(HttpResponse, HeadersAreCaseInsensitiveAndNeverSplitLines) {
  HttpResponse res;
  res.AddHeader("retry-after", "1");
  res.AddHeader("X-Bad", "a\r\nSet-Cookie: x");
  EXPECT_EQ(res.Header("Retry-After"), "1");
  EXPECT_FALSE(res.HasHeader("X-Bad"));
  res.SetContent("a", "text/plain");
  res.SetContent("b", "application/json");
  EXPECT_EQ(res.headers.count("content-type"), 1u);
  EXPECT_EQ(res.Header("Content-Type"), "application/json");
}

}  // namespace
}  // namespace npfkct::server
