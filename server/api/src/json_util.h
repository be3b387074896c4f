// JSON plumbing of the API layer (private): bounded parsing, field paths, readers of the shapes
// the schemas have already checked.
#pragma once

#include <cmath>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

#include "npfkct/api/limits.h"
#include "npfkct/common/status.h"
#include "npfkct/object_search/geometry.h"

namespace npfkct::api::internal {

using nlohmann::json;

/// Parses a request body as a JSON object. Nesting deeper than `max_depth`, more than
/// `max_values` values and numbers that do not fit a double are refused while parsing, before
/// they are allocated. Errors are INVALID_ARGUMENT on the field "body". An empty body is `{}`
/// when `allow_empty`.
StatusOr<json> ParseBody(std::string_view text, int max_depth, int64_t max_values,
                         bool allow_empty);

/// Numbers with no fractional part written with one (300.0, 3e2) as integers, everywhere in `v`:
/// JSON Schema counts them as integers, valijson does not (it asks the parser, which kept them as
/// floats).
void IntegralNumbersAsIntegers(json& v);

/// Checks one planner option override as a request gives it (a lowerCamelCase key, a finite
/// value within the bound of the options that size memory or work); the error names
/// "planner.options.<key>". Requests and restored records both pass through it.
Status CheckPlannerOption(const std::string& key, double value, const Limits& limits);

/// "parent.key" (or "key" at the top).
inline std::string Join(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}
/// "parent[i]".
inline std::string At(const std::string& parent, size_t i) {
  return parent + "[" + std::to_string(i) + "]";
}

/// j[key] as a double, `fallback` when absent or not a number.
inline double Number(const json& j, const char* key, double fallback = 0.0) {
  if (!j.is_object()) return fallback;
  auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : fallback;
}
/// j[key] as a string, `fallback` when absent or not a string.
inline std::string String(const json& j, const char* key, const std::string& fallback = "") {
  if (!j.is_object()) return fallback;
  auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : fallback;
}
/// The first `max_chars` characters (UTF-8 code points, as the schemas' maxLength counts them)
/// of `s`: a value the API accepted comes back whole, however many bytes its characters take.
inline std::string Utf8Prefix(std::string s, size_t max_chars) {
  size_t chars = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    if ((static_cast<unsigned char>(s[i]) & 0xc0) != 0x80 && chars++ == max_chars) {
      s.resize(i);
      break;
    }
  }
  return s;
}
/// j[key] as a bool, `fallback` when absent or not a bool.
inline bool Bool(const json& j, const char* key, bool fallback = false) {
  if (!j.is_object()) return fallback;
  auto it = j.find(key);
  return it != j.end() && it->is_boolean() ? it->get<bool>() : fallback;
}
/// j[key] as an integer, `fallback` when absent or not an integer.
inline int64_t Integer(const json& j, const char* key, int64_t fallback = 0) {
  if (!j.is_object()) return fallback;
  auto it = j.find(key);
  return it != j.end() && it->is_number_integer() ? it->get<int64_t>() : fallback;
}

/// [x, y] or [x, y, z] arrays of numbers.
json Vec(const object_search::Vec2& v);
json Vec(const object_search::Vec3& v);
/// Reads an array of N numbers into v; false when the shape is wrong.
bool ReadVec(const json& j, object_search::Vec2* v);
bool ReadVec(const json& j, object_search::Vec3* v);

/// {"x", "y", "yaw", "lift", "pan", "tilt"}.
json ConfigJson(const object_search::RobotConfig& c);
/// Reads the fields present (absent ones keep their value).
object_search::RobotConfig ReadConfig(const json& j, object_search::RobotConfig c = {});
/// {"center", "yaw", "size"}.
json BoxJson(const object_search::Box& b);
/// Reads a box; false when the shape is wrong.
bool ReadBox(const json& j, object_search::Box* b);

/// Serialises a JSON value (invalid UTF-8 replaced).
std::string Dump(const json& j);

}  // namespace npfkct::api::internal
