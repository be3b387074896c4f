// Readers of JSON fields of scenario files that report errors as INVALID_ARGUMENT naming the
// field's path. (Requests to the server are read by the API layer, server/api.)
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "npfkct/common/status.h"
#include "npfkct/sim/scenario.h"

namespace npfkct::sim::json_read {

/// INVALID_ARGUMENT "<path>: <what>".
Status Err(const std::string& path, const std::string& what);
/// Reads parent[key] as a finite number into *out (left unchanged when absent and optional).
/// `path` is the parent's path with a trailing '.' (or empty at the top level).
Status ReadNumber(const nlohmann::json& parent, const std::string& key, const std::string& path,
                  double* out, bool required);
/// Reads parent[key] as a boolean.
Status ReadBool(const nlohmann::json& parent, const std::string& key, const std::string& path,
                bool* out);
/// Reads parent[key] as a string.
Status ReadString(const nlohmann::json& parent, const std::string& key, const std::string& path,
                  std::string* out, bool required);
/// Reads parent[key] as an array of N finite numbers.
template <int N>
Status ReadVector(const nlohmann::json& parent, const std::string& key, const std::string& path,
                  Eigen::Matrix<double, N, 1>* out, bool required) {
  if (!parent.contains(key)) return required ? Err(path + key, "missing") : OkStatus();
  const nlohmann::json& v = parent.at(key);
  if (!v.is_array() || v.size() != N) {
    return Err(path + key, "expected " + std::to_string(N) + " numbers");
  }
  for (int i = 0; i < N; ++i) {
    if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) {
      return Err(path + key + "[" + std::to_string(i) + "]", "expected a finite number");
    }
    (*out)[i] = v[i].get<double>();
  }
  return OkStatus();
}
/// Reads parent[key] as [r, g, b] with integers in [0, 255].
Status ReadColor(const nlohmann::json& parent, const std::string& key, const std::string& path,
                 Color* out);
/// Reads a robot configuration object {x, y, yaw, lift, pan, tilt} (every field optional).
Status ReadConfig(const nlohmann::json& j, const std::string& path, RobotConfig* c);
/// Rejects keys of `j` that are not in `known`.
Status CheckKeys(const nlohmann::json& j, const std::string& path,
                 const std::set<std::string>& known);

}  // namespace npfkct::sim::json_read
