#include "json_util.h"

// x86-64 always has SSE2: the reader then scans a string's plain characters 16 at a time.
#if defined(__SSE2__)
#define RAPIDJSON_SSE2
#endif
#include <rapidjson/reader.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace npfkct::api::internal {
namespace {

// A SAX handler that builds the DOM like json::parse, but stops at the first value past the
// depth or count limits, or at a number that overflowed to infinity, so that a hostile body is
// refused before it is allocated.
class BoundedSax {
 public:
  BoundedSax(json* out, int max_depth, int64_t max_values)
      : dom_(*out, /*allow_exceptions=*/false), max_depth_(max_depth), max_values_(max_values) {}

  bool null() { return Count() && dom_.null(); }
  bool boolean(bool v) { return Count() && dom_.boolean(v); }
  bool number_integer(json::number_integer_t v) { return Count() && dom_.number_integer(v); }
  bool number_unsigned(json::number_unsigned_t v) { return Count() && dom_.number_unsigned(v); }
  bool number_float(json::number_float_t v, const json::string_t& s) {
    if (!std::isfinite(v)) return Fail("a number does not fit a double: " + s.substr(0, 40));
    return Count() && dom_.number_float(v, s);
  }
  bool string(json::string_t& v) { return Count() && dom_.string(v); }
  bool binary(json::binary_t& v) { return Count() && dom_.binary(v); }
  bool start_object(std::size_t n) { return Open() && dom_.start_object(n); }
  bool key(json::string_t& k) { return dom_.key(k); }
  bool end_object() {
    --depth_;
    return dom_.end_object();
  }
  bool start_array(std::size_t n) { return Open() && dom_.start_array(n); }
  bool end_array() {
    --depth_;
    return dom_.end_array();
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) {
    return Fail("not valid JSON");
  }

  const std::string& error() const { return error_; }

 private:
  bool Count() {
    if (++values_ > max_values_) {
      return Fail("more than " + std::to_string(max_values_) + " JSON values");
    }
    return true;
  }
  bool Open() {
    if (++depth_ > max_depth_) {
      return Fail("nested deeper than " + std::to_string(max_depth_) + " levels");
    }
    return Count();
  }
  bool Fail(std::string why) {
    if (error_.empty()) error_ = std::move(why);
    return false;
  }

  nlohmann::detail::json_sax_dom_parser<json> dom_;
  int max_depth_;
  int64_t max_values_;
  int depth_ = 0;
  int64_t values_ = 0;
  std::string error_;
};

// Whether `s` is well-formed UTF-8 (RFC 3629: no overlong forms, no surrogates, at most
// U+10FFFF). Plain ASCII goes eight bytes at a time.
bool IsUtf8(const char* s, size_t n) {
  const auto* p = reinterpret_cast<const unsigned char*>(s);
  size_t i = 0;
  while (i < n) {
    if (i + 8 <= n) {
      uint64_t word;
      std::memcpy(&word, p + i, 8);
      if ((word & 0x8080808080808080ULL) == 0) {
        i += 8;
        continue;
      }
    }
    const unsigned char c = p[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    int more;
    unsigned char lo = 0x80, hi = 0xBF;  // the bounds of the second byte
    if (c >= 0xC2 && c <= 0xDF) {
      more = 1;
    } else if (c >= 0xE0 && c <= 0xEF) {
      more = 2;
      if (c == 0xE0) lo = 0xA0;  // overlong
      if (c == 0xED) hi = 0x9F;  // surrogates
    } else if (c >= 0xF0 && c <= 0xF4) {
      more = 3;
      if (c == 0xF0) lo = 0x90;  // overlong
      if (c == 0xF4) hi = 0x8F;  // past U+10FFFF
    } else {
      return false;
    }
    if (i + static_cast<size_t>(more) >= n) return false;
    if (p[i + 1] < lo || p[i + 1] > hi) return false;
    for (int k = 2; k <= more; ++k) {
      if ((p[i + k] & 0xC0) != 0x80) return false;
    }
    i += static_cast<size_t>(more) + 1;
  }
  return true;
}

// Drives a BoundedSax from RapidJSON's reader: nlohmann's lexer copies a string's characters one
// at a time (a raw frame's 5 MB of Base64 took 40 ms to read), RapidJSON's in bulk. Numbers reach
// it as their text and become what nlohmann's parser makes of them: an integer without a
// fraction or exponent (signed when negative) that fits 64 bits, else a double by strtod.
class RapidToNlohmann {
 public:
  explicit RapidToNlohmann(BoundedSax* sax) : sax_(*sax) {}

  bool Null() { return sax_.null(); }
  bool Bool(bool b) { return sax_.boolean(b); }
  bool RawNumber(const char* text, rapidjson::SizeType length, bool) {
    const std::string number(text, length);
    if (number.find_first_of(".eE") == std::string::npos) {
      errno = 0;
      char* end = nullptr;
      if (number.front() == '-') {
        const long long v = std::strtoll(number.c_str(), &end, 10);
        if (errno == 0 && *end == '\0') return sax_.number_integer(v);
      } else {
        const unsigned long long v = std::strtoull(number.c_str(), &end, 10);
        if (errno == 0 && *end == '\0') return sax_.number_unsigned(v);
      }
    }
    return sax_.number_float(std::strtod(number.c_str(), nullptr), number);
  }
  bool String(const char* text, rapidjson::SizeType length, bool) {
    if (!IsUtf8(text, length)) return false;
    json::string_t v(text, length);
    return sax_.string(v);
  }
  bool StartObject() { return sax_.start_object(static_cast<std::size_t>(-1)); }
  bool Key(const char* text, rapidjson::SizeType length, bool) {
    if (!IsUtf8(text, length)) return false;
    json::string_t k(text, length);
    return sax_.key(k);
  }
  bool EndObject(rapidjson::SizeType) { return sax_.end_object(); }
  bool StartArray() { return sax_.start_array(static_cast<std::size_t>(-1)); }
  bool EndArray(rapidjson::SizeType) { return sax_.end_array(); }
  // Numbers arrive as RawNumber (kParseNumbersAsStringsFlag); these are never called.
  bool Int(int) { return false; }
  bool Uint(unsigned) { return false; }
  bool Int64(int64_t) { return false; }
  bool Uint64(uint64_t) { return false; }
  bool Double(double) { return false; }

 private:
  BoundedSax& sax_;
};

}  // namespace

StatusOr<json> ParseBody(std::string_view text, int max_depth, int64_t max_values,
                         bool allow_empty) {
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    if (allow_empty) return json::object();
    return InvalidFieldError("body", "expected a JSON object");
  }
  json out;
  BoundedSax sax(&out, max_depth, max_values);
  // Iterative (no recursion however deep the text nests), one value and nothing after it but
  // whitespace; strings are checked for UTF-8 as they arrive (the reader's own check goes a
  // character at a time). The reader takes a NUL byte for the end of the text, so it reads a
  // copy that ends there, and one inside the text must not end it early. The copy has 16 NUL
  // bytes at its end: the reader loads aligned blocks of 16 bytes, the last one past the end.
  constexpr unsigned kFlags =
      rapidjson::kParseIterativeFlag | rapidjson::kParseNumbersAsStringsFlag;
  // A UTF-8 byte order mark before the text is skipped, as nlohmann's parser did.
  if (text.starts_with("\xef\xbb\xbf")) text.remove_prefix(3);
  std::string terminated;
  terminated.reserve(text.size() + 16);
  terminated.append(text);
  terminated.append(16, '\0');
  rapidjson::StringStream in(terminated.c_str());
  rapidjson::Reader reader;
  RapidToNlohmann handler(&sax);
  const bool ok = !reader.Parse<kFlags>(in, handler).IsError() && in.Tell() == text.size();
  if (!ok) return InvalidFieldError("body", sax.error().empty() ? "not valid JSON" : sax.error());
  if (!out.is_object()) return InvalidFieldError("body", "expected a JSON object");
  return out;
}

