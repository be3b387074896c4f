#include "npfkct/sim/json_read.h"

namespace npfkct::sim::json_read {

using nlohmann::json;

Status Err(const std::string& path, const std::string& what) {
  return InvalidArgumentError(path + ": " + what);
}

Status ReadNumber(const json& parent, const std::string& key, const std::string& path, double* out,
                  bool required) {
  if (!parent.contains(key)) return required ? Err(path + key, "missing") : OkStatus();
  const json& v = parent.at(key);
  if (!v.is_number()) return Err(path + key, "expected a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) return Err(path + key, "not finite");
  *out = d;
  return OkStatus();
}

Status ReadBool(const json& parent, const std::string& key, const std::string& path, bool* out) {
  if (!parent.contains(key)) return OkStatus();
  if (!parent.at(key).is_boolean()) return Err(path + key, "expected true or false");
  *out = parent.at(key).get<bool>();
  return OkStatus();
}

Status ReadString(const json& parent, const std::string& key, const std::string& path,
                  std::string* out, bool required) {
  if (!parent.contains(key)) return required ? Err(path + key, "missing") : OkStatus();
  if (!parent.at(key).is_string()) return Err(path + key, "expected a string");
  *out = parent.at(key).get<std::string>();
  return OkStatus();
}

Status ReadColor(const json& parent, const std::string& key, const std::string& path, Color* out) {
  if (!parent.contains(key)) return OkStatus();
  const json& v = parent.at(key);
  if (!v.is_array() || v.size() != 3) return Err(path + key, "expected [r, g, b]");
  for (int i = 0; i < 3; ++i) {
    if (!v[i].is_number_integer() || v[i].get<int64_t>() < 0 || v[i].get<int64_t>() > 255) {
      return Err(path + key + "[" + std::to_string(i) + "]", "expected an integer in [0, 255]");
    }
    (*out)[i] = static_cast<uint8_t>(v[i].get<int>());
  }
  return OkStatus();
}

Status ReadConfig(const json& j, const std::string& path, RobotConfig* c) {
  if (!j.is_object()) return Err(path.substr(0, path.size() - 1), "expected an object");
  for (auto [key, field] : {std::pair<const char*, double*>{"x", &c->x},
                            {"y", &c->y},
                            {"yaw", &c->yaw},
                            {"lift", &c->lift},
                            {"pan", &c->pan},
                            {"tilt", &c->tilt}}) {
    if (Status s = ReadNumber(j, key, path, field, false); !s.ok()) return s;
  }
  return OkStatus();
}

Status CheckKeys(const json& j, const std::string& path, const std::set<std::string>& known) {
  for (auto it = j.begin(); it != j.end(); ++it) {
    if (!known.count(it.key())) return Err(path + it.key(), "unknown field");
  }
  return OkStatus();
}

}  // namespace npfkct::sim::json_read
