#include "npfkct/server/codec.h"

#include <cctype>
#include <cmath>

#include "npfkct/object_search/model.h"
#include "npfkct/sim/json_read.h"

namespace npfkct::server {
namespace {

using namespace sim::json_read;  // NOLINT: field readers
using object_search::Box;
using object_search::Vec2;
using object_search::Vec3;
using object_search::World;

json Vec(const Vec3& v) { return json::array({v.x(), v.y(), v.z()}); }
json Vec(const Vec2& v) { return json::array({v.x(), v.y()}); }

#define RETURN_IF_ERROR(expr) \
  do {                        \
    Status _s = (expr);       \
    if (!_s.ok()) return _s;  \
  } while (0)

// Snapshot readers trust the shape less than the API readers do not: they still check it, so that
// a corrupted state file is an error, not a crash.
Status Need(bool ok, const std::string& what) {
  return ok ? OkStatus() : Status(StatusCode::kDataLoss, "snapshot: " + what);
}

double Num(const json& j, const char* key, double fallback = 0.0) {
  return j.contains(key) && j.at(key).is_number() ? j.at(key).get<double>() : fallback;
}

}  // namespace

json ConfigToJson(const object_search::RobotConfig& c) {
  return {{"x", c.x},       {"y", c.y},     {"yaw", c.yaw},
          {"lift", c.lift}, {"pan", c.pan}, {"tilt", c.tilt}};
}

json BoxToJson(const Box& b) {
  return {{"center", Vec(b.center)}, {"yaw", b.yaw}, {"size", Vec(b.size)}};
}

Status BoxFromJson(const json& j, const std::string& path, Box* b) {
  if (!j.is_object()) return Err(path, "expected an object");
  RETURN_IF_ERROR(CheckKeys(j, path + ".", {"center", "yaw", "size"}));
  RETURN_IF_ERROR(ReadVector<3>(j, "center", path + ".", &b->center, true));
  RETURN_IF_ERROR(ReadVector<3>(j, "size", path + ".", &b->size, true));
  RETURN_IF_ERROR(ReadNumber(j, "yaw", path + ".", &b->yaw, false));
  if (!(b->size.minCoeff() > 0.0) || b->size.maxCoeff() > 100.0) {
    return Err(path + ".size", "each extent must be in (0, 100] m");
  }
  if (b->center.cwiseAbs().maxCoeff() > 1e4) return Err(path + ".center", "too far away");
  return OkStatus();
}

std::string StatusName(int8_t status) {
  switch (status) {
    case object_search::kRemoved:
      return "REMOVED";
    case object_search::kDeclaredObstacle:
      return "DECLARED_OBSTACLE";
    case object_search::kDeclaredTarget:
      return "DECLARED_TARGET";
    default:
      return "UPDATING";
  }
}

json WorldToJson(const World& w) {
  json j;
  const auto& r = w.robot;
  j["robot"] = {{"name", r.name},
                {"cameraOffset", Vec(r.camera_offset)},
                {"liftMovesCamera", r.lift_moves_camera},
                {"liftMin", r.lift_min},
                {"liftMax", r.lift_max},
                {"panMin", r.pan_min},
                {"panMax", r.pan_max},
                {"tiltMin", r.tilt_min},
                {"tiltMax", r.tilt_max},
                {"footprintRadius", r.footprint_radius},
                {"reach", r.reach}};
  j["camera"] = {{"horizontalFov", w.camera.horizontal_fov},
                 {"aspect", w.camera.aspect},
                 {"near", w.camera.near},
                 {"far", w.camera.far}};
  const auto& p = w.params;
  j["params"] = {{"rMax", p.r_max},
                 {"rCt", p.r_ct},
                 {"rCo", p.r_co},
                 {"rMin", p.r_min},
                 {"rIll", p.r_ill},
                 {"discount", p.discount},
                 {"cO", p.c_o},
                 {"etaStd", p.eta_std},
                 {"nuP", p.nu_p},
                 {"nuN", p.nu_n},
                 {"nOdds", p.n_odds},
                 {"declareThreshold", p.declare_threshold},
                 {"guessOdds", p.guess_odds},
                 {"guessSize", p.guess_size},
                 {"guessMoveability", p.guess_moveability},
                 {"gridFreeDelta", p.grid_free_delta},
                 {"gridMin", p.grid_min},
                 {"gridMax", p.grid_max},
                 {"detectionMaxStep", p.detection_max_step},
                 {"faceOddsLimit", p.face_odds_limit},
                 {"maxSteps", p.max_steps}};
  j["furniture"] = json::array();
  for (const Box& b : w.furniture) j["furniture"].push_back(BoxToJson(b));
  // Occupancy as run lengths of alternating free / occupied cells, starting with free.
  json runs = json::array();
  uint8_t current = 0;
  int64_t count = 0;
  for (uint8_t c : w.occupancy.cells()) {
    if ((c != 0) != (current != 0)) {
      runs.push_back(count);
      current = c != 0;
      count = 0;
    }
    ++count;
  }
  runs.push_back(count);
  j["occupancy"] = {{"min", Vec(w.occupancy.min())},
                    {"max", Vec(w.occupancy.max())},
                    {"resolution", w.occupancy.resolution()},
                    {"runs", runs}};
  j["baseRegions"] = json::array();
  for (const auto& br : w.base_regions) {
    j["baseRegions"].push_back({{"min", Vec(br.min)}, {"max", Vec(br.max)}});
  }
  j["discretePoses"] = json::array();
  for (const auto& c : w.discrete_poses) j["discretePoses"].push_back(ConfigToJson(c));
  j["grid"]["resolution"] = w.grid.resolution();
  j["grid"]["workspaces"] = json::array();
  for (const auto& ws : w.grid.workspaces()) {
    j["grid"]["workspaces"].push_back({{"name", ws.name},
                                       {"center", Vec(ws.center)},
                                       {"yaw", ws.yaw},
                                       {"length", ws.length},
                                       {"width", ws.width},
                                       {"height", ws.height}});
  }
  j["grid"]["logOdds"] = w.grid.all_log_odds();
  j["objects"] = json::array();
  for (const auto& o : w.objects) {
    j["objects"].push_back({{"id", o.key},
                            {"box", BoxToJson(o.box)},
                            {"moveability", o.moveability},
                            {"odds", o.odds},
                            {"status", o.status}});
  }
  j["robotConfig"] = ConfigToJson(w.robot_config);
  j["steps"] = w.steps;
  return j;
}

StatusOr<World> WorldFromJson(const json& j) {
  World w;
  RETURN_IF_ERROR(Need(j.is_object(), "world is not an object"));
  for (const char* key : {"robot", "camera", "params", "furniture", "occupancy", "baseRegions",
                          "grid", "objects", "robotConfig"}) {
    RETURN_IF_ERROR(Need(j.contains(key), std::string("missing ") + key));
  }
  const json& r = j.at("robot");
  RETURN_IF_ERROR(Need(r.is_object() && r.contains("cameraOffset") &&
                           r.at("cameraOffset").is_array() && r.at("cameraOffset").size() == 3,
                       "robot"));
  w.robot.name = r.value("name", std::string("custom"));
  for (int i = 0; i < 3; ++i) w.robot.camera_offset[i] = r.at("cameraOffset")[i].get<double>();
  w.robot.lift_moves_camera = r.value("liftMovesCamera", true);
  w.robot.lift_min = Num(r, "liftMin");
  w.robot.lift_max = Num(r, "liftMax");
  w.robot.pan_min = Num(r, "panMin");
  w.robot.pan_max = Num(r, "panMax");
  w.robot.tilt_min = Num(r, "tiltMin");
  w.robot.tilt_max = Num(r, "tiltMax");
  w.robot.footprint_radius = Num(r, "footprintRadius", 0.3);
  w.robot.reach = Num(r, "reach", 1.0);
  const json& c = j.at("camera");
  w.camera.horizontal_fov = Num(c, "horizontalFov", w.camera.horizontal_fov);
  w.camera.aspect = Num(c, "aspect", w.camera.aspect);
  w.camera.near = Num(c, "near", w.camera.near);
  w.camera.far = Num(c, "far", w.camera.far);
  const json& p = j.at("params");
  auto& q = w.params;
  q.r_max = Num(p, "rMax", q.r_max);
  q.r_ct = Num(p, "rCt", q.r_ct);
  q.r_co = Num(p, "rCo", q.r_co);
  q.r_min = Num(p, "rMin", q.r_min);
  q.r_ill = Num(p, "rIll", q.r_ill);
  q.discount = Num(p, "discount", q.discount);
  q.c_o = Num(p, "cO", q.c_o);
  q.eta_std = Num(p, "etaStd", q.eta_std);
  q.nu_p = Num(p, "nuP", q.nu_p);
  q.nu_n = Num(p, "nuN", q.nu_n);
  q.n_odds = static_cast<int>(Num(p, "nOdds", q.n_odds));
  q.declare_threshold = Num(p, "declareThreshold", q.declare_threshold);
  q.guess_odds = Num(p, "guessOdds", q.guess_odds);
  q.guess_size = Num(p, "guessSize", q.guess_size);
  q.guess_moveability = Num(p, "guessMoveability", q.guess_moveability);
  q.grid_free_delta = Num(p, "gridFreeDelta", q.grid_free_delta);
  q.grid_min = Num(p, "gridMin", q.grid_min);
  q.grid_max = Num(p, "gridMax", q.grid_max);
  q.detection_max_step = Num(p, "detectionMaxStep", q.detection_max_step);
  q.face_odds_limit = Num(p, "faceOddsLimit", q.face_odds_limit);
  q.max_steps = static_cast<int>(Num(p, "maxSteps", q.max_steps));
  auto box = [](const json& b, Box* out) { return BoxFromJson(b, "snapshot box", out); };
  RETURN_IF_ERROR(Need(j.at("furniture").is_array(), "furniture"));
  for (const json& b : j.at("furniture")) {
    Box fb;
    RETURN_IF_ERROR(box(b, &fb));
    w.furniture.push_back(fb);
  }
  const json& occ = j.at("occupancy");
  Vec2 lo, hi;
  RETURN_IF_ERROR(ReadVector<2>(occ, "min", "occupancy.", &lo, true));
  RETURN_IF_ERROR(ReadVector<2>(occ, "max", "occupancy.", &hi, true));
  const double res = Num(occ, "resolution", 0.05);
  RETURN_IF_ERROR(Need(res > 0 && (hi - lo).minCoeff() > 0 && (hi - lo).prod() / (res * res) < 1e8,
                       "occupancy extent"));
  w.occupancy = object_search::OccupancyMap(lo, hi, res);
  std::vector<uint8_t> cells;
  cells.reserve(w.occupancy.cells().size());
  RETURN_IF_ERROR(Need(occ.contains("runs") && occ.at("runs").is_array(), "occupancy runs"));
  uint8_t value = 0;
  for (const json& run : occ.at("runs")) {
    RETURN_IF_ERROR(Need(run.is_number_integer() && run.get<int64_t>() >= 0 &&
                             cells.size() + run.get<size_t>() <= w.occupancy.cells().size(),
                         "occupancy run"));
    cells.insert(cells.end(), run.get<size_t>(), value);
    value = !value;
  }
  RETURN_IF_ERROR(w.occupancy.SetCells(cells));
  RETURN_IF_ERROR(Need(j.at("baseRegions").is_array(), "baseRegions"));
  for (const json& br : j.at("baseRegions")) {
    object_search::BaseRegion region;
    RETURN_IF_ERROR(ReadVector<2>(br, "min", "baseRegions.", &region.min, true));
    RETURN_IF_ERROR(ReadVector<2>(br, "max", "baseRegions.", &region.max, true));
    w.base_regions.push_back(region);
  }
  if (j.contains("discretePoses") && j.at("discretePoses").is_array()) {
    for (const json& pose : j.at("discretePoses")) {
      object_search::RobotConfig rc;
      RETURN_IF_ERROR(ReadConfig(pose, "discretePoses.", &rc));
      w.discrete_poses.push_back(rc);
    }
  }
  const json& g = j.at("grid");
  RETURN_IF_ERROR(Need(g.is_object() && g.contains("workspaces") && g.at("workspaces").is_array() &&
                           g.contains("logOdds") && g.at("logOdds").is_array(),
                       "grid"));
  std::vector<object_search::Workspace> workspaces;
  for (const json& ws : g.at("workspaces")) {
    object_search::Workspace s;
    s.name = ws.value("name", std::string());
    RETURN_IF_ERROR(ReadVector<2>(ws, "center", "grid.workspaces.", &s.center, true));
    s.yaw = Num(ws, "yaw");
    s.length = Num(ws, "length", 1.0);
    s.width = Num(ws, "width", 1.0);
    s.height = Num(ws, "height", 0.75);
    workspaces.push_back(s);
  }
  w.grid = object_search::GridWorld(workspaces, Num(g, "resolution", 0.02));
  RETURN_IF_ERROR(w.grid.Validate());
  std::vector<float> odds;
  for (const json& v : g.at("logOdds")) {
    RETURN_IF_ERROR(Need(v.is_number(), "grid log-odds"));
    odds.push_back(v.get<float>());
  }
  RETURN_IF_ERROR(w.grid.SetAllLogOdds(odds));
  RETURN_IF_ERROR(Need(j.at("objects").is_array() && !j.at("objects").empty(), "objects"));
  for (const json& o : j.at("objects")) {
    object_search::ObjectKnowledge k;
    RETURN_IF_ERROR(Need(o.is_object() && o.contains("odds") && o.at("odds").is_array() &&
                             o.at("odds").size() == 8 && o.contains("box"),
                         "object"));
    k.key = o.value("id", std::string());
    RETURN_IF_ERROR(box(o.at("box"), &k.box));
    k.moveability = Num(o, "moveability", 1.0);
    for (int i = 0; i < 8; ++i) k.odds[i] = o.at("odds")[i].get<float>();
    k.status = static_cast<int8_t>(Num(o, "status", object_search::kUpdating));
    w.objects.push_back(k);
  }
  RETURN_IF_ERROR(ReadConfig(j.at("robotConfig"), "robotConfig.", &w.robot_config));
  w.steps = static_cast<int>(Num(j, "steps"));
  RETURN_IF_ERROR(w.Validate());
  return w;
}

json BeliefToJson(const World& w) {
  json j;
  j["robot"] = ConfigToJson(w.robot_config);
  j["step"] = w.steps;
  j["grid"]["resolution"] = w.grid.resolution();
  j["grid"]["workspaces"] = json::array();
  const auto mass = w.grid.WorkspaceMass();
  for (size_t i = 0; i < w.grid.workspaces().size(); ++i) {
    const auto& ws = w.grid.workspaces()[i];
    std::vector<float> odds;
    const int n = w.grid.cells_x(static_cast<int>(i)) * w.grid.cells_y(static_cast<int>(i));
    const int first = w.grid.Index(static_cast<int>(i), 0, 0);
    odds.assign(w.grid.all_log_odds().begin() + first, w.grid.all_log_odds().begin() + first + n);
    j["grid"]["workspaces"].push_back({{"name", ws.name},
                                       {"center", Vec(ws.center)},
                                       {"yaw", ws.yaw},
                                       {"length", ws.length},
                                       {"width", ws.width},
                                       {"height", ws.height},
                                       {"cellsX", w.grid.cells_x(static_cast<int>(i))},
                                       {"cellsY", w.grid.cells_y(static_cast<int>(i))},
                                       {"targetMass", mass[i]},
                                       {"logOdds", odds}});
  }
  j["objects"] = json::array();
  for (size_t i = 1; i < w.objects.size(); ++i) {
    const auto& o = w.objects[i];
    double mean = 0.0;
    for (float v : o.odds) mean += v;
    mean /= 8.0;
    j["objects"].push_back({{"id", o.key},
                            {"box", BoxToJson(o.box)},
                            {"faceLogOdds", o.odds},
                            {"status", StatusName(o.status)},
                            {"moveability", o.moveability},
                            {"targetProbability", 1.0 / (1.0 + std::exp(-mean))}});
  }
  return j;
}

json ActionToJson(const HybridAction& a, const World& w) {
  if (a.kind == object_search::kMoveKind) {
    return {{"type", "MOVE"},
            {"configuration", ConfigToJson(object_search::ObjectSearchModel::ConfigOf(a.x))}};
  }
  static const char* kTypes[] = {"DECLARE_TARGET", "DECLARE_OBSTACLE", "REMOVE"};
  const int i = object_search::KindObject(a.kind);
  json out = {{"type", kTypes[object_search::KindOffset(a.kind)]},
              {"objectId", i < static_cast<int>(w.objects.size()) ? w.objects[i].key : ""}};
  // Where the object is, as the robot last saw it: what it needs to act on it.
  if (i > 0 && i < static_cast<int>(w.objects.size()))
    out["objectBox"] = BoxToJson(w.objects[i].box);
  return out;
}

StatusOr<HybridAction> ActionFromJson(const json& j, const std::string& path, const World& w) {
  if (!j.is_object()) return Err(path, "expected an object");
  std::string type;
  RETURN_IF_ERROR(ReadString(j, "type", path + ".", &type, true));
  HybridAction a;
  if (type == "MOVE") {
    RETURN_IF_ERROR(CheckKeys(j, path + ".", {"type", "configuration"}));
    if (!j.contains("configuration")) return Err(path + ".configuration", "missing");
    object_search::RobotConfig c;
    RETURN_IF_ERROR(ReadConfig(j.at("configuration"), path + ".configuration.", &c));
    a.kind = object_search::kMoveKind;
    a.x = object_search::ObjectSearchModel::VecOf(c);
    return a;
  }
  int offset = -1;
  if (type == "DECLARE_TARGET") offset = 0;
  if (type == "DECLARE_OBSTACLE") offset = 1;
  if (type == "REMOVE") offset = 2;
  if (offset < 0) {
    return Err(path + ".type",
               "expected MOVE, DECLARE_TARGET, DECLARE_OBSTACLE or REMOVE, got '" + type + "'");
  }
  RETURN_IF_ERROR(CheckKeys(j, path + ".", {"type", "objectId", "objectBox"}));
  std::string id;
  RETURN_IF_ERROR(ReadString(j, "objectId", path + ".", &id, true));
  const int index = w.FindObject(id);
  if (index < 0) return Err(path + ".objectId", "no object '" + id + "'");
  a.kind = 1 + 3 * index + offset;
  return a;
}

StatusOr<object_search::RealObservation> ObservationFromJson(const json& body, const World& w,
                                                             bool robot_state_required) {
  object_search::RealObservation obs;
  obs.achieved = w.robot_config;
  if (body.contains("robotState")) {
    const json& rs = body.at("robotState");
    if (!rs.is_object()) return Err("robotState", "expected an object");
    RETURN_IF_ERROR(CheckKeys(rs, "robotState.", {"x", "y", "yaw", "lift", "pan", "tilt"}));
    for (const char* key : {"x", "y", "yaw", "lift", "pan", "tilt"}) {
      if (!rs.contains(key)) return Err(std::string("robotState.") + key, "missing");
    }
    RETURN_IF_ERROR(ReadConfig(rs, "robotState.", &obs.achieved));
    const auto& c = obs.achieved;
    if (std::abs(c.x) > 1e4 || std::abs(c.y) > 1e4) return Err("robotState", "too far away");
    if (std::abs(c.yaw) > 1e3 || std::abs(c.pan) > 1e3 || std::abs(c.tilt) > 1e3 ||
        std::abs(c.lift) > 1e3) {
      return Err("robotState", "angle or lift out of range");
    }
  } else if (robot_state_required) {
    return Err("robotState", "missing (required after a MOVE)");
  }
  if (body.contains("detections")) {
    const json& dets = body.at("detections");
    if (!dets.is_array()) return Err("detections", "expected an array");
    if (dets.size() > 63) return Err("detections", "at most 63 detections per observation");
    std::set<std::string> seen;
    for (size_t i = 0; i < dets.size(); ++i) {
      const std::string path = "detections[" + std::to_string(i) + "]";
      const json& d = dets[i];
      if (!d.is_object()) return Err(path, "expected an object");
      RETURN_IF_ERROR(CheckKeys(d, path + ".", {"id", "box", "moveability", "faces"}));
      object_search::ObjectDetection det;
      RETURN_IF_ERROR(ReadString(d, "id", path + ".", &det.key, true));
      if (det.key.empty() || det.key.size() > 128) {
        return Err(path + ".id", "must have 1 to 128 characters");
      }
      if (det.key == w.objects[0].key) return Err(path + ".id", "reserved id");
      if (!seen.insert(det.key).second) return Err(path + ".id", "duplicate id '" + det.key + "'");
      if (!d.contains("box")) return Err(path + ".box", "missing");
      RETURN_IF_ERROR(BoxFromJson(d.at("box"), path + ".box", &det.box));
      RETURN_IF_ERROR(ReadNumber(d, "moveability", path + ".", &det.moveability, false));
      if (!(det.moveability >= 0.0 && det.moveability <= 1.0)) {
        return Err(path + ".moveability", "must be in [0, 1]");
      }
      if (d.contains("faces")) {
        const json& faces = d.at("faces");
        if (!faces.is_array() || faces.size() > 8) {
          return Err(path + ".faces", "expected an array of at most 8 faces");
        }
        for (size_t k = 0; k < faces.size(); ++k) {
          const std::string fp = path + ".faces[" + std::to_string(k) + "]";
          if (!faces[k].is_object()) return Err(fp, "expected an object");
          RETURN_IF_ERROR(CheckKeys(faces[k], fp + ".", {"corner", "score"}));
          double corner = -1, score = -1;
          RETURN_IF_ERROR(ReadNumber(faces[k], "corner", fp + ".", &corner, true));
          RETURN_IF_ERROR(ReadNumber(faces[k], "score", fp + ".", &score, true));
          if (corner != std::floor(corner) || corner < 0 || corner > 7) {
            return Err(fp + ".corner", "must be an integer in [0, 7]");
          }
          if (!(score >= 0.0 && score <= 1.0)) return Err(fp + ".score", "must be in [0, 1]");
          det.faces.push_back({static_cast<int>(corner), score});
        }
      }
      obs.objects.push_back(std::move(det));
    }
  }
  return obs;
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

}  // namespace npfkct::server
