#include "world_codec.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <utility>

#include "npfkct/api/api.h"
#include "npfkct/api/wire.h"
#include "npfkct/render/belief_picture.h"
#include "npfkct/robot/urdf.h"

namespace npfkct::api::internal {
namespace {

using object_search::Box;
using object_search::Vec2;
using object_search::Vec3;

using object_search::kGridResolution;

// The most cells a side of the occupancy map may have (the belief picture's warp takes images
// of fewer than 32,767 pixels a side), and the longest side of a piece of furniture (m, the
// schema's).
constexpr int64_t kMaxMapSide = 20'000;
constexpr double kMaxFurnitureSide = 20.0;

// ceil(x) as a count, saturating far below int64 overflow.
int64_t CeilCount(double x) {
  if (!(x > 0.0)) return 1;
  if (x > 1e15) return int64_t{1} << 50;
  return std::max<int64_t>(1, static_cast<int64_t>(std::ceil(x)));
}

int64_t SaturatingProduct(int64_t a, int64_t b) {
  if (a > 0 && b > std::numeric_limits<int64_t>::max() / 4 / a) {
    return std::numeric_limits<int64_t>::max() / 4;
  }
  return a * b;
}

Status Lost(const std::string& what) { return Status(StatusCode::kDataLoss, "snapshot: " + what); }

// The real-valued params a world spec may set ("params" of common.schema.json#/$defs/World;
// nOdds and maxSteps are its integers).
constexpr std::pair<const char*, double object_search::SearchParams::*> kWorldParams[] = {
    {"rMax", &object_search::SearchParams::r_max},
    {"rCt", &object_search::SearchParams::r_ct},
    {"rCo", &object_search::SearchParams::r_co},
    {"rMin", &object_search::SearchParams::r_min},
    {"rIll", &object_search::SearchParams::r_ill},
    {"discount", &object_search::SearchParams::discount},
    {"cO", &object_search::SearchParams::c_o},
    {"etaStd", &object_search::SearchParams::eta_std},
    {"nuP", &object_search::SearchParams::nu_p},
    {"nuN", &object_search::SearchParams::nu_n},
    {"declareThreshold", &object_search::SearchParams::declare_threshold},
    {"guessOdds", &object_search::SearchParams::guess_odds},
    {"guessSize", &object_search::SearchParams::guess_size},
    {"gridFreeDelta", &object_search::SearchParams::grid_free_delta}};
// The real-valued params a snapshot keeps besides those (they are the server's, not a request's).
constexpr std::pair<const char*, double object_search::SearchParams::*> kSnapshotOnlyParams[] = {
    {"guessMoveability", &object_search::SearchParams::guess_moveability},
    {"gridMin", &object_search::SearchParams::grid_min},
    {"gridMax", &object_search::SearchParams::grid_max},
    {"detectionMaxStep", &object_search::SearchParams::detection_max_step},
    {"faceOddsLimit", &object_search::SearchParams::face_odds_limit}};

// ---- snapshot parts (WorldJson / WorldFromJson) ----

json ParamsJson(const object_search::SearchParams& p) {
  json j = {{"nOdds", p.n_odds}, {"maxSteps", p.max_steps}};
  for (const auto& [key, field] : kWorldParams) j[key] = p.*field;
  for (const auto& [key, field] : kSnapshotOnlyParams) j[key] = p.*field;
  return j;
}

void ReadParams(const json& p, object_search::SearchParams* q) {
  for (const auto& [key, field] : kWorldParams) q->*field = Number(p, key, q->*field);
  for (const auto& [key, field] : kSnapshotOnlyParams) q->*field = Number(p, key, q->*field);
  q->n_odds = static_cast<int>(Integer(p, "nOdds", q->n_odds));
  q->max_steps =
      static_cast<int>(std::clamp<int64_t>(Integer(p, "maxSteps", q->max_steps), 1, 1'000'000));
}

// Occupancy as run lengths of alternating free / occupied cells, starting with free.
json OccupancyJson(const object_search::OccupancyMap& occupancy) {
  json runs = json::array();
  bool current = false;
  int64_t count = 0;
  for (uint8_t c : occupancy.cells()) {
    if ((c != 0) != current) {
      runs.push_back(count);
      current = c != 0;
      count = 0;
    }
    ++count;
  }
  runs.push_back(count);
  return {{"min", Vec(occupancy.min())},
          {"max", Vec(occupancy.max())},
          {"resolution", occupancy.resolution()},
          {"runs", runs}};
}

json GridJson(const object_search::GridWorld& grid) {
  json g;
  g["resolution"] = grid.resolution();
  g["workspaces"] = json::array();
  for (const auto& ws : grid.workspaces()) {
    g["workspaces"].push_back({{"name", ws.name},
                               {"center", Vec(ws.center)},
                               {"yaw", ws.yaw},
                               {"length", ws.length},
                               {"width", ws.width},
                               {"height", ws.height}});
  }
  g["logOdds"] = grid.all_log_odds();
  return g;
}

// ---- robots ----

using object_search::CameraJoint;
using object_search::RobotDescription;

constexpr const char* kJointTypes[] = {"fixed", "prismatic", "revolute"};
constexpr const char* kJointRoles[] = {"none", "lift", "pan", "tilt"};

// `s` (a status about a field of a robot) about the same field under `path`.
Status UnderPath(const std::string& path, const Status& s) {
  const auto& v = s.field_violations();
  return v.empty() ? InvalidFieldError(path, s.message())
                   : InvalidFieldError(Join(path, v[0].field), v[0].description);
}

// A robot's camera {horizontalFov, aspect, near, far}, each optional (appendix J's default).
void ReadCamera(const json& j, object_search::CameraModel* camera) {
  if (!j.is_object() || !j.contains("camera") || !j.at("camera").is_object()) return;
  const json& c = j.at("camera");
  camera->horizontal_fov = Number(c, "horizontalFov", camera->horizontal_fov);
  camera->aspect = Number(c, "aspect", camera->aspect);
  camera->near = Number(c, "near", camera->near);
  camera->far = Number(c, "far", camera->far);
}

// The footprint polygon of a schema-checked robot object (or a snapshot's): its [x, y] vertices,
// none when it has no "footprint".
std::vector<object_search::Vec2> ReadFootprint(const json& j) {
  std::vector<object_search::Vec2> out;
  const auto f = j.find("footprint");
  if (f == j.end() || !f->is_array()) return out;
  for (const json& v : *f) {
    object_search::Vec2 p = object_search::Vec2::Constant(std::nan(""));
    ReadVec(v, &p);  // left NaN when it is not two finite numbers: Validate names it
    out.push_back(p);
  }
  return out;
}

// A description's joints, name, footprint, reach and camera from a schema-checked object (or a
// snapshot's), validated; errors name the field under `path`.
StatusOr<RobotDescription> ReadDescription(const json& j, const std::string& path) {
  RobotDescription r;
  r.name = Utf8Prefix(String(j, "name", "custom"), 64);
  r.footprint_radius = Number(j, "footprintRadius", r.footprint_radius);
  r.footprint = ReadFootprint(j);
  r.reach = Number(j, "reach", r.reach);
  ReadCamera(j, &r.camera);
  const auto joints = j.find("joints");
  if (joints == j.end() || !joints->is_array() ||
      joints->size() > static_cast<size_t>(RobotDescription::kMaxJoints)) {
    return InvalidFieldError(Join(path, "joints"), "an array of at most 16 joints");
  }
  for (size_t i = 0; i < joints->size(); ++i) {
    const json& jj = (*joints)[i];
    const std::string at = Join(path, At("joints", i));
    if (!jj.is_object()) return InvalidFieldError(at, "a joint object");
    CameraJoint c;
    for (const auto& [key, v] : {std::pair{"xyz", &c.xyz}, {"rpy", &c.rpy}, {"axis", &c.axis}}) {
      if (jj.contains(key) && !ReadVec(jj.at(key), v)) {
        return InvalidFieldError(Join(at, key), "three numbers");
      }
    }
    c.name = Utf8Prefix(String(jj, "name"), 64);
    const std::string type = String(jj, "type", "fixed");
    const std::string role = String(jj, "role", "none");
    const auto* type_at = std::find(std::begin(kJointTypes), std::end(kJointTypes), type);
    const auto* role_at = std::find(std::begin(kJointRoles), std::end(kJointRoles), role);
    if (type_at == std::end(kJointTypes)) {
      return InvalidFieldError(Join(at, "type"), "fixed, prismatic or revolute");
    }
    if (role_at == std::end(kJointRoles)) {
      return InvalidFieldError(Join(at, "role"), "none, lift, pan or tilt");
    }
    c.type = static_cast<CameraJoint::Type>(type_at - std::begin(kJointTypes));
    c.role = static_cast<CameraJoint::Role>(role_at - std::begin(kJointRoles));
    c.lower = Number(jj, "lower");
    c.upper = Number(jj, "upper");
    r.chain.push_back(std::move(c));
  }
  if (Status s = r.Validate(); !s.ok()) return UnderPath(path, s);
  return r;
}

// The create request's robot: a shipped name, a description, or a URDF.
StatusOr<RobotDescription> ReadRobotSpec(const json& j, const std::string& path) {
  if (j.is_string()) {
    auto r = RobotDescription::ByName(j.get<std::string>());
    if (!r.ok()) return InvalidFieldError(path, "expected \"fetch\" or \"stretch\"");
    return r;
  }
  if (!j.is_object()) return InvalidFieldError(path, "a name, a description or a URDF");
  if (!j.contains("urdf")) return ReadDescription(j, path);
  robot::UrdfSelection s;
  s.name = Utf8Prefix(String(j, "name", "urdf"), 64);
  s.footprint_radius = Number(j, "footprintRadius", s.footprint_radius);
  s.reach = Number(j, "reach", s.reach);
  s.base_link = String(j, "baseLink");
  s.camera_link = String(j, "cameraLink");
  s.optical_frame = j.value("opticalFrame", false);
  s.lift_joint = String(j, "liftJoint");
  s.pan_joint = String(j, "panJoint");
  s.tilt_joint = String(j, "tiltJoint");
  auto r = robot::DescriptionFromUrdf(String(j, "urdf"), s);
  if (!r.ok()) return UnderPath(path, r.status());
  ReadCamera(j, &r->camera);
  r->footprint = ReadFootprint(j);  // checked here, so that its errors name it
  if (Status v = r->Validate(); !v.ok()) return UnderPath(path, v);
  return r;
}

// A snapshot's robot: its description, or (written before descriptions) a camera offset with
// a lift that moves it or not, and the lift, pan and tilt limits.
Status ReadRobot(const json& r, RobotDescription* robot) {
  if (r.is_object() && r.contains("joints")) {
    auto read = ReadDescription(r, "robot");
    if (!read.ok()) return Lost("robot");
    *robot = std::move(read).value();
    return OkStatus();
  }
  RobotDescription d;
  if (!r.is_object() || !r.contains("cameraOffset") ||
      !ReadVec(r.at("cameraOffset"), &d.chain.emplace_back().xyz)) {
    return Lost("robot");
  }
  d.name = Utf8Prefix(String(r, "name", "custom"), 64);
  CameraJoint& mount = d.chain.back();
  mount.name = "mount";
  if (r.value("liftMovesCamera", true)) {
    mount.type = CameraJoint::Type::kPrismatic;
    mount.role = CameraJoint::Role::kLift;
    mount.lower = Number(r, "liftMin");
    mount.upper = Number(r, "liftMax");
  }
  CameraJoint pan, tilt;
  pan.name = "pan";
  pan.type = tilt.type = CameraJoint::Type::kRevolute;
  pan.role = CameraJoint::Role::kPan;
  pan.lower = Number(r, "panMin");
  pan.upper = Number(r, "panMax");
  tilt.name = "tilt";
  tilt.role = CameraJoint::Role::kTilt;
  tilt.axis = Vec3::UnitY();
  tilt.lower = Number(r, "tiltMin");
  tilt.upper = Number(r, "tiltMax");
  d.chain.push_back(pan);
  d.chain.push_back(tilt);
  d.footprint_radius = Number(r, "footprintRadius", 0.3);
  d.reach = Number(r, "reach", 1.0);
  if (!d.Validate().ok()) return Lost("robot");
  *robot = std::move(d);
  return OkStatus();
}

}  // namespace

json RobotDescriptionJson(const RobotDescription& r) {
  json joints = json::array();
  for (const CameraJoint& c : r.chain) {
    json j = {{"name", c.name},
              {"type", kJointTypes[static_cast<int>(c.type)]},
              {"xyz", Vec(c.xyz)},
              {"rpy", Vec(c.rpy)}};
    if (c.type != CameraJoint::Type::kFixed) {
      j["role"] = kJointRoles[static_cast<int>(c.role)];
      j["axis"] = Vec(c.axis);
      j["lower"] = c.lower;
      j["upper"] = c.upper;
    }
    joints.push_back(std::move(j));
  }
  json out = {{"name", r.name},
              {"footprintRadius", r.footprint_radius},
              {"reach", r.reach},
              {"camera",
               {{"horizontalFov", r.camera.horizontal_fov},
                {"aspect", r.camera.aspect},
                {"near", r.camera.near},
                {"far", r.camera.far}}},
              {"joints", std::move(joints)}};
  if (!r.footprint.empty()) {
    out["footprint"] = json::array();
    for (const auto& v : r.footprint) out["footprint"].push_back(Vec(v));
  }
  return out;
}

json RobotJson(const RobotDescription& r) {
  // A shipped robot as its name, so that a spec reads as it was written.
  if (auto shipped = RobotDescription::ByName(r.name); shipped.ok() && *shipped == r) return r.name;
  return RobotDescriptionJson(r);
}

namespace {

Status ReadFurniture(const json& furniture, const Limits& limits, World* w) {
  if (!furniture.is_array() || static_cast<int64_t>(furniture.size()) > limits.max_furniture) {
    return Lost("furniture");
  }
  for (const json& b : furniture) {
    Box fb;
    if (!ReadBox(b, &fb) || fb.center.cwiseAbs().maxCoeff() > limits.max_coordinate) {
      return Lost("furniture box");
    }
    w->furniture.push_back(fb);
  }
  return OkStatus();
}

// The occupancy map, its cells counted against the limits before it is allocated.
Status ReadOccupancy(const json& occ, const Limits& limits, World* w) {
  Vec2 lo, hi;
  const double res = Number(occ, "resolution", 0.0);
  if (!occ.is_object() || !occ.contains("min") || !occ.contains("max") ||
      !ReadVec(occ.at("min"), &lo) || !ReadVec(occ.at("max"), &hi) || !(res >= 0.005) ||
      !((hi - lo).minCoeff() > 0) || lo.cwiseAbs().maxCoeff() > limits.max_coordinate ||
      hi.cwiseAbs().maxCoeff() > limits.max_coordinate ||
      MapCells(lo, hi, res) > limits.max_map_cells) {
    return Lost("occupancy extent");
  }
  w->occupancy = object_search::OccupancyMap(lo, hi, res);
  const size_t cell_count = w->occupancy.cells().size();
  if (!occ.contains("runs") || !occ.at("runs").is_array()) return Lost("occupancy runs");
  std::vector<uint8_t> cells;
  cells.reserve(cell_count);
  uint8_t value = 0;
  for (const json& run : occ.at("runs")) {
    if (!run.is_number_integer() || run.get<int64_t>() < 0 ||
        static_cast<uint64_t>(run.get<int64_t>()) > cell_count - cells.size()) {
      return Lost("occupancy run");
    }
    cells.insert(cells.end(), run.get<size_t>(), value);
    value = !value;
  }
  if (Status s = w->occupancy.SetCells(cells); !s.ok()) return Lost("occupancy cells");
  return OkStatus();
}

Status ReadRegionsAndPoses(const json& j, const Limits& limits, World* w) {
  const json& regions = j.at("baseRegions");
  if (!regions.is_array() || static_cast<int64_t>(regions.size()) > limits.max_base_regions) {
    return Lost("baseRegions");
  }
  for (const json& br : regions) {
    object_search::BaseRegion region;
    if (!br.is_object() || !br.contains("min") || !br.contains("max") ||
        !ReadVec(br.at("min"), &region.min) || !ReadVec(br.at("max"), &region.max)) {
      return Lost("base region");
    }
    w->base_regions.push_back(region);
  }
  if (j.contains("discretePoses")) {
    const json& poses = j.at("discretePoses");
    if (!poses.is_array() || static_cast<int64_t>(poses.size()) > limits.max_discrete_poses) {
      return Lost("discretePoses");
    }
    for (const json& pose : poses) w->discrete_poses.push_back(ReadConfig(pose));
  }
  return OkStatus();
}

// The grid world, its cells counted against the limits before it is allocated.
Status ReadGrid(const json& g, const Limits& limits, World* w) {
  if (!g.is_object() || !g.contains("workspaces") || !g.at("workspaces").is_array() ||
      !g.contains("logOdds") || !g.at("logOdds").is_array() ||
      static_cast<int64_t>(g.at("workspaces").size()) > limits.max_furniture) {
    return Lost("grid");
  }
  std::vector<object_search::Workspace> workspaces;
  for (const json& ws : g.at("workspaces")) {
    object_search::Workspace s;
    s.name = Utf8Prefix(String(ws, "name"), HardLimits().max_id_length);  // as furniture names
    if (!ws.is_object() || !ws.contains("center") || !ReadVec(ws.at("center"), &s.center)) {
      return Lost("grid workspace");
    }
    s.yaw = Number(ws, "yaw");
    s.length = Number(ws, "length", 1.0);
    s.width = Number(ws, "width", 1.0);
    s.height = Number(ws, "height", 0.75);
    if (!(s.length > 0 && s.width > 0 && s.length <= 100 && s.width <= 100)) {
      return Lost("grid workspace size");
    }
    workspaces.push_back(s);
  }
  const double grid_resolution = Number(g, "resolution", kGridResolution);
  if (!(grid_resolution >= 0.005 && grid_resolution <= 1.0) ||
      GridCells(workspaces, grid_resolution) > limits.max_grid_cells ||
      static_cast<int64_t>(g.at("logOdds").size()) != GridCells(workspaces, grid_resolution)) {
    return Lost("grid size");
  }
  w->grid = object_search::GridWorld(workspaces, grid_resolution);
  if (!w->grid.Validate().ok()) return Lost("grid");
  std::vector<float> odds;
  odds.reserve(g.at("logOdds").size());
  for (const json& v : g.at("logOdds")) {
    if (!v.is_number()) return Lost("grid log-odds");
    odds.push_back(v.get<float>());
  }
  if (!w->grid.SetAllLogOdds(odds).ok()) return Lost("grid log-odds");
  return OkStatus();
}

Status ReadObjects(const json& objects, const Limits& limits, World* w) {
  if (!objects.is_array() || objects.empty() ||
      static_cast<int64_t>(objects.size()) > limits.max_objects + 1) {
    return Lost("objects");
  }
  for (const json& o : objects) {
    object_search::ObjectKnowledge k;
    if (!o.is_object() || !o.contains("odds") || !o.at("odds").is_array() ||
        o.at("odds").size() != 8 || !o.contains("box") || !ReadBox(o.at("box"), &k.box)) {
      return Lost("object");
    }
    k.key = Utf8Prefix(String(o, "id"), HardLimits().max_id_length);
    k.moveability = Number(o, "moveability", 1.0);
    k.removal_failed = Bool(o, "removalFailed", false);
    for (int i = 0; i < 8; ++i) {
      if (!o.at("odds")[i].is_number()) return Lost("object odds");
      k.odds[i] = o.at("odds")[i].get<float>();
    }
    const int64_t status = Integer(o, "status", object_search::kUpdating);
    if (status < object_search::kRemoved || status > object_search::kDeclaredTarget) {
      return Lost("object status");
    }
    k.status = static_cast<int8_t>(status);
    w->objects.push_back(k);
  }
  return OkStatus();
}

}  // namespace

int64_t GridCells(const std::vector<object_search::Workspace>& workspaces, double resolution) {
  int64_t total = 0;
  for (const object_search::Workspace& w : workspaces) {
    // GridWorld's count: max(1, ceil(extent / resolution - 1e-9)) per axis.
    const int64_t nx = CeilCount(w.length / resolution - 1e-9);
    const int64_t ny = CeilCount(w.width / resolution - 1e-9);
    total = std::min<int64_t>(total + SaturatingProduct(nx, ny),
                              std::numeric_limits<int64_t>::max() / 4);
  }
  return total;
}

int64_t MapCells(const Vec2& lo, const Vec2& hi, double resolution) {
  return SaturatingProduct(CeilCount((hi.x() - lo.x()) / resolution),
                           CeilCount((hi.y() - lo.y()) / resolution));
}

// A SLAM occupancy grid as the OccupancyGrid message has it: resolution, origin [x, y, yaw] of
// cell (0, 0)'s corner, width x height cells row by row from the origin, data base64 int8 (-1
// unknown, 0-100 occupied); a cell at occupiedThreshold or above, or unknown, is where the base
// may not stand. Gives the room, its resolution and its cells; counted before it is allocated.
Status ReadOccupancyGrid(const json& g, const std::string& path, const Limits& limits,
                         WorldSpec* spec) {
  const double resolution = Number(g, "resolution", 0.05);
  const int64_t width = Integer(g, "width", 0), height = Integer(g, "height", 0);
  if (SaturatingProduct(width, height) > limits.max_map_cells) {
    return InvalidFieldError(
        Join(path, "width"),
        "width x height is more than " + std::to_string(limits.max_map_cells) + " cells");
  }
  const json& origin = g.at("origin");
  if (origin.size() > 2 && origin[2].get<double>() != 0.0) {
    return InvalidFieldError(Join(path, "origin") + "[2]",
                             "a rotated map is not supported: its yaw must be 0");
  }
  const Vec2 lo(origin[0].get<double>(), origin[1].get<double>());
  // The map's far edges stay within the coordinates the API takes (a pose beyond them could be
  // planned and then not observed, and the session's snapshot not read back).
  const Vec2 hi = lo + Vec2(static_cast<double>(width), static_cast<double>(height)) * resolution;
  if (!(hi.x() <= limits.max_coordinate && hi.y() <= limits.max_coordinate)) {
    return InvalidFieldError(Join(path, hi.x() > limits.max_coordinate ? "width" : "height"),
                             "the map would reach past " + std::to_string(limits.max_coordinate) +
                                 " m from the origin of the map frame");
  }
  if (width > kMaxMapSide || height > kMaxMapSide) {
    return InvalidFieldError(Join(path, width > kMaxMapSide ? "width" : "height"),
                             "at most " + std::to_string(kMaxMapSide) + " cells a side");
  }
  auto data = Base64Decode(g.at("data").get<std::string>(), Join(path, "data"),
                           static_cast<size_t>(width * height));
  if (!data.ok()) return data.status();
  if (static_cast<int64_t>(data->size()) != width * height) {
    return InvalidFieldError(Join(path, "data"), std::to_string(data->size()) +
                                                     " cells; width x height is " +
                                                     std::to_string(width * height));
  }
  const int threshold = static_cast<int>(Integer(g, "occupiedThreshold", 65));
  spec->room_min = lo;
  // A hair less than whole cells, so that counting them again (a ceiling) gives width x height.
  spec->room_max = lo + Vec2(width - 1e-6, height - 1e-6) * resolution;
  spec->map_resolution = resolution;
  spec->occupied.resize(data->size());
  for (size_t i = 0; i < data->size(); ++i) {
    const int v = static_cast<int8_t>((*data)[i]);
    if (v < -1 || v > 100) {
      return InvalidFieldError(Join(path, "data"), "cell " + std::to_string(i) + " is " +
                                                       std::to_string(v) +
                                                       "; a cell is -1 (unknown) or 0-100");
    }
    spec->occupied[i] = v < 0 || v >= threshold ? 1 : 0;
  }
  return OkStatus();
}

StatusOr<WorldSpec> ReadWorldSpec(const json& j, const std::string& path, const Limits& limits) {
  WorldSpec spec;
  if (j.contains("robot")) {
    auto robot = ReadRobotSpec(j.at("robot"), Join(path, "robot"));
    if (!robot.ok()) return robot.status();
    spec.robot = std::move(robot).value();
  }
  if (j.contains("room")) {
    const json& room = j.at("room");
    ReadVec(room.at("min"), &spec.room_min);
    ReadVec(room.at("max"), &spec.room_max);
    if (!(spec.room_min.x() < spec.room_max.x() && spec.room_min.y() < spec.room_max.y())) {
      return InvalidFieldError(Join(path, "room.max"), "must be above room.min in x and y");
    }
  }
  spec.map_resolution = Number(j, "mapResolution", spec.map_resolution);
  if (j.contains("occupancyGrid")) {
    if (j.contains("room") || j.contains("mapResolution")) {
      return InvalidFieldError(Join(path, j.contains("room") ? "room" : "mapResolution"),
                               "the occupancy grid gives the room and its resolution");
    }
    if (Status s =
            ReadOccupancyGrid(j.at("occupancyGrid"), Join(path, "occupancyGrid"), limits, &spec);
        !s.ok()) {
      return s;
    }
  }
  const int64_t map_cells = MapCells(spec.room_min, spec.room_max, spec.map_resolution);
  if (CeilCount((spec.room_max.x() - spec.room_min.x()) / spec.map_resolution) > kMaxMapSide ||
      CeilCount((spec.room_max.y() - spec.room_min.y()) / spec.map_resolution) > kMaxMapSide) {
    return InvalidFieldError(Join(path, "mapResolution"),
                             "the occupancy map of the room would have more than " +
                                 std::to_string(kMaxMapSide) + " cells a side");
  }
  if (map_cells > limits.max_map_cells) {
    return InvalidFieldError(Join(path, "mapResolution"),
                             "the occupancy map of the room would have " +
                                 std::to_string(map_cells) + " cells, more than " +
                                 std::to_string(limits.max_map_cells) +
                                 " (use a coarser resolution or a smaller room)");
  }
  const json none = json::array();
  const json& furniture = j.contains("furniture") ? j.at("furniture") : none;
  const json& traced = j.contains("workspaces") ? j.at("workspaces") : none;
  if (static_cast<int64_t>(furniture.size() + traced.size()) > limits.max_furniture) {
    return InvalidFieldError(Join(path, traced.empty() ? "furniture" : "workspaces"),
                             "at most " + std::to_string(limits.max_furniture) +
                                 " pieces of furniture and workspaces together");
  }
  std::set<std::string> names;
  int64_t grid_cells = 0;
  for (size_t i = 0; i < furniture.size() + traced.size(); ++i) {
    const bool polygon = i >= furniture.size();
    const json& f = polygon ? traced[i - furniture.size()] : furniture[i];
    const std::string at = polygon ? At(Join(path, "workspaces"), i - furniture.size())
                                   : At(Join(path, "furniture"), i);
    WorldSpec::Furniture piece;
    piece.name = String(f, "name");
    if (!names.insert(piece.name).second) {
      return InvalidFieldError(at + ".name", "duplicate name '" + piece.name + "'");
    }
    Vec2 center = Vec2::Zero();
    if (polygon) {  // a workspace traced as a polygon with its height: the box around it
      std::vector<Vec2> points;
      for (const json& p : f.at("polygon")) ReadVec(p, &points.emplace_back());
      auto box = object_search::BoxAroundPolygon(points, Number(f, "height", 0.0));
      if (!box.ok()) return InvalidFieldError(at + ".polygon", box.status().message());
      if (box->size.x() > kMaxFurnitureSide || box->size.y() > kMaxFurnitureSide) {
        return InvalidFieldError(at + ".polygon",
                                 "the rectangle around it is more than " +
                                     std::to_string(static_cast<int>(kMaxFurnitureSide)) +
                                     " m long, as no piece of furniture may be");
      }
      piece.box = *box;
      piece.workspace = true;
      center = piece.box.center.head<2>();
    } else {
      ReadVec(f.at("center"), &center);
      ReadVec(f.at("size"), &piece.box.size);
      piece.box.yaw = Number(f, "yaw", 0.0);
      piece.box.center = Vec3(center.x(), center.y(), 0.5 * piece.box.size.z());
      piece.workspace = Bool(f, "workspace", false);
    }
    if (piece.workspace) {
      grid_cells += GridCells({{piece.name, center, piece.box.yaw, piece.box.size.x(),
                                piece.box.size.y(), piece.box.size.z()}},
                              kGridResolution);
      if (grid_cells > limits.max_grid_cells) {
        return InvalidFieldError(at + (polygon ? ".polygon" : ".size"),
                                 "the workspaces would have more than " +
                                     std::to_string(limits.max_grid_cells) +
                                     " grid-world cells of 2 cm together");
      }
    }
    spec.furniture.push_back(std::move(piece));
  }
  if (grid_cells == 0) {
    return InvalidFieldError(Join(path, "furniture"), "at least one piece must be a workspace");
  }
  const json& regions = j.contains("baseRegions") ? j.at("baseRegions") : none;
  if (regions.empty() && static_cast<int64_t>(object_search::BaseRegionsAround(spec).size()) >
                             limits.max_base_regions) {
    return InvalidFieldError(Join(path, "baseRegions"),
                             "needed: the regions around the workspaces would be more than " +
                                 std::to_string(limits.max_base_regions));
  }
  if (static_cast<int64_t>(regions.size()) > limits.max_base_regions) {
    return InvalidFieldError(Join(path, "baseRegions"),
                             "at most " + std::to_string(limits.max_base_regions) + " regions");
  }
  for (size_t i = 0; i < regions.size(); ++i) {
    object_search::BaseRegion r;
    ReadVec(regions[i].at("min"), &r.min);
    ReadVec(regions[i].at("max"), &r.max);
    if (!(r.min.x() < r.max.x() && r.min.y() < r.max.y())) {
      return InvalidFieldError(At(Join(path, "baseRegions"), i) + ".max",
                               "must be above min in x and y");
    }
    spec.base_regions.push_back(r);
  }
  if (j.contains("discretePoses")) {
    const json& poses = j.at("discretePoses");
    if (static_cast<int64_t>(poses.size()) > limits.max_discrete_poses) {
      return InvalidFieldError(Join(path, "discretePoses"),
                               "at most " + std::to_string(limits.max_discrete_poses) + " poses");
    }
    for (const json& p : poses) spec.discrete_poses.push_back(ReadConfig(p));
  }
  if (j.contains("start")) spec.start = ReadConfig(j.at("start"));
  if (j.contains("params")) {
    const json& p = j.at("params");
    auto& q = spec.params;
    for (auto [key, field] : kWorldParams) q.*field = Number(p, key, q.*field);
    q.n_odds = static_cast<int>(Integer(p, "nOdds", q.n_odds));
    q.max_steps = static_cast<int>(Integer(p, "maxSteps", q.max_steps));
    if (Status s = q.Validate(); !s.ok())
      return InvalidFieldError(Join(path, "params"), s.message());
  }
  return spec;
}

json WorldSpecJson(const WorldSpec& spec) {
  json j;
  j["robot"] = RobotJson(spec.robot);
  if (spec.occupied.empty()) {
    j["room"] = {{"min", Vec(spec.room_min)}, {"max", Vec(spec.room_max)}};
    j["mapResolution"] = spec.map_resolution;
  } else {  // the occupancy grid it was read from: its cells as occupied (100) or free (0)
    const object_search::OccupancyMap map(spec.room_min, spec.room_max, spec.map_resolution);
    std::string cells(spec.occupied.size(), '\0');
    for (size_t i = 0; i < cells.size(); ++i) cells[i] = spec.occupied[i] ? 100 : 0;
    j["occupancyGrid"] = {{"resolution", spec.map_resolution},
                          {"origin", {spec.room_min.x(), spec.room_min.y(), 0.0}},
                          {"width", map.nx()},
                          {"height", map.ny()},
                          {"data", Base64Encode(cells)}};
  }
  j["furniture"] = json::array();
  for (const WorldSpec::Furniture& f : spec.furniture) {
    // Furniture stands on the floor: ReadWorldSpec puts its center at half its height.
    j["furniture"].push_back({{"name", f.name},
                              {"center", Vec(Vec2(f.box.center.x(), f.box.center.y()))},
                              {"size", Vec(f.box.size)},
                              {"yaw", f.box.yaw},
                              {"workspace", f.workspace}});
  }
  if (!spec.base_regions.empty()) {  // none: the server places them around the workspaces
    j["baseRegions"] = json::array();
    for (const object_search::BaseRegion& r : spec.base_regions) {
      j["baseRegions"].push_back({{"min", Vec(r.min)}, {"max", Vec(r.max)}});
    }
  }
  if (!spec.discrete_poses.empty()) {
    j["discretePoses"] = json::array();
    for (const object_search::RobotConfig& c : spec.discrete_poses) {
      j["discretePoses"].push_back({{"x", c.x}, {"y", c.y}, {"yaw", c.yaw}});
    }
  }
  j["start"] = ConfigJson(spec.start);
  // The params that differ from the defaults, which the server takes for the others.
  const object_search::SearchParams defaults;
  json params = json::object();
  for (auto [key, field] : kWorldParams) {
    if (spec.params.*field != defaults.*field) params[key] = spec.params.*field;
  }
  if (spec.params.n_odds != defaults.n_odds) params["nOdds"] = spec.params.n_odds;
  if (spec.params.max_steps != defaults.max_steps) params["maxSteps"] = spec.params.max_steps;
  if (!params.empty()) j["params"] = params;
  return j;
}

json WorldJson(const World& w) {
  json j;
  j["robot"] = RobotDescriptionJson(w.robot);
  j["camera"] = {{"horizontalFov", w.camera.horizontal_fov},
                 {"aspect", w.camera.aspect},
                 {"near", w.camera.near},
                 {"far", w.camera.far}};
  j["params"] = ParamsJson(w.params);
  j["furniture"] = json::array();
  for (const Box& b : w.furniture) j["furniture"].push_back(BoxJson(b));
  j["occupancy"] = OccupancyJson(w.occupancy);
  j["baseRegions"] = json::array();
  for (const auto& br : w.base_regions) {
    j["baseRegions"].push_back({{"min", Vec(br.min)}, {"max", Vec(br.max)}});
  }
  j["discretePoses"] = json::array();
  for (const auto& c : w.discrete_poses) j["discretePoses"].push_back(ConfigJson(c));
  j["grid"] = GridJson(w.grid);
  j["objects"] = json::array();
  for (const auto& o : w.objects) {
    json object = {{"id", o.key},
                   {"box", BoxJson(o.box)},
                   {"moveability", o.moveability},
                   {"odds", o.odds},
                   {"status", o.status}};
    if (o.removal_failed) object["removalFailed"] = true;
    j["objects"].push_back(std::move(object));
  }
  j["robotConfig"] = ConfigJson(w.robot_config);
  j["steps"] = w.steps;
  return j;
}

StatusOr<World> WorldFromJson(const json& j, const Limits& limits) {
  World w;
  if (!j.is_object()) return Lost("world is not an object");
  for (const char* key : {"robot", "camera", "params", "furniture", "occupancy", "baseRegions",
                          "grid", "objects", "robotConfig"}) {
    if (!j.contains(key)) return Lost(std::string("world: missing ") + key);
  }
  if (Status s = ReadRobot(j.at("robot"), &w.robot); !s.ok()) return s;
  const json& c = j.at("camera");
  w.camera.horizontal_fov = Number(c, "horizontalFov", w.camera.horizontal_fov);
  w.camera.aspect = Number(c, "aspect", w.camera.aspect);
  w.camera.near = Number(c, "near", w.camera.near);
  w.camera.far = Number(c, "far", w.camera.far);
  ReadParams(j.at("params"), &w.params);
  if (Status s = ReadFurniture(j.at("furniture"), limits, &w); !s.ok()) return s;
  if (Status s = ReadOccupancy(j.at("occupancy"), limits, &w); !s.ok()) return s;
  if (Status s = ReadRegionsAndPoses(j, limits, &w); !s.ok()) return s;
  if (Status s = ReadGrid(j.at("grid"), limits, &w); !s.ok()) return s;
  if (Status s = ReadObjects(j.at("objects"), limits, &w); !s.ok()) return s;
  w.robot_config = ReadConfig(j.at("robotConfig"));
  w.steps = static_cast<int>(std::clamp<int64_t>(Integer(j, "steps"), 0, 1'000'000));
  if (Status s = w.Validate(); !s.ok()) return Lost("world: " + s.message());
  return w;
}

json FrustumJson(const World& w, const RobotConfig& c) {
  json out = json::array();
  for (const Vec2& p : render::FrustumFootprint(w, c)) out.push_back(Vec(p));
  return out;
}

json BeliefJson(const World& w, const SessionView* session) {
  json j;
  j["robot"] = ConfigJson(w.robot_config);
  j["step"] = w.steps;
  // What the web console draws: the same crop, frusta and colours as the PNG (npfkct/render).
  j["camera"] = {{"frustum", FrustumJson(w, w.robot_config)}};
  j["robotRadius"] = w.robot.footprint_radius;
  if (!w.robot.footprint.empty()) {
    j["robotFootprint"] = json::array();
    for (const auto& v : w.robot.footprint) j["robotFootprint"].push_back(Vec(v));
  }
  std::optional<RobotConfig> next;
  if (session && session->pending && session->pending->second.type == ActionView::Type::kMove) {
    next = session->pending->second.configuration;
    j["nextView"] = {{"actionId", session->pending->first},
                     {"configuration", ConfigJson(*next)},
                     {"frustum", FrustumJson(w, *next)}};
  }
  const auto [lo, hi] = render::CropBounds(w, next, render::BeliefPictureOptions{}.margin);
  j["view"] = {{"min", Vec(lo)}, {"max", Vec(hi)}};
  j["furniture"] = json::array();
  for (const Box& b : w.furniture) j["furniture"].push_back(BoxJson(b));
  j["baseRegions"] = json::array();
  for (const auto& br : w.base_regions) {
    j["baseRegions"].push_back({{"min", Vec(br.min)}, {"max", Vec(br.max)}});
  }
  j["grid"]["resolution"] = w.grid.resolution();
  j["grid"]["workspaces"] = json::array();
  const auto mass = w.grid.WorkspaceMass();
  const auto& all = w.grid.all_log_odds();
  for (size_t i = 0; i < w.grid.workspaces().size(); ++i) {
    const auto& ws = w.grid.workspaces()[i];
    const int wi = static_cast<int>(i);
    const size_t n = static_cast<size_t>(w.grid.cells_x(wi)) * w.grid.cells_y(wi);
    const size_t first = static_cast<size_t>(w.grid.Index(wi, 0, 0));
    std::vector<float> odds(all.begin() + first, all.begin() + first + n);
    j["grid"]["workspaces"].push_back({{"name", ws.name},
                                       {"center", Vec(ws.center)},
                                       {"yaw", ws.yaw},
                                       {"length", ws.length},
                                       {"width", ws.width},
                                       {"height", ws.height},
                                       {"cellsX", w.grid.cells_x(wi)},
                                       {"cellsY", w.grid.cells_y(wi)},
                                       {"targetMass", mass[i]},
                                       {"logOdds", odds}});
  }
  j["objects"] = json::array();
  static const char* kStatus[] = {"REMOVED", "UPDATING", "DECLARED_OBSTACLE", "DECLARED_TARGET"};
  for (size_t i = 1; i < w.objects.size(); ++i) {
    const auto& o = w.objects[i];
    double mean = 0.0;
    for (float v : o.odds) mean += v;
    mean /= 8.0;
    j["objects"].push_back({{"id", o.key},
                            {"box", BoxJson(o.box)},
                            {"faceLogOdds", o.odds},
                            {"status", kStatus[std::clamp(o.status + 2, 0, 3)]},
                            {"moveability", o.moveability},
                            {"removalFailed", o.removal_failed},
                            {"targetProbability", 1.0 / (1.0 + std::exp(-mean))}});
  }
  return j;
}

}  // namespace npfkct::api::internal

