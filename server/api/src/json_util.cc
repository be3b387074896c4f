#include "json_util.h"

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

}  // namespace

StatusOr<json> ParseBody(std::string_view text, int max_depth, int64_t max_values,
                         bool allow_empty) {
  if (text.find_first_not_of(" \t\r\n") == std::string_view::npos) {
    if (allow_empty) return json::object();
    return InvalidFieldError("body", "expected a JSON object");
  }
  json out;
  BoundedSax sax(&out, max_depth, max_values);
  const bool ok = json::sax_parse(text.begin(), text.end(), &sax, json::input_format_t::json,
                                  /*strict=*/true);
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