void IntegralNumbersAsIntegers(json& v) {
  if (v.is_number_float()) {
    const double d = v.get<double>();
    if (std::trunc(d) == d && std::abs(d) <= 9007199254740992.0) v = static_cast<int64_t>(d);
  } else if (v.is_array() || v.is_object()) {
    for (json& child : v) IntegralNumbersAsIntegers(child);
  }
}

json Vec(const object_search::Vec2& v) { return json::array({v.x(), v.y()}); }
json Vec(const object_search::Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }

namespace {
template <int N>
bool ReadN(const json& j, Eigen::Matrix<double, N, 1>* v) {
  if (!j.is_array() || j.size() != N) return false;
  for (int i = 0; i < N; ++i) {
    if (!j[i].is_number()) return false;
    (*v)[i] = j[i].get<double>();
  }
  return v->allFinite();
}
}  // namespace

bool ReadVec(const json& j, object_search::Vec2* v) { return ReadN<2>(j, v); }
bool ReadVec(const json& j, object_search::Vec3* v) { return ReadN<3>(j, v); }

json ConfigJson(const object_search::RobotConfig& c) {
  return {{"x", c.x},       {"y", c.y},     {"yaw", c.yaw},
          {"lift", c.lift}, {"pan", c.pan}, {"tilt", c.tilt}};
}

object_search::RobotConfig ReadConfig(const json& j, object_search::RobotConfig c) {
  c.x = Number(j, "x", c.x);
  c.y = Number(j, "y", c.y);
  c.yaw = Number(j, "yaw", c.yaw);
  c.lift = Number(j, "lift", c.lift);
  c.pan = Number(j, "pan", c.pan);
  c.tilt = Number(j, "tilt", c.tilt);
  return c;
}

json BoxJson(const object_search::Box& b) {
  return {{"center", Vec(b.center)}, {"yaw", b.yaw}, {"size", Vec(b.size)}};
}

bool ReadBox(const json& j, object_search::Box* b) {
  if (!j.is_object() || !j.contains("center") || !j.contains("size")) return false;
  if (!ReadVec(j.at("center"), &b->center) || !ReadVec(j.at("size"), &b->size)) return false;
  b->yaw = Number(j, "yaw", 0.0);
  return std::isfinite(b->yaw);
}

std::string Dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

}  // namespace npfkct::api::internal