namespace npfkct::api {

StatusOr<object_search::RobotDescription> ParseRobot(std::string_view json_text,
                                                     const std::string& path) {
  if (json_text.size() > (size_t{2} << 20)) return InvalidFieldError(path, "at most 2 MiB");
  // Wrapped in an object, which is what the bounded parser reads (the robot may be a name).
  const std::string text = "{\"robot\": " + std::string(json_text) + "}";
  auto j = internal::ParseBody(text, 16, 100'000, false);
  if (!j.ok()) return InvalidFieldError(path, "not JSON");
  return internal::ReadRobotSpec(j->at("robot"), path);
}

std::string RobotText(const object_search::RobotDescription& robot) {
  return internal::RobotJson(robot).dump();
}

StatusOr<World> BuildWorld(const WorldSpec& spec, const Limits& limits) {
  using internal::GridCells;
  using internal::MapCells;
  // The same counts as in ReadWorldSpec, again: a WorldSpec may be built in code.
  if (MapCells(spec.room_min, spec.room_max, spec.map_resolution) > limits.max_map_cells ||
      !(spec.map_resolution >= 0.005)) {
    return InvalidFieldError("world.mapResolution", "the occupancy map would be too large");
  }
  const auto workspaces = spec.Workspaces();
  if (GridCells(workspaces, object_search::kGridResolution) > limits.max_grid_cells) {
    return InvalidFieldError("world.furniture", "the workspaces' grid world would be too large");
  }
  if (static_cast<int64_t>(spec.furniture.size()) > limits.max_furniture) {
    return InvalidFieldError("world.furniture", "too many pieces");
  }
  auto world = object_search::BuildWorld(spec);
  if (!world.ok()) {
    // The builder names the part of the prior map; here it is a field of the request's world.
    const Status& s = world.status();
    if (!s.field_violations().empty()) {
      const FieldViolation& v = s.field_violations().front();
      return InvalidFieldError("world." + v.field, v.description);
    }
    return InvalidFieldError("world", s.message());
  }
  return *std::move(world);
}

}  // namespace npfkct::api
