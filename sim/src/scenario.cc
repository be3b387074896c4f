#include "npfkct/sim/scenario.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "npfkct/api/api.h"
#include "npfkct/sim/json_read.h"

namespace npfkct::sim {
namespace {

using nlohmann::json;
using namespace json_read;  // NOLINT: the field readers

#define NPFKCT_RETURN_IF_ERROR(expr) \
  do {                               \
    Status _s = (expr);              \
    if (!_s.ok()) return _s;         \
  } while (0)

Status ParseParams(const json& j, object_search::SearchParams* p) {
  const std::string path = "params.";
  if (!j.is_object()) return Err("params", "expected an object");
  const std::pair<const char*, double*> reals[] = {{"rMax", &p->r_max},
                                                   {"rCt", &p->r_ct},
                                                   {"rCo", &p->r_co},
                                                   {"rMin", &p->r_min},
                                                   {"rIll", &p->r_ill},
                                                   {"discount", &p->discount},
                                                   {"cO", &p->c_o},
                                                   {"etaStd", &p->eta_std},
                                                   {"nuP", &p->nu_p},
                                                   {"nuN", &p->nu_n},
                                                   {"declareThreshold", &p->declare_threshold},
                                                   {"guessOdds", &p->guess_odds},
                                                   {"guessSize", &p->guess_size},
                                                   {"gridFreeDelta", &p->grid_free_delta},
                                                   {"baseClearance", &p->base_clearance}};
  std::set<std::string> known = {"nOdds", "maxSteps"};
  for (auto [key, field] : reals) {
    known.insert(key);
    NPFKCT_RETURN_IF_ERROR(ReadNumber(j, key, path, field, false));
  }
  NPFKCT_RETURN_IF_ERROR(CheckKeys(j, path, known));
  double n_odds = p->n_odds, max_steps = p->max_steps;
  NPFKCT_RETURN_IF_ERROR(ReadNumber(j, "nOdds", path, &n_odds, false));
  NPFKCT_RETURN_IF_ERROR(ReadNumber(j, "maxSteps", path, &max_steps, false));
  if (n_odds != std::floor(n_odds)) return Err(path + "nOdds", "expected an integer");
  if (max_steps != std::floor(max_steps) || max_steps > 1e6) {
    return Err(path + "maxSteps", "expected an integer");
  }
  p->n_odds = static_cast<int>(n_odds);
  p->max_steps = static_cast<int>(max_steps);
  if (Status s = p->Validate(); !s.ok()) return Err("params", s.message());
  return OkStatus();
}

}  // namespace

Status Scenario::Validate() const {
  if (name.empty()) return Err("name", "must not be empty");
  NPFKCT_RETURN_IF_ERROR(ValidateWorld());
  int targets = 0;
  for (const SceneObject& o : objects) targets += o.target;
  if (targets != 1) return Err("objects", "exactly one object must be the target");
  if (objects.size() > 60) return Err("objects", "at most 60 objects are supported");
  return OkStatus();
}

Status Scenario::ValidateWorld() const {
  if (!(room_min.x() < room_max.x() && room_min.y() < room_max.y())) {
    return Err("room", "min must be below max");
  }
  if (!(map_resolution > 0.0) || map_resolution > 1.0) {
    return Err("mapResolution", "must be in (0, 1]");
  }
  if ((room_max - room_min).prod() / (map_resolution * map_resolution) > 4e6) {
    return Err("mapResolution", "the map would have more than 4e6 cells");
  }
  if (std::none_of(furniture.begin(), furniture.end(),
                   [](const Furniture& f) { return f.workspace; })) {
    return Err("furniture", "at least one piece must be a workspace");
  }
  if (base_regions.empty()) return Err("baseRegions", "at least one region is needed");
  return OkStatus();
}

std::vector<object_search::Workspace> Scenario::Workspaces() const { return Prior().Workspaces(); }

object_search::PriorMap Scenario::Prior() const {
  object_search::PriorMap prior;
  prior.robot = robot;
  prior.room_min = room_min;
  prior.room_max = room_max;
  prior.map_resolution = map_resolution;
  for (const Furniture& f : furniture) prior.furniture.push_back({f.name, f.box, f.workspace});
  prior.base_regions = base_regions;
  prior.discrete_poses = discrete_poses;
  prior.start = start;
  prior.params = params;
  return prior;
}

namespace {

// The furniture of a scenario; its names go to `names`.
Status ParseFurniture(const json& j, Scenario* sc, std::set<std::string>* names) {
  if (!j.contains("furniture") || !j.at("furniture").is_array()) {
    return Err("furniture", "expected an array");
  }
  for (size_t i = 0; i < j.at("furniture").size(); ++i) {
    const json& f = j.at("furniture")[i];
    const std::string path = "furniture[" + std::to_string(i) + "].";
    if (!f.is_object()) return Err(path.substr(0, path.size() - 1), "expected an object");
    NPFKCT_RETURN_IF_ERROR(
        CheckKeys(f, path, {"name", "center", "size", "yaw", "workspace", "color"}));
    Furniture fu;
    NPFKCT_RETURN_IF_ERROR(ReadString(f, "name", path, &fu.name, true));
    if (!names->insert(fu.name).second)
      return Err(path + "name", "duplicate name '" + fu.name + "'");
    Vec2 center;
    NPFKCT_RETURN_IF_ERROR(ReadVector<2>(f, "center", path, &center, true));
    NPFKCT_RETURN_IF_ERROR(ReadVector<3>(f, "size", path, &fu.box.size, true));
    if (!(fu.box.size.minCoeff() > 0.0) || fu.box.size.maxCoeff() > 20.0) {
      return Err(path + "size", "each extent must be in (0, 20] m");
    }
    NPFKCT_RETURN_IF_ERROR(ReadNumber(f, "yaw", path, &fu.box.yaw, false));
    NPFKCT_RETURN_IF_ERROR(ReadBool(f, "workspace", path, &fu.workspace));
    NPFKCT_RETURN_IF_ERROR(ReadColor(f, "color", path, &fu.color));
    fu.box.center = Vec3(center.x(), center.y(), 0.5 * fu.box.size.z());
    sc->furniture.push_back(fu);
  }

  return OkStatus();
}

// The base regions of a scenario.
Status ParseBaseRegions(const json& j, Scenario* sc) {
  if (!j.contains("baseRegions") || !j.at("baseRegions").is_array()) {
    return Err("baseRegions", "expected an array");
  }
  for (size_t i = 0; i < j.at("baseRegions").size(); ++i) {
    const json& r = j.at("baseRegions")[i];
    const std::string path = "baseRegions[" + std::to_string(i) + "].";
    if (!r.is_object()) return Err(path.substr(0, path.size() - 1), "expected an object");
    NPFKCT_RETURN_IF_ERROR(CheckKeys(r, path, {"min", "max"}));
    object_search::BaseRegion region;
    NPFKCT_RETURN_IF_ERROR(ReadVector<2>(r, "min", path, &region.min, true));
    NPFKCT_RETURN_IF_ERROR(ReadVector<2>(r, "max", path, &region.max, true));
    if (!(region.min.x() < region.max.x() && region.min.y() < region.max.y())) {
      return Err(path + "max", "must be above min in x and y");
    }
    sc->base_regions.push_back(region);
  }

  return OkStatus();
}

// The manual poses of a scenario (the discrete planners' base poses).
Status ParseDiscretePoses(const json& j, Scenario* sc) {
  if (j.contains("discretePoses")) {
    if (!j.at("discretePoses").is_array()) return Err("discretePoses", "expected an array");
    for (size_t i = 0; i < j.at("discretePoses").size(); ++i) {
      const std::string path = "discretePoses[" + std::to_string(i) + "].";
      const json& p = j.at("discretePoses")[i];
      if (p.is_object()) NPFKCT_RETURN_IF_ERROR(CheckKeys(p, path, {"x", "y", "yaw"}));
      RobotConfig c;
      NPFKCT_RETURN_IF_ERROR(ReadConfig(p, path, &c));
      sc->discrete_poses.push_back(c);
    }
  }

  return OkStatus();
}

// objects[i] of a scenario, placed on its workspace among `furniture`; `names` holds every name
// so far.
StatusOr<SceneObject> ParseObject(const json& o, const std::string& path,
                                  const std::vector<Furniture>& furniture,
                                  std::set<std::string>* names) {
  if (!o.is_object()) return Err(path.substr(0, path.size() - 1), "expected an object");
  NPFKCT_RETURN_IF_ERROR(CheckKeys(
      o, path,
      {"name", "on", "position", "z", "size", "yaw", "color", "target", "moveable", "texture"}));
  SceneObject so;
  NPFKCT_RETURN_IF_ERROR(ReadString(o, "name", path, &so.name, true));
  if (!names->insert(so.name).second) return Err(path + "name", "duplicate name '" + so.name + "'");
  std::string on;
  NPFKCT_RETURN_IF_ERROR(ReadString(o, "on", path, &on, true));
  const Furniture* support = nullptr;
  for (const Furniture& f : furniture) {
    if (f.name == on) support = &f;
  }
  if (support == nullptr || !support->workspace) {
    return Err(path + "on", "'" + on + "' is not a workspace");
  }
  Vec2 uv = Vec2::Zero();
  NPFKCT_RETURN_IF_ERROR(ReadVector<2>(o, "position", path, &uv, true));
  NPFKCT_RETURN_IF_ERROR(ReadVector<3>(o, "size", path, &so.box.size, true));
  if (!(so.box.size.minCoeff() > 0.0) || so.box.size.maxCoeff() > 2.0) {
    return Err(path + "size", "each extent must be in (0, 2] m");
  }
  double yaw = 0.0, z = 0.0;
  NPFKCT_RETURN_IF_ERROR(ReadNumber(o, "yaw", path, &yaw, false));
  NPFKCT_RETURN_IF_ERROR(ReadNumber(o, "z", path, &z, false));
  if (z < 0.0) return Err(path + "z", "must be >= 0 (height above the surface)");
  if (std::abs(uv.x()) > 0.5 * support->box.size.x() ||
      std::abs(uv.y()) > 0.5 * support->box.size.y()) {
    return Err(path + "position", "outside the surface of '" + on + "'");
  }
  const double c = std::cos(support->box.yaw), s = std::sin(support->box.yaw);
  so.box.center = Vec3(support->box.center.x() + c * uv.x() - s * uv.y(),
                       support->box.center.y() + s * uv.x() + c * uv.y(),
                       support->box.size.z() + z + 0.5 * so.box.size.z());
  so.box.yaw = support->box.yaw + yaw;
  NPFKCT_RETURN_IF_ERROR(ReadColor(o, "color", path, &so.color));
  NPFKCT_RETURN_IF_ERROR(ReadBool(o, "target", path, &so.target));
  NPFKCT_RETURN_IF_ERROR(ReadBool(o, "moveable", path, &so.moveable));
  double texture = 0;
  NPFKCT_RETURN_IF_ERROR(ReadNumber(o, "texture", path, &texture, false));
  if (texture < 0 || texture != std::floor(texture) || texture > 4e9) {
    return Err(path + "texture", "expected a non-negative integer seed");
  }
  so.texture_seed = static_cast<uint32_t>(texture);
  return so;
}

// The objects of a scenario, each on a workspace; their names go to `names`.
Status ParseObjects(const json& j, Scenario* sc, std::set<std::string>* names) {
  if (!j.contains("objects") || !j.at("objects").is_array()) {
    return Err("objects", "expected an array");
  }
  for (size_t i = 0; i < j.at("objects").size(); ++i) {
    auto object = ParseObject(j.at("objects")[i], "objects[" + std::to_string(i) + "].",
                              sc->furniture, names);
    if (!object.ok()) return object.status();
    sc->objects.push_back(std::move(object).value());
  }
  return OkStatus();
}

// The noise of the simulated robot and sensors.
Status ParseNoise(const json& j, Scenario* sc) {
  if (j.contains("noise")) {
    const json& n = j.at("noise");
    if (!n.is_object()) return Err("noise", "expected an object");
    const std::pair<const char*, double*> fields[] = {
        {"poseXY", &sc->noise.pose_xy},
        {"poseYaw", &sc->noise.pose_yaw},
        {"objectJitter", &sc->noise.object_jitter},
        {"boxEstimate", &sc->noise.box_estimate},
        {"detection", &sc->noise.detection},
        {"falseDetection", &sc->noise.false_detection},
        {"localizationXY", &sc->noise.localization_xy},
        {"localizationYaw", &sc->noise.localization_yaw}};
    std::set<std::string> known;
    for (auto [key, field] : fields) {
      known.insert(key);
      NPFKCT_RETURN_IF_ERROR(ReadNumber(n, key, "noise.", field, false));
      if (*field < 0.0) return Err(std::string("noise.") + key, "must be >= 0");
    }
    NPFKCT_RETURN_IF_ERROR(CheckKeys(n, "noise.", known));
    if (sc->noise.false_detection > 0.5) return Err("noise.falseDetection", "must be <= 0.5");
  }
  return OkStatus();
}

StatusOr<Scenario> ParseScenarioJson(const json& j) {
  if (!j.is_object()) return InvalidArgumentError("scenario: expected a JSON object");
  NPFKCT_RETURN_IF_ERROR(
      CheckKeys(j, "",
                {"name", "description", "robot", "room", "mapResolution", "furniture",
                 "baseRegions", "discretePoses", "objects", "start", "noise", "params"}));
  Scenario sc;
  NPFKCT_RETURN_IF_ERROR(ReadString(j, "name", "", &sc.name, true));
  NPFKCT_RETURN_IF_ERROR(ReadString(j, "description", "", &sc.description, false));
  if (j.contains("robot")) {
    auto robot = api::ParseRobot(j.at("robot").dump(), "robot");
    if (!robot.ok()) return robot.status();
    sc.robot = std::move(robot).value();
  }
  if (j.contains("room")) {
    const json& room = j.at("room");
    if (!room.is_object()) return Err("room", "expected an object");
    NPFKCT_RETURN_IF_ERROR(CheckKeys(room, "room.", {"min", "max"}));
    NPFKCT_RETURN_IF_ERROR(ReadVector<2>(room, "min", "room.", &sc.room_min, true));
    NPFKCT_RETURN_IF_ERROR(ReadVector<2>(room, "max", "room.", &sc.room_max, true));
  }
  NPFKCT_RETURN_IF_ERROR(ReadNumber(j, "mapResolution", "", &sc.map_resolution, false));

  std::set<std::string> names;
  NPFKCT_RETURN_IF_ERROR(ParseFurniture(j, &sc, &names));
  NPFKCT_RETURN_IF_ERROR(ParseBaseRegions(j, &sc));
  NPFKCT_RETURN_IF_ERROR(ParseDiscretePoses(j, &sc));
  NPFKCT_RETURN_IF_ERROR(ParseObjects(j, &sc, &names));
  if (j.contains("start")) {
    NPFKCT_RETURN_IF_ERROR(
        CheckKeys(j.at("start"), "start.", {"x", "y", "yaw", "lift", "pan", "tilt"}));
    NPFKCT_RETURN_IF_ERROR(ReadConfig(j.at("start"), "start.", &sc.start));
  }
  NPFKCT_RETURN_IF_ERROR(ParseNoise(j, &sc));
  if (j.contains("params")) NPFKCT_RETURN_IF_ERROR(ParseParams(j.at("params"), &sc.params));
  NPFKCT_RETURN_IF_ERROR(sc.Validate());
  return sc;
}

}  // namespace

StatusOr<Scenario> ParseScenario(const std::string& json_text) {
  const json j = json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return InvalidArgumentError("scenario: not valid JSON");
  return ParseScenarioJson(j);
}

StatusOr<Scenario> LoadScenario(const std::string& path) {
  std::ifstream in(path);
  if (!in) return NotFoundError("cannot read scenario file '" + path + "'");
  std::stringstream buffer;
  buffer << in.rdbuf();
  StatusOr<Scenario> s = ParseScenario(buffer.str());
  if (!s.ok()) return Status(s.status().code(), path + ": " + s.status().message());
  return s;
}

StatusOr<object_search::World> InitialWorld(const Scenario& scenario) {
  return object_search::BuildWorld(scenario.Prior());
}

}  // namespace npfkct::sim
