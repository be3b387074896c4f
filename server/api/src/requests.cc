// Request bodies to typed requests: bounded parse, schema validation, then the domain checks.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <set>

#include "json_util.h"
#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/object_search/planner_registry.h"
#include "schema.h"
#include "world_codec.h"

namespace npfkct::api {
namespace {

using internal::At;
using internal::Join;
using internal::json;

#define NPFKCT_API_RETURN_IF_ERROR(expr) \
  do {                                   \
    Status _s = (expr);                  \
    if (!_s.ok()) return _s;             \
  } while (0)

StatusOr<json> ParseAndValidate(std::string_view body, std::string_view message,
                                const Limits& limits, bool allow_empty,
                                const std::vector<std::string>* planner_names = nullptr) {
  auto j = internal::ParseBody(body, limits.max_json_depth, limits.max_json_values, allow_empty);
  if (!j.ok()) return j.status();
  internal::IntegralNumbersAsIntegers(*j);
  NPFKCT_API_RETURN_IF_ERROR(
      internal::ValidateAgainstSchema(message, *j, /*max_violations=*/8, planner_names));
  return j;
}

// The planner options that size memory or work, by their leaf name (the option tables accept a
// bare leaf for a nested option): the schema bounds the canonical keys, this bounds the aliases
// too. Keep in step with common.schema.json#/$defs/PlannerSpec (a unit test compares them).
struct OptionBound {
  const char* leaf;
  double max;
  bool exact_only = false;  ///< Only the key itself ("k" is not "observations.k").
};
constexpr OptionBound kOptionBounds[] = {
    {"k", 16, true},
    {"numCandidates", 4096},
    {"maxInitialClusters", 16},
    {"maxFeasibilityTries", 10000},
    {"treeFeasibilityTries", 1000},
    {"feasibilityTries", 10000},
    {"maxDepth", 100},
    {"numParticles", 10000},
    {"threads", 4},
    {"maxAttemptsPerParticle", 1000},
    {"diameterSamples", 300},
    {"walkSteps", 10000},
    {"splitCoefficient", 1000},
    {"maxTries", 10000},
    {"priorCount", 1000000},
    {"candidates", 100000},
    {"context", 256},
    {"placements", 4096},
};

// Dot-separated segments, each a lowercase letter followed by letters and digits.
bool IsLowerCamelKey(const std::string& key) {
  bool segment_start = true;
  for (char ch : key) {
    const auto c = static_cast<unsigned char>(ch);
    if (ch == '.') {
      if (segment_start) return false;
      segment_start = true;
    } else if (segment_start) {
      if (!std::islower(c)) return false;
      segment_start = false;
    } else if (!std::isalnum(c)) {
      return false;
    }
  }
  return !segment_start;
}

}  // namespace

Status internal::CheckPlannerOption(const std::string& key, double value, const Limits& limits) {
  const std::string field = "planner.options." + key;
  // lowerCamelCase only: the session turns keys into snake_case, so "num_candidates" or
  // "search.Threads" would reach the same option past the bounds below.
  if (!IsLowerCamelKey(key)) {
    return InvalidFieldError(field, "expected a lowerCamelCase key (e.g. search.maxDepth)");
  }
  if (!std::isfinite(value)) return InvalidFieldError(field, "not finite");
  const size_t dot = key.find_last_of('.');
  const std::string leaf = dot == std::string::npos ? key : key.substr(dot + 1);
  for (const OptionBound& b : kOptionBounds) {
    const bool applies = b.exact_only ? key == b.leaf : leaf == b.leaf;
    if (applies && std::abs(value) > b.max) {
      return InvalidFieldError(field, "must be <= " + std::to_string(int64_t(b.max)));
    }
  }
  if (leaf == "numParticles" && value > limits.max_particles) {
    return InvalidFieldError(field, "must be <= " + std::to_string(limits.max_particles));
  }
  return OkStatus();
}

namespace {

Status ReadPlanner(const json& p, const Limits& limits,
                   const object_search::PlannerRegistry& planners, PlannerSpec* spec) {
  spec->name = internal::String(p, "name", spec->name);
  const object_search::PlannerEntry* entry = planners.Find(spec->name);
  if (entry == nullptr || entry->needs_truth) {
    std::string known;
    for (const auto& name : planners.Names(/*servable_only=*/true)) {
      known += (known.empty() ? "" : ", ") + name;
    }
    return InvalidFieldError(
        "planner.name",
        entry ? "'" + spec->name +
                    "' is benchmark-only (it must be told the true "
                    "world); the server plans with " +
                    known
              : "unknown planner '" + spec->name + "' (expected one of " + known + ")");
  }
  spec->takes_model = entry->takes_sampler;
  if (p.contains("particles")) {
    const int64_t n = p.at("particles").get<int64_t>();
    if (n > limits.max_particles) {
      return InvalidFieldError("planner.particles",
                               "must be <= " + std::to_string(limits.max_particles));
    }
    spec->particles = static_cast<int>(n);
  }
  if (p.contains("model")) {
    spec->model = p.at("model").get<std::string>();
    spec->model_given = true;
    if (!spec->model.empty() && !IsModelName(spec->model)) {
      return InvalidFieldError("planner.model",
                               "expected a model file name (letters, digits, '.', '_', '-'; no "
                               "path), e.g. \"filter.pt\"");
    }
  }
  if (p.contains("options")) {
    const json& o = p.at("options");
    if (static_cast<int64_t>(o.size()) > limits.max_planner_options) {
      return InvalidFieldError(
          "planner.options", "at most " + std::to_string(limits.max_planner_options) + " options");
    }
    for (auto it = o.begin(); it != o.end(); ++it) {
      const double v = it->is_boolean() ? (it->get<bool>() ? 1.0 : 0.0) : it->get<double>();
      NPFKCT_API_RETURN_IF_ERROR(internal::CheckPlannerOption(it.key(), v, limits));
      spec->options.emplace_back(SnakeCase(it.key()), v);
      spec->option_is_bool.push_back(it->is_boolean());
    }
  }
  return OkStatus();
}

StatusOr<uint64_t> ReadSeed(const json& s) {
  if (s.is_number_unsigned()) return s.get<uint64_t>();
  if (s.is_number_integer()) {
    if (s.get<int64_t>() < 0) return InvalidFieldError("seed", "must be >= 0");
    return static_cast<uint64_t>(s.get<int64_t>());
  }
  const std::string text = s.is_string() ? s.get<std::string>() : "";
  if (text.empty() || text.size() > 20 ||
      text.find_first_not_of("0123456789") != std::string::npos) {
    return InvalidFieldError("seed", "expected a non-negative integer or its decimal string");
  }
  uint64_t v = 0;
  for (char c : text) {
    const uint64_t digit = static_cast<uint64_t>(c - '0');
    if (v > (UINT64_MAX - digit) / 10) return InvalidFieldError("seed", "beyond 2^64 - 1");
    v = v * 10 + digit;
  }
  return v;
}

// The robot state a client reports: every field present (schema), angles and lift bounded.
object_search::RobotConfig ReadFullConfig(const json& j) { return internal::ReadConfig(j); }

Status ReadDetections(const json& dets, const Limits& limits,
                      std::vector<object_search::ObjectDetection>* out) {
  if (static_cast<int64_t>(dets.size()) > limits.max_objects) {
    return InvalidFieldError("detections",
                             "at most " + std::to_string(limits.max_objects) + " per observation");
  }
  std::set<std::string> seen;
  for (size_t i = 0; i < dets.size(); ++i) {
    const json& d = dets[i];
    const std::string path = At("detections", i);
    object_search::ObjectDetection det;
    det.key = d.at("id").get<std::string>();
    if (!seen.insert(det.key).second) {
      return InvalidFieldError(path + ".id", "duplicate id '" + det.key + "'");
    }
    if (!internal::ReadBox(d.at("box"), &det.box))
      return InvalidFieldError(path + ".box", "bad box");
    det.moveability = internal::Number(d, "moveability", 1.0);
    if (d.contains("faces")) {
      for (const json& f : d.at("faces")) {
        det.faces.push_back(
            {static_cast<int>(f.at("corner").get<int64_t>()), f.at("score").get<double>()});
      }
    }
    if (d.contains("score")) det.score = d.at("score").get<double>();  // the schema: not both
    out->push_back(std::move(det));
  }
  return OkStatus();
}

StatusOr<perception::SensorFrame> ReadFrame(const json& body, const Limits& limits) {
  perception::SensorFrame frame;
  const json& pc = body.at("pointCloud");
  frame.cloud_in_map_frame = internal::String(pc, "frame", "camera") == "map";
  const std::string fields = internal::String(pc, "fields", "xyz");
  auto bytes = Base64Decode(pc.at("data").get<std::string>(), "pointCloud.data",
                            static_cast<size_t>(limits.max_points) * 16);
  if (!bytes.ok()) return bytes.status();
  auto cloud = DecodeCloud(*bytes, fields, limits.max_points, limits.max_coordinate, "pointCloud");
  if (!cloud.ok()) return cloud.status();
  frame.cloud = *cloud;
  if (body.contains("camera")) {
    const json& c = body.at("camera");
    auto& in = frame.intrinsics;
    in.width = static_cast<int>(internal::Integer(c, "width", in.width));
    in.height = static_cast<int>(internal::Integer(c, "height", in.height));
    in.fx = internal::Number(c, "fx", in.fx);
    in.fy = internal::Number(c, "fy", in.fy);
    in.cx = internal::Number(c, "cx", in.cx);
    in.cy = internal::Number(c, "cy", in.cy);
  }
  const auto& in = frame.intrinsics;
  if (in.width > limits.max_image_side || in.height > limits.max_image_side ||
      int64_t{in.width} * in.height > limits.max_image_pixels) {
    return InvalidFieldError("camera",
                             "at most " + std::to_string(limits.max_image_pixels) + " pixels");
  }
  if (Status s = in.Validate(); !s.ok()) return InvalidFieldError("camera", s.message());
  if (body.contains("image")) {
    auto data = Base64Decode(body.at("image").at("data").get<std::string>(), "image.data",
                             static_cast<size_t>(limits.max_image_pixels) * 4 + (1 << 20));
    if (!data.ok()) return data.status();
    if (const json& img = body.at("image"); img.contains("encoding")) {
      auto info = ProbeImage(*data, "image.data");
      if (!info.ok()) return info.status();
      const std::string said = img.at("encoding").get<std::string>();
      const std::string is = info->format == ImageInfo::Format::kPng ? "png" : "jpeg";
      if (said != is) {
        return InvalidFieldError("image.encoding",
                                 "says " + said + ", the data is a " + is + " image");
      }
    }
    auto image = DecodeImage(*data, limits.max_image_pixels, "image.data");
    if (!image.ok()) return image.status();
    if (image->cols != in.width || image->rows != in.height) {
      return InvalidFieldError("image.data", "the image is " + std::to_string(image->cols) + "x" +
                                                 std::to_string(image->rows) +
                                                 ", the camera says " + std::to_string(in.width) +
                                                 "x" + std::to_string(in.height));
    }
    frame.image = *image;
  }
  if (body.contains("semanticScores")) {
    const json& scores = body.at("semanticScores");
    for (auto it = scores.begin(); it != scores.end(); ++it) {
      frame.semantic_scores[it.key()] = it->get<double>();
    }
  }
  if (body.contains("imageBoxes")) {
    // The schema bounds the count and each number; perception checks them against the image.
    const json& boxes = body.at("imageBoxes");
    if (boxes.size() > static_cast<size_t>(limits.max_image_boxes)) {
      return InvalidFieldError("imageBoxes",
                               "at most " + std::to_string(limits.max_image_boxes) + " boxes");
    }
    frame.image_boxes.emplace();
    for (const json& b : boxes) {
      frame.image_boxes->push_back({internal::Number(b, "x"), internal::Number(b, "y"),
                                    internal::Number(b, "width"), internal::Number(b, "height"),
                                    internal::Number(b, "score")});
    }
  }
  return frame;
}

}  // namespace

bool IsSessionId(std::string_view id) {
  return id.size() == 32 && std::all_of(id.begin(), id.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

bool IsModelName(std::string_view name) {
  if (name.empty() || name.size() > 64 || name.front() == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-';
  });
}

StatusOr<CreateSessionRequest> ParseCreateSession(std::string_view body, const Limits& limits,
                                                  const object_search::PlannerRegistry& planners) {
  const std::vector<std::string> names = planners.Names(/*servable_only=*/true);
  auto parsed = ParseAndValidate(body, "create_session_request", limits, false, &names);
  if (!parsed.ok()) return parsed.status();
  const json& j = *parsed;
  CreateSessionRequest req;
  req.display_name = internal::String(j, "displayName");
  auto world = internal::ReadWorldSpec(j.at("world"), "world", limits);
  if (!world.ok()) return world.status();
  req.world = std::move(world).value();
  if (j.contains("target")) {
    const json& t = j.at("target");
    req.target.description = internal::String(t, "description");
    if (t.contains("photos")) {
      const json& photos = t.at("photos");
      if (static_cast<int64_t>(photos.size()) > limits.max_photos) {
        return InvalidFieldError("target.photos",
                                 "at most " + std::to_string(limits.max_photos) + " photos");
      }
      for (size_t i = 0; i < photos.size(); ++i) {
        const std::string field = At("target.photos", i);
        auto bytes = Base64Decode(photos[i].get<std::string>(), field,
                                  static_cast<size_t>(limits.max_photo_pixels) * 4 + (1 << 20));
        if (!bytes.ok()) return bytes.status();
        auto image = DecodeImage(*bytes, limits.max_photo_pixels, field);
        if (!image.ok()) return image.status();
        if (image->cols < 16 || image->rows < 16) {
          return InvalidFieldError(field, "at least 16 x 16 pixels");
        }
        req.target.photos.push_back(std::move(bytes).value());
      }
    }
  }
  NPFKCT_API_RETURN_IF_ERROR(ReadPlanner(j.contains("planner") ? j.at("planner") : json::object(),
                                         limits, planners, &req.planner));
  if (j.contains("seed")) {
    auto seed = ReadSeed(j.at("seed"));
    if (!seed.ok()) return seed.status();
    req.seed = *seed;
  }
  if (j.contains("ttlSeconds")) req.ttl_seconds = j.at("ttlSeconds").get<double>();
  return req;
}

StatusOr<PlanRequest> ParsePlan(std::string_view body, const Limits& limits) {
  auto parsed = ParseAndValidate(body, "plan_request", limits, true);
  if (!parsed.ok()) return parsed.status();
  PlanRequest req;
  if (!parsed->contains("budget")) return req;
  const json& b = parsed->at("budget");
  const std::string max = std::to_string(static_cast<int64_t>(limits.max_plan_ms));
  if (b.contains("timeMs")) {
    req.time_ms = b.at("timeMs").get<double>();
    if (*req.time_ms > limits.max_plan_ms) {
      return InvalidFieldError("budget.timeMs", "must be <= " + max + " (the server's maximum)");
    }
  }
  if (b.contains("cpuMs")) {
    req.cpu_ms = b.at("cpuMs").get<double>();
    if (*req.cpu_ms > limits.max_plan_ms) {
      return InvalidFieldError("budget.cpuMs", "must be <= " + max + " (the server's maximum)");
    }
  }
  if (b.contains("simulations")) {
    req.simulations = b.at("simulations").get<int64_t>();
    if (*req.simulations > limits.max_plan_simulations) {
      return InvalidFieldError(
          "budget.simulations",
          "must be <= " + std::to_string(limits.max_plan_simulations) + " (the server's maximum)");
    }
  }
  if (req.time_ms.value_or(0) == 0 && req.cpu_ms.value_or(0) == 0 &&
      req.simulations.value_or(0) == 0 && !b.empty()) {
    return InvalidFieldError("budget", "set timeMs, cpuMs and/or simulations above 0");
  }
  return req;
}

StatusOr<ObserveRequest> ParseObserve(std::string_view body, const Limits& limits) {
  auto parsed = ParseAndValidate(body, "observe_request", limits, false);
  if (!parsed.ok()) return parsed.status();
  const json& j = *parsed;
  ObserveRequest req;
  req.action_id = j.at("actionId").get<std::string>();
  req.succeeded = internal::Bool(j, "succeeded", true);
  if (j.contains("robotState")) req.robot_state = ReadFullConfig(j.at("robotState"));
  if (j.contains("detections")) {
    NPFKCT_API_RETURN_IF_ERROR(ReadDetections(j.at("detections"), limits, &req.detections));
  }
  if (j.contains("pointCloud")) {
    auto frame = ReadFrame(j, limits);
    if (!frame.ok()) return frame.status();
    req.frame = std::move(frame).value();
  }
  return req;
}

StatusOr<ListRequest> ParseList(const std::optional<std::string>& page_size,
                                const std::optional<std::string>& page_token) {
  ListRequest req;
  if (page_size) {
    const std::string& v = *page_size;
    if (v.empty() || v.size() > 4 || v.find_first_not_of("0123456789") != std::string::npos ||
        std::stoi(v) < 1 || std::stoi(v) > 1000) {
      return InvalidFieldError("pageSize", "expected an integer in [1, 1000]");
    }
    req.page_size = std::stoi(v);
  }
  if (page_token) {
    if (!page_token->empty() && !IsSessionId(*page_token)) {
      return InvalidFieldError("pageToken", "not a page token of this server");
    }
    req.page_token = *page_token;
  }
  return req;
}

StatusOr<BeliefFormat> ParseBeliefFormat(const std::optional<std::string>& format) {
  if (!format || *format == "json") return BeliefFormat::kJson;
  if (*format == "png") return BeliefFormat::kPng;
  return InvalidFieldError("format", "expected \"json\" or \"png\"");
}

std::string CamelCase(const std::string& snake) {
  std::string out;
  bool upper = false;
  for (char ch : snake) {
    if (ch == '_' && !out.empty() && out.back() != '.') {
      upper = true;
    } else {
      out += upper ? static_cast<char>(std::toupper(static_cast<unsigned char>(ch))) : ch;
      upper = false;
    }
  }
  return out;
}

std::string SnakeCase(const std::string& camel) {
  std::string out;
  for (char ch : camel) {
    if (std::isupper(static_cast<unsigned char>(ch))) {
      if (!out.empty() && out.back() != '.') out += '_';
      out += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    } else {
      out += ch;
    }
  }
  return out;
}

}  // namespace npfkct::api
