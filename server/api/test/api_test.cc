// The API layer: schema validation with field violations as data, the domain checks and limits,
// typed requests, replies and records.
#include "npfkct/api/api.h"

#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <sstream>

#include "json_util.h"
#include "npfkct/api/wire.h"
#include "npfkct/object_search/planner_registry.h"
#include "schema.h"
#include "world_codec.h"

namespace npfkct::api {
namespace {

using nlohmann::json;

json ReadJson(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return json::parse(buffer.str());
}

// The prior-map part of a scenario file: what a robot tells the server.
json WorldOf(const std::string& scenario) {
  const json s = ReadJson(std::string(NPFKCT_SCENARIO_DIR) + "/" + scenario + ".json");
  json world;
  for (const char* key :
       {"robot", "room", "mapResolution", "furniture", "baseRegions", "discretePoses", "start"}) {
    if (s.contains(key)) world[key] = s[key];
  }
  return world;
}

// "prefix" + number, built by appending: GCC 12 warns falsely (-Wrestrict) on "literal" +
// std::string when inlined.
std::string Name(const char* prefix, int i) {
  std::string out(prefix);
  out.append(std::to_string(i));
  return out;
}

json CreateBody(json world = WorldOf("loose1")) {
  return {{"world", world}, {"seed", 3}, {"planner", {{"name", "kct"}, {"particles", 100}}}};
}

// The first field violation of a failed parse.
template <class T>
std::string FieldOf(const StatusOr<T>& r) {
  if (r.ok() || r.status().field_violations().empty())
    return "<none: " + r.status().ToString() + ">";
  return r.status().field_violations()[0].field;
}

const Limits kLimits;

TEST(ParseCreateSession, AcceptsAScenarioWorldAndBuildsIt) {
  auto req = ParseCreateSession(CreateBody().dump(), kLimits);
  ASSERT_TRUE(req.ok()) << req.status().ToString();
  EXPECT_EQ(req->planner.name, "kct");
  EXPECT_EQ(req->planner.particles, 100);
  EXPECT_EQ(*req->seed, 3u);
  // Seeds above 2^63 - 1 as JSON integers too (the schema validator reads them as negative).
  auto big = CreateBody();
  big["seed"] = 18446744073709551615ull;
  auto big_req = ParseCreateSession(big.dump(), kLimits);
  ASSERT_TRUE(big_req.ok()) << big_req.status().ToString();
  EXPECT_EQ(*big_req->seed, 18446744073709551615ull);
  // Integers written with a fractional part of zero are integers (JSON Schema's rule).
  auto floats = json::parse(R"({"planner": {"name": "kct", "particles": 300.0}, "seed": 3e2})");
  floats["world"] = CreateBody()["world"];
  auto float_req = ParseCreateSession(floats.dump(), kLimits);
  ASSERT_TRUE(float_req.ok()) << float_req.status().ToString();
  EXPECT_EQ(float_req->planner.particles, 300);
  EXPECT_EQ(*float_req->seed, 300u);
  floats["planner"]["particles"] = 300.5;
  EXPECT_FALSE(ParseCreateSession(floats.dump(), kLimits).ok());
  auto world = BuildWorld(req->world, kLimits);
  ASSERT_TRUE(world.ok()) << world.status().ToString();
  EXPECT_GT(world->grid.num_cells(), 0);
  EXPECT_EQ(world->objects.size(), 1u);  // the guessed target only
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

TEST(ParseCreateSession, ARobotIsANameADescriptionOrAUrdf) {
  // A description: a camera on a 1.2 m mast with a pan and no tilt or lift.
  json mast = {{"name", "mast-bot"},
               {"footprintRadius", 0.25},
               {"joints",
                {{{"type", "fixed"}, {"xyz", {0.1, 0, 1.2}}},
                 {{"name", "pan"},
                  {"type", "revolute"},
                  {"role", "pan"},
                  {"axis", {0, 0, 1}},
                  {"lower", -0.5},
                  {"upper", 0.5}}}}};
  json world = WorldOf("loose1");
  world["robot"] = mast;
  auto req = ParseCreateSession(CreateBody(world).dump(), kLimits);
  ASSERT_TRUE(req.ok()) << req.status().ToString();
  EXPECT_EQ(req->world.robot.name, "mast-bot");
  EXPECT_FALSE(req->world.robot.has_lift());
  EXPECT_EQ(req->world.robot.pan_max, 0.5);
  EXPECT_EQ(req->world.robot.tilt_max, 0.0);
  auto built = BuildWorld(req->world, kLimits);
  ASSERT_TRUE(built.ok()) << built.status().ToString();
  EXPECT_DOUBLE_EQ(CameraPoseFor(built->robot, {0, 0, 0, 0.3, 0, 0}).position.z(), 1.2);
  // Written back as it was read (a shipped robot as its name).
  EXPECT_EQ(ParseRobot(RobotText(req->world.robot), "robot").value(), req->world.robot);
  EXPECT_EQ(RobotText(object_search::RobotDescription::Stretch()), "\"stretch\"");
  // A scenario file's robot text past its bound, or not JSON, names the field.
  EXPECT_EQ(FieldOf(ParseRobot(std::string(3 << 20, ' '), "robot")), "robot");
  EXPECT_EQ(FieldOf(ParseRobot("{\"joints\": [", "robot")), "robot");
  // A URDF: Fetch's head chain.
  world["robot"] = {
      {"urdf", ReadText(std::string(NPFKCT_SOURCE_DIR) + "/robot/urdf/fetch_head.urdf")},
      {"baseLink", "base_link"},
      {"cameraLink", "head_camera_rgb_optical_frame"},
      {"opticalFrame", true},
      {"liftJoint", "torso_lift_joint"},
      {"panJoint", "head_pan_joint"},
      {"tiltJoint", "head_tilt_joint"}};
  req = ParseCreateSession(CreateBody(world).dump(), kLimits);
  ASSERT_TRUE(req.ok()) << req.status().ToString();
  EXPECT_DOUBLE_EQ(req->world.robot.lift_max, 0.386);
  // Errors name the field.
  struct Case {
    std::function<void(json*)> change;
    std::string field;
  };
  const std::vector<Case> cases = {
      {[](json* r) { (*r)["baseLink"] = "nope"; }, "world.robot.baseLink"},
      {[](json* r) { (*r)["tiltJoint"] = "torso_lift_joint"; }, "world.robot.tiltJoint"},
      {[](json* r) { (*r)["urdf"] = "<robot"; }, "world.robot.urdf"},
  };
  for (const Case& c : cases) {
    json w = world;
    c.change(&w["robot"]);
    EXPECT_EQ(FieldOf(ParseCreateSession(CreateBody(w).dump(), kLimits)), c.field);
  }
  const std::vector<Case> description_cases = {
      {[](json* r) { (*r)["joints"][1]["role"] = "lift"; }, "world.robot.joints[1].role"},
      {[](json* r) {
         (*r)["joints"][1]["axis"] = {0, 0, 0};
       },
       "world.robot.joints[1].axis"},
      {[](json* r) { (*r)["joints"][1]["lower"] = 1.0; }, "world.robot.joints[1].lower"},
      {[](json* r) { (*r)["joints"][0]["role"] = "pan"; }, "world.robot.joints[0].role"},
      // What the schema refuses (a shape none of the three forms has) names the robot.
      {[](json* r) { (*r)["footprintRadius"] = 0; }, "world.robot"},
      {[](json* r) { (*r)["joints"][0]["kind"] = "x"; }, "world.robot"},
  };
  for (const Case& c : description_cases) {
    json w = world;
    w["robot"] = mast;
    c.change(&w["robot"]);
    EXPECT_EQ(FieldOf(ParseCreateSession(CreateBody(w).dump(), kLimits)), c.field);
  }
  json w = world;
  w["robot"] = mast;
  w["robot"]["joints"] = json::array();
  for (int i = 0; i < 17; ++i) w["robot"]["joints"].push_back({{"type", "fixed"}});
  EXPECT_FALSE(ParseCreateSession(CreateBody(w).dump(), kLimits).ok());
}

TEST(WorldSnapshot, KeepsTheRobotAndReadsTheFormBeforeDescriptions) {
  auto req = ParseCreateSession(CreateBody(WorldOf("fig16")).dump(), kLimits);
  ASSERT_TRUE(req.ok()) << req.status().ToString();
  const World world = BuildWorld(req->world, kLimits).value();
  json j = internal::WorldJson(world);
  EXPECT_EQ(internal::WorldFromJson(j, kLimits).value().robot, world.robot);
  // A snapshot written before robot descriptions: a camera offset, a lift that moves it or not.
  for (bool lift : {true, false}) {
    const auto robot = lift ? object_search::RobotDescription::Fetch()
                            : object_search::RobotDescription::Stretch();
    j["robot"] = {{"name", robot.name},
                  {"cameraOffset", lift ? json{0.15, 0, 1.08} : json{0.05, 0, 1.29}},
                  {"liftMovesCamera", lift},
                  {"liftMin", 0.0},
                  {"liftMax", lift ? 0.4 : 0.0},
                  {"panMin", -0.2618},
                  {"panMax", 0.2618},
                  {"tiltMin", -0.5},
                  {"tiltMax", 0.5},
                  {"footprintRadius", robot.footprint_radius},
                  {"reach", robot.reach}};
    const auto read = internal::WorldFromJson(j, kLimits);
    ASSERT_TRUE(read.ok()) << read.status().ToString();
    EXPECT_EQ(read->robot.has_lift(), lift);
    for (const object_search::RobotConfig& c :
         {object_search::RobotConfig{1, 2, 0.3, 0.2, 0.1, -0.4},
          object_search::RobotConfig{-1, 0.5, -2, 0.4, -0.26, 0.5}}) {
      const auto a = CameraPoseFor(read->robot, c), b = CameraPoseFor(robot, c);
      EXPECT_LT((a.position - b.position).norm(), 1e-12);
      EXPECT_LT((a.forward - b.forward).norm(), 1e-12);
    }
  }
  j["robot"] = {{"name", "x"}};
  EXPECT_EQ(internal::WorldFromJson(j, kLimits).status().code(), StatusCode::kDataLoss);
}

TEST(ParseCreateSession, EachKindOfBoundIsDescribedInWordsWithItsValue) {
  // One body per bound the schemas use: minimum, exclusiveMinimum, maximum, exclusiveMaximum,
  // minItems, maxItems and minLength; each is reported at its field with the bound's value.
  auto described = [](json body, const std::string& field) -> std::string {
    auto r = ParseCreateSession(body.dump(), kLimits);
    if (r.ok()) return "<accepted>";
    for (const auto& v : r.status().field_violations()) {
      if (v.field == field) return v.description;
    }
    return "<not at " + field + ": " + r.status().ToString() + ">";
  };
  json body = CreateBody();
  body["planner"]["particles"] = 0;
  EXPECT_EQ(described(body, "planner.particles"), "must be >= 1");
  body["planner"]["particles"] = 20000;
  EXPECT_EQ(described(body, "planner.particles"), "must be <= 10000");
  body = CreateBody();
  body["ttlSeconds"] = 0;
  EXPECT_EQ(described(body, "ttlSeconds"), "must be > 0");
  body = CreateBody();
  body["world"]["params"]["discount"] = 1;
  EXPECT_EQ(described(body, "world.params.discount"), "must be < 1");
  body = CreateBody();
  body["world"]["furniture"] = json::array();
  EXPECT_EQ(described(body, "world.furniture"), "expected at least 1 items");
  body = CreateBody();
  body["world"]["furniture"][0]["name"] = "";
  EXPECT_EQ(described(body, "world.furniture[0].name"), "expected at least 1 characters");
  body = CreateBody();
  body["world"]["furniture"][0]["size"] = {1, 1, 1, 1};
  EXPECT_EQ(described(body, "world.furniture[0].size"), "expected at most 3 items");
}

TEST(ParseCreateSession, SchemaViolationsNameTheFieldAsData) {
  struct Case {
    json body;
    std::string field;
  };
  json world = WorldOf("loose1");
  std::vector<Case> cases;
  {
    json w = world;
    w["furniture"][0]["size"] = json::array({1, 2});
    cases.push_back({{{"world", w}}, "world.furniture[0].size"});
  }
  cases.push_back({{{"world", world}, {"colour", "red"}}, "colour"});
  cases.push_back({json::object(), "world"});
  cases.push_back({{{"world", world}, {"seed", -3}}, "seed"});
  cases.push_back({{{"world", world}, {"seed", "12x"}}, "seed"});
  cases.push_back({{{"world", world}, {"seed", "99999999999999999999"}}, "seed"});
  cases.push_back({{{"world", world}, {"planner", {{"particles", 0}}}}, "planner.particles"});
  cases.push_back({{{"world", world}, {"planner", {{"particles", 1e9}}}}, "planner.particles"});
  cases.push_back({{{"world", world}, {"planner", {{"name", "magic"}}}}, "planner.name"});
  cases.push_back({{{"world", world}, {"planner", {{"name", "oracle"}}}}, "planner.name"});
  cases.push_back(
      {{{"world", world}, {"planner", {{"name", "oracle-cover-unknown"}}}}, "planner.name"});
  cases.push_back(
      {{{"world", world}, {"planner", {{"modelPath", "/etc/passwd"}}}}, "planner.modelPath"});
  cases.push_back({{{"world", world}, {"planner", {{"model", "../filter.pt"}}}}, "planner.model"});
  cases.push_back({{{"world", world}, {"planner", {{"model", "/etc/passwd"}}}}, "planner.model"});
  cases.push_back({{{"world", world}, {"planner", {{"options", {{"numCandidates", 1e9}}}}}},
                   "planner.options.numCandidates"});
  cases.push_back({{{"world", world}, {"planner", {{"options", {{"maxDepth", 1e6}}}}}},
                   "planner.options.maxDepth"});
  // The schema allowed 10,000, which kCT refuses (a schema-valid request that got a 400).
  cases.push_back({{{"world", world}, {"planner", {{"options", {{"treeFeasibilityTries", 1001}}}}}},
                   "planner.options.treeFeasibilityTries"});
  cases.push_back(
      {{{"world", world}, {"planner", {{"options", {{"x", "str"}}}}}}, "planner.options.x"});
  // The bounds above hold for the lowerCamelCase keys; other spellings, which the session would
  // turn into the same snake_case option, are refused.
  for (const char* key : {"num_candidates", "search.Threads", "K", "diameter_samples"}) {
    cases.push_back({{{"world", world}, {"planner", {{"options", {{key, 1e9}}}}}},
                     std::string("planner.options.") + key});
  }
  {
    json w = world;
    w["furniture"][0]["center"][0] = 1e37;  // finite, huge
    cases.push_back({{{"world", w}}, "world.furniture[0].center[0]"});
  }
  {
    json w = world;
    w["baseRegions"][0]["min"] = json::array({-1e308, -1e308});
    cases.push_back({{{"world", w}}, "world.baseRegions[0].min[0]"});
  }
  {
    json w = world;  // a 200 m room at 5 cm: 16e6 cells
    w["room"] = {{"min", {-100, -100}}, {"max", {100, 100}}};
    cases.push_back({{{"world", w}}, "world.mapResolution"});
  }
  {
    json w = world;  // 100 workspaces of 20 x 20 m: 1e8 grid cells of 2 cm
    w["furniture"] = json::array();
    for (int i = 0; i < 100; ++i) {
      w["furniture"].push_back(
          {{"name", Name("t", i)}, {"center", {0, 0}}, {"size", {20, 20, 1}}, {"workspace", true}});
    }
    cases.push_back({{{"world", w}}, "world.furniture[0].size"});
  }
  {
    json w = world;  // ~4,300 pieces: refused by count, before any cell is counted
    for (int i = 0; i < 4300; ++i) {
      w["furniture"].push_back(
          {{"name", Name("p", i)}, {"center", {0, 0}}, {"size", {19, 19, 1}}, {"workspace", true}});
    }
    cases.push_back({{{"world", w}}, "world.furniture"});
  }
  {
    json w = world;
    w["furniture"].push_back(w["furniture"][0]);
    cases.push_back({{{"world", w}}, "world.furniture[1].name"});
  }
  {
    json w = world;
    w["room"] = {{"min", {1, 1}}, {"max", {-1, 3}}};
    cases.push_back({{{"world", w}}, "world.room.max"});
  }
  cases.push_back({{{"world", world}, {"target", {{"photos", {"!!!"}}}}}, "target.photos[0]"});
  cases.push_back({{{"world", world}, {"ttlSeconds", 0}}, "ttlSeconds"});
  for (const Case& c : cases) {
    auto r = ParseCreateSession(c.body.dump(), kLimits);
    ASSERT_FALSE(r.ok()) << c.body.dump().substr(0, 200);
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(FieldOf(r), c.field) << r.status().ToString();
    // The message leads with the same field, for people; the data is the violation.
    EXPECT_EQ(r.status().message().rfind(c.field, 0), 0u) << r.status().message();
  }
}

TEST(ParseCreateSession, ALongUnknownKeyIsNotEchoedBack) {
  json body = CreateBody();
  const std::string key = "\xc3\xa9" + std::string(100'000, 'a');  // a 2-byte character first
  body[key] = 1;
  auto r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  const std::string field = FieldOf(r);
  EXPECT_EQ(field, key.substr(0, 96) + "...");
  EXPECT_LT(r.status().ToString().size(), 400u) << r.status().ToString().size();
  // Cut at a character boundary: 95 bytes when the 96th would split a character.
  body = CreateBody();
  body[std::string(95, 'b') + "\xc3\xa9"] = 1;
  r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(FieldOf(r), std::string(95, 'b') + "...");
}

TEST(ParseCreateSession, DescribesViolationsInWords) {
  json body = CreateBody();
  body["world"]["robot"] = "r2d2";
  auto r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field_violations()[0].field, "world.robot");
  EXPECT_EQ(r.status().field_violations()[0].description,
            R"(expected "fetch", "stretch", a robot description {joints, ...} or a URDF robot )"
            R"({urdf, baseLink, cameraLink, ...})");
  body = CreateBody();
  body["planner"]["particles"] = "many";
  r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field_violations()[0].description, "expected an integer");
  body = CreateBody();
  body["displayName"] = std::string(300, 'x');
  r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field_violations()[0].field, "displayName");
  EXPECT_EQ(r.status().field_violations()[0].description, "expected at most 200 characters");
  // valijson reports a key past `propertyNames` by nothing but its parents: it named "body".
  body = CreateBody();
  body["planner"]["options"][std::string(65, 'k')] = 1;
  r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field_violations()[0].field, "planner.options");
  EXPECT_EQ(r.status().field_violations()[0].description, "keys must be at most 64 characters");
}

// valijson measures a string up to its first NUL: "a\0" followed by 1,000 characters passed
// every maxLength (and a restored session then came back with its strings cut).
TEST(ParseCreateSession, RefusesStringsWithNulWhateverTheirLength) {
  auto body = CreateBody();
  body["displayName"] = std::string("a") + '\0' + std::string(1000, 'x');
  auto r = ParseCreateSession(body.dump(), kLimits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().field_violations()[0].field, "displayName");
  EXPECT_EQ(r.status().field_violations()[0].description, "must not contain U+0000");
  body = CreateBody();
  body["displayName"] = std::string(1, '\0');
  EXPECT_EQ(FieldOf(ParseCreateSession(body.dump(), kLimits)), "displayName");
  body = CreateBody();
  body["world"]["furniture"][0]["name"] = std::string("t") + '\0';
  EXPECT_EQ(FieldOf(ParseCreateSession(body.dump(), kLimits)), "world.furniture[0].name");
  body = CreateBody();
  body[std::string("x") + '\0'] = 1;
  EXPECT_EQ(FieldOf(ParseCreateSession(body.dump(), kLimits)), "(a key)");
}

TEST(ParseBody, RefusesHostileJsonWhileParsing) {
  auto deep = ParsePlan(std::string(100, '[') + std::string(100, ']'), kLimits);
  EXPECT_EQ(FieldOf(deep), "body");
  auto deep_object =
      ParsePlan("{\"a\":" + std::string(1000, '[') + std::string(1000, ']') + "}", kLimits);
  EXPECT_EQ(FieldOf(deep_object), "body");
  std::string many = "{\"budget\": {\"timeMs\": 1}, \"x\": [";
  for (int i = 0; i < 200'000; ++i) many += "0,";
  many += "0]}";
  auto wide = ParsePlan(many, kLimits);
  EXPECT_EQ(FieldOf(wide), "body");
  EXPECT_NE(wide.status().message().find("JSON values"), std::string::npos);
  auto overflow = ParsePlan(R"({"budget": {"timeMs": 1e400}})", kLimits);
  EXPECT_EQ(FieldOf(overflow), "body");
  EXPECT_EQ(FieldOf(ParsePlan("{\"budget\": ", kLimits)), "body");
  EXPECT_EQ(FieldOf(ParsePlan("[1, 2]", kLimits)), "body");
  EXPECT_EQ(FieldOf(ParsePlan("\xff\xfe", kLimits)), "body");
  EXPECT_TRUE(ParsePlan("", kLimits).ok());  // no body: the default budget
}

// ParseBody reads with RapidJSON; what it makes of a text must be what nlohmann's own parser
// makes of it (the same value of the same types, or both refuse it), for edge cases of the
// grammar and for bodies with random bytes changed.
TEST(ParseBody, ReadsWhatNlohmannReads) {
  auto same = [](const std::string& text) {
    auto ours = internal::ParseBody(text, 1'000, 1'000'000, false);
    const json theirs = json::parse(text, nullptr, /*allow_exceptions=*/false);
    const bool they_read = !theirs.is_discarded() && theirs.is_object();
    if (ours.ok() != they_read) {
      ADD_FAILURE() << "accepted by " << (ours.ok() ? "ours" : "nlohmann") << ": " << text;
      return;
    }
    if (ours.ok() && (*ours != theirs || ours->dump() != theirs.dump())) {
      ADD_FAILURE() << text << " read as " << ours->dump() << " and " << theirs.dump();
    }
  };
  using namespace std::string_literals;
  const std::vector<std::string> cases = {
      R"({"a": 0, "b": -0, "c": 1.0, "d": -1.5e-3, "e": 1E5, "f": 18446744073709551615})",
      R"({"g": 18446744073709551616, "h": -9223372036854775808, "i": -9223372036854775809})",
      R"({"j": 1e-400, "k": 0.1, "l": 123456789012345678901234567890, "m": 5e-324})",
      R"({"n": 1e400})",
      R"({"n": -1e309})",
      R"({"o": 01})",
      R"({"o": 1.})",
      R"({"o": .5})",
      R"({"o": +1})",
      R"({"o": NaN})",
      R"({"o": Infinity})",
      R"({"o": 0x10})",
      R"({"s": "\u00e9\u4e2d\ud83d\ude00 \" \\ \/ \b \f \n \r \t"})",
      R"({"s": "\ud800"})",
      R"({"s": "\udc00\ud800"})",
      R"({"s": "\u0000"})",
      "{\"s\": \"\x01\"}",
      "{\"s\": \"\xc3\xa9\xe4\xb8\xad\xf0\x9f\x98\x80\"}",
      "{\"s\": \"\xc0\xaf\"}",
      "{\"s\": \"\xe0\x80\xaf\"}",
      "{\"s\": \"\xed\xa0\x80\"}",
      "{\"s\": \"\xf4\x90\x80\x80\"}",
      "{\"s\": \"\xf8\x88\x80\x80\x80\"}",
      "{\"s\": \"\xc3\"}",
      "{\"s\": \"\xff\"}",
      "{\"\xc3\xa9\": 1}",
      "{\"\xc3\": 1}",
      "\0{}"s,
      "{\"a\":1\0}"s,
      R"({"a": [1, 2, {"b": null, "c": [true, false, []]}], "a": "again"})",
      " \t\r\n{}\n ",
      R"({"a": 1,})",
      R"({"a": [1,]})",
      R"({'a': 1})",
      R"({"a": 1} {})",
      R"({"a": 1}])",
      R"({"a" 1})",
      R"({"a": tru})",
      R"({"a": "unterminated)",
      "// comment\n{}",
      "\xef\xbb\xbf{}",
      R"({"a": "\x"})",
      R"({"a": "\u12"})",
      R"({"a": "\u12G4"})"};
  for (const std::string& text : cases) same(text);
  // Where it is stricter: nlohmann's lexer takes a NUL byte for the end of the text, so that it
  // read a body with anything after a NUL that follows the object.
  EXPECT_EQ(FieldOf(internal::ParseBody("{} \0"s, 10, 100, false)), "body");
  EXPECT_EQ(FieldOf(internal::ParseBody("{}\0{\"a\": 1}"s, 10, 100, false)), "body");
  // Bodies with bytes changed: each byte of a request by turns, to characters that matter to
  // the grammar and to bytes that are not UTF-8.
  const std::string body =
      R"({"robotState": {"x": -1.25, "y": 3e-2, "yaw": 0}, "ids": ["a\u00e9", "b"], )"
      R"("n": [1, 22, 333], "ok": true, "none": null})";
  const std::string replacements = "{}[]\",:.-+eE0 \\u\0\x80\xc3\xed\xff"s;
  std::mt19937 rng(5);
  for (int trial = 0; trial < 3'000; ++trial) {
    std::string text = body;
    const int changes = 1 + static_cast<int>(rng() % 3);
    for (int c = 0; c < changes; ++c) {
      text[rng() % text.size()] = replacements[rng() % replacements.size()];
    }
    if (text.find('\0') == std::string::npos) same(text);
  }
}

TEST(ParsePlan, BudgetsWithinTheServersMaximum) {
  auto ok = ParsePlan(R"({"budget": {"timeMs": 50, "cpuMs": 20, "simulations": 100}})", kLimits);
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  EXPECT_EQ(*ok->cpu_ms, 20);
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"timeMs": -5}})", kLimits)), "budget.timeMs");
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"timeMs": 1e9}})", kLimits)), "budget.timeMs");
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"timeMs": 70000}})", kLimits)), "budget.timeMs");
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"cpuMs": 70000}})", kLimits)), "budget.cpuMs");
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"simulations": 1.5}})", kLimits)),
            "budget.simulations");
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"timeMs": 0}})", kLimits)), "budget");
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"wallMs": 5}})", kLimits)), "budget.wallMs");
  Limits strict;
  strict.max_plan_ms = 100;
  EXPECT_EQ(FieldOf(ParsePlan(R"({"budget": {"timeMs": 500}})", strict)), "budget.timeMs");
}

TEST(ParseObserve, DetectionsOrRawDataWithinLimits) {
  const json detection = {{"id", "box-1"},
                          {"box", {{"center", {1.4, 0.1, 0.82}}, {"size", {0.12, 0.12, 0.14}}}},
                          {"faces", {{{"corner", 0}, {"score", 0.2}}}}};
  json body = {
      {"actionId", "a1-000000"},
      {"robotState", {{"x", 0}, {"y", 0}, {"yaw", 0}, {"lift", 0}, {"pan", 0}, {"tilt", 0}}},
      {"detections", {detection}}};
  auto ok = ParseObserve(body.dump(), kLimits);
  ASSERT_TRUE(ok.ok()) << ok.status().ToString();
  ASSERT_EQ(ok->detections.size(), 1u);
  EXPECT_EQ(ok->detections[0].faces[0].corner, 0);

  json both = body;
  both["pointCloud"] = {{"data", "AAAA"}};
  auto r = ParseObserve(both.dump(), kLimits);
  EXPECT_EQ(FieldOf(r), "detections");
  EXPECT_NE(r.status().message().find("not both"), std::string::npos);

  json image_only = {{"actionId", "a1"}, {"image", {{"data", "AAAA"}}}};
  EXPECT_EQ(FieldOf(ParseObserve(image_only.dump(), kLimits)), "pointCloud");

  json bad_corner = body;
  bad_corner["detections"][0]["faces"][0]["corner"] = 11;
  EXPECT_EQ(FieldOf(ParseObserve(bad_corner.dump(), kLimits)), "detections[0].faces[0].corner");

  json duplicate = body;
  duplicate["detections"].push_back(detection);
  EXPECT_EQ(FieldOf(ParseObserve(duplicate.dump(), kLimits)), "detections[1].id");

  json far = body;
  far["robotState"]["x"] = 1e300;
  EXPECT_EQ(FieldOf(ParseObserve(far.dump(), kLimits)), "robotState.x");

  // Three camera-frame points at depth 3e38: refused before perception.
  perception::Cloud cloud;
  for (int i = 0; i < 3; ++i) {
    pcl::PointXYZRGB p;
    p.x = 0.0f;
    p.y = 0.0f;
    p.z = 3e38f;
    cloud.push_back(p);
  }
  json raw = {{"actionId", "a1"},
              {"pointCloud", {{"fields", "xyzrgb"}, {"data", Base64Encode(EncodeCloud(cloud))}}}};
  EXPECT_EQ(FieldOf(ParseObserve(raw.dump(), kLimits)), "pointCloud.data");
  json long_key = raw;
  long_key["semanticScores"] = {{std::string(129, 's'), 0.5}};
  EXPECT_EQ(FieldOf(ParseObserve(long_key.dump(), kLimits)), "semanticScores");

  json big_camera = raw;
  big_camera["camera"] = {{"width", 4096}, {"height", 4096}};
  cloud[0].z = cloud[1].z = cloud[2].z = 1.0f;
  big_camera["pointCloud"]["data"] = Base64Encode(EncodeCloud(cloud));
  EXPECT_EQ(FieldOf(ParseObserve(big_camera.dump(), kLimits)), "camera");

  // image.encoding must name the data's format (it was not read: JPEG bytes said to be PNG
  // passed).
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", cv::Mat(16, 16, CV_8UC3, cv::Scalar(1, 2, 3)), jpeg);
  json with_image = raw;
  with_image["pointCloud"]["data"] = Base64Encode(EncodeCloud(cloud));
  with_image["camera"] = {{"width", 16}, {"height", 16}, {"fx", 16},
                          {"fy", 16},    {"cx", 8},      {"cy", 8}};
  with_image["image"] = {{"encoding", "jpeg"},
                         {"data", Base64Encode(std::string(jpeg.begin(), jpeg.end()))}};
  auto jpeg_ok = ParseObserve(with_image.dump(), kLimits);
  ASSERT_TRUE(jpeg_ok.ok()) << jpeg_ok.status().ToString();
  with_image["image"].erase("encoding");
  EXPECT_TRUE(ParseObserve(with_image.dump(), kLimits).ok());
  with_image["image"]["encoding"] = "png";
  auto said_png = ParseObserve(with_image.dump(), kLimits);
  EXPECT_EQ(FieldOf(said_png), "image.encoding");
  EXPECT_NE(said_png.status().message().find("says png, the data is a jpeg image"),
            std::string::npos)
      << said_png.status().ToString();
}

TEST(Schemas, AgreeWithTheLimitsAndThePlannerRegistry) {
  const json* common = internal::SchemaDocument("common.schema.json");
  ASSERT_NE(common, nullptr);
  const json& defs = common->at("$defs");
  const Limits& hard = HardLimits();
  EXPECT_EQ(defs["Coordinate"]["maximum"].get<double>(), hard.max_coordinate);
  EXPECT_EQ(defs["World"]["properties"]["furniture"]["maxItems"], hard.max_furniture);
  EXPECT_EQ(defs["World"]["properties"]["baseRegions"]["maxItems"], hard.max_base_regions);
  EXPECT_EQ(defs["World"]["properties"]["discretePoses"]["maxItems"], hard.max_discrete_poses);
  EXPECT_EQ(defs["PlannerSpec"]["properties"]["particles"]["maximum"], hard.max_particles);
  EXPECT_EQ(defs["PlannerSpec"]["properties"]["options"]["maxProperties"],
            hard.max_planner_options);
  EXPECT_EQ(defs["Budget"]["properties"]["timeMs"]["maximum"].get<double>(), hard.max_plan_ms);
  EXPECT_EQ(defs["Budget"]["properties"]["simulations"]["maximum"], hard.max_plan_simulations);
  const json* observe = internal::SchemaDocument("observe_request.schema.json");
  EXPECT_EQ(observe->at("properties")["detections"]["maxItems"], hard.max_objects);
  EXPECT_EQ(observe->at("properties")["camera"]["properties"]["width"]["maximum"],
            hard.max_image_side);
  const json* create = internal::SchemaDocument("create_session_request.schema.json");
  EXPECT_EQ(create->at("properties")["target"]["properties"]["photos"]["maxItems"],
            hard.max_photos);
  // Every planner the server may run, and only those.
  const std::vector<std::string> servable =
      object_search::PlannerRegistry::BuiltIn().Names(/*servable_only=*/true);
  EXPECT_EQ(defs["PlannerSpec"]["properties"]["name"]["enum"].get<std::vector<std::string>>(),
            servable);
  // Every bounded option of the schema is bounded under its bare leaf name too.
  for (const auto& [key, bound] :
       defs["PlannerSpec"]["properties"]["options"]["properties"].items()) {
    const double over = bound["maximum"].get<double>() + 1;
    const size_t dot = key.find_last_of('.');
    const std::string leaf = dot == std::string::npos ? key : key.substr(dot + 1);
    for (const std::string& k : {key, leaf}) {
      json body = CreateBody();
      body["planner"]["options"] = {{k, over}};
      auto r = ParseCreateSession(body.dump(), kLimits);
      EXPECT_EQ(FieldOf(r), "planner.options." + k) << r.status().ToString();
    }
  }
}

TEST(BuildWorld, MarksTheSameOccupancyAsAddBox) {
  std::mt19937 gen(5);
  std::uniform_real_distribution<double> u(-4.0, 4.0), s(0.1, 3.0), yaw(-3.2, 3.2);
  WorldSpec spec;
  spec.room_min = {-5, -4};
  spec.room_max = {12, 5};  // the furniture stays within x < 7; the robot starts at x = 10
  spec.map_resolution = 0.05;
  spec.start.x = 10.0;
  object_search::OccupancyMap reference(spec.room_min, spec.room_max, spec.map_resolution);
  for (int i = 0; i < 40; ++i) {
    WorldSpec::Furniture f;
    f.name = Name("f", i);
    f.box.size = {s(gen), s(gen), 0.8};
    f.box.center = {u(gen), u(gen), 0.4};
    f.box.yaw = yaw(gen);
    f.workspace = i == 0;
    spec.furniture.push_back(f);
    reference.AddBox(f.box);
  }
  spec.base_regions.push_back({{-1, -1}, {1, 1}});
  auto world = BuildWorld(spec, kLimits);
  ASSERT_TRUE(world.ok()) << world.status().ToString();
  EXPECT_EQ(world->occupancy.cells(), reference.cells());
  // A start on the furniture is refused, naming it.
  spec.start.x = spec.furniture[0].box.center.x();
  spec.start.y = spec.furniture[0].box.center.y();
  EXPECT_EQ(FieldOf(BuildWorld(spec, kLimits)), "world.start");
}

TEST(Records, RoundTripAndRefuseCorruptOrOversizedSnapshots) {
  auto req = ParseCreateSession(CreateBody().dump(), kLimits);
  ASSERT_TRUE(req.ok());
  SessionRecord r;
  r.id = std::string(32, 'a');
  r.planner = req->planner;
  r.planner.options = {{"k", 4}, {"search.reuse_tree", 1}};
  r.planner.option_is_bool = {false, true};
  r.seed = 18446744073709551615ull;
  r.state = SessionState::kActionPending;
  r.pending_action_id = "a1-abcdef";
  r.pending_action.kind = 0;
  r.pending_action.x = ActionVec::Zero(6);
  r.world = BuildWorld(req->world, kLimits).value();
  r.world.grid.set_log_odds(7, -1.5f);
  r.perception = std::make_pair(3, std::vector<perception::TrackState>{{"obj-1", 0, {1, 2, 3}}});
  // Strings at the API's limits, in characters of several bytes each, come back whole (ids were
  // cut at 256 bytes: a second object appeared when the restored session saw the first again).
  auto repeat = [](const std::string& c, int n) {
    std::string out;
    for (int i = 0; i < n; ++i) out += c;
    return out;
  };
  r.display_name = repeat("\u20ac", kLimits.max_display_name);
  r.target.description = repeat("\u20ac", kLimits.max_description);
  object_search::ObjectKnowledge known;
  known.key = repeat("\U0001F600", kLimits.max_id_length);
  known.box.center = {1.0, 0.0, 0.8};
  known.box.size = {0.1, 0.1, 0.1};
  r.world.objects.push_back(known);
  r.perception->second.push_back({repeat("\u00e9", kLimits.max_id_length), 1, {4, 5, 6}});
  StepRecord step;
  step.step = 1;
  step.action_id = "a1-abcdef";
  step.action.type = ActionView::Type::kRemove;
  step.action.object_id = known.key;
  r.history.push_back(step);
  const std::string bytes = EncodeRecord(r);
  auto back = DecodeRecord(bytes, kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->seed, r.seed);
  EXPECT_EQ(back->planner.options, r.planner.options);
  EXPECT_EQ(back->world.grid.all_log_odds(), r.world.grid.all_log_odds());
  EXPECT_EQ(back->world.occupancy.cells(), r.world.occupancy.cells());
  EXPECT_EQ(back->perception->second[0].points, (std::vector<float>{1, 2, 3}));
  EXPECT_EQ(back->world.objects.back().key, known.key);
  EXPECT_EQ(back->display_name, r.display_name);
  EXPECT_EQ(EncodeRecord(*back), bytes);
  // Past the limits a hostile snapshot is cut at a character boundary.
  json long_name = json::parse(bytes);
  long_name["displayName"] = repeat("\u20ac", kLimits.max_display_name + 5);
  EXPECT_EQ(DecodeRecord(long_name.dump(), kLimits)->display_name, r.display_name);

  EXPECT_EQ(DecodeRecord(bytes.substr(0, bytes.size() / 2), kLimits).status().code(),
            StatusCode::kDataLoss);
  // A snapshot claiming a 1e6 x 1e6 m map or an enormous grid is refused before allocation.
  json j = json::parse(bytes);
  j["world"]["occupancy"]["max"] = {1e4, 1e4};
  j["world"]["occupancy"]["min"] = {-1e4, -1e4};
  EXPECT_EQ(DecodeRecord(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  j = json::parse(bytes);
  j["world"]["grid"]["resolution"] = 0.005;
  EXPECT_EQ(DecodeRecord(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  j = json::parse(bytes);
  j["world"]["grid"]["workspaces"][0]["length"] = 100;
  j["world"]["grid"]["workspaces"][0]["width"] = 100;
  EXPECT_EQ(DecodeRecord(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  j = json::parse(bytes);
  j["pendingAction"]["kind"] = 9999;
  EXPECT_EQ(DecodeRecord(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  j = json::parse(bytes);
  j["id"] = "../../etc/passwd";
  EXPECT_EQ(DecodeRecord(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  // A record edited on disk restores no planner option a request could not set (found by an
  // outside attack: search.numParticles 5e7 and search.maxDepth 1e6 were restored), nor a time
  // to live past the API's maximum.
  for (const auto& [key, value] : std::vector<std::pair<std::string, double>>{
           {"search.numParticles", 5e7}, {"search.maxDepth", 1e6}, {"num_candidates", 8}}) {
    j = json::parse(bytes);
    j["planner"]["options"] = json::array({{{"key", key}, {"value", value}, {"bool", false}}});
    const auto decoded = DecodeRecord(j.dump(), kLimits);
    EXPECT_EQ(decoded.status().code(), StatusCode::kDataLoss) << key;
    EXPECT_NE(decoded.status().message().find("planner.options." + key), std::string::npos)
        << decoded.status().message();
  }
  j = json::parse(bytes);
  j["ttlSeconds"] = 1e15;
  EXPECT_EQ(DecodeRecord(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  // A record whose photos are kept apart is of version 3, which a server knowing version 2 only
  // refuses (it read such a record as a session without photos, and saved it so); a reader that
  // takes no digest refuses it too, and a version-2 record never names photos kept apart.
  const std::string apart = EncodeRecord(r, "0badc0de-123");
  EXPECT_EQ(json::parse(apart)["version"], 3);
  EXPECT_EQ(json::parse(bytes)["version"], 2);
  std::string digest;
  auto named = DecodeRecord(apart, kLimits, &digest);
  ASSERT_TRUE(named.ok()) << named.status().ToString();
  EXPECT_EQ(digest, "0badc0de-123");
  EXPECT_EQ(DecodeRecord(apart, kLimits).status().code(), StatusCode::kDataLoss);
  j = json::parse(apart);
  j["version"] = 2;
  ASSERT_TRUE(DecodeRecord(j.dump(), kLimits, &digest).ok());
  EXPECT_TRUE(digest.empty());
}

TEST(Records, SessionSummariesRenderAsTheViewTheyWereMadeOf) {
  SessionView v;
  v.id = std::string(32, 'b');
  v.display_name = "kitchen \u20ac";
  v.state = SessionState::kActionPending;
  v.create_time = FromUnixMillis(1'764'000'000'123);
  v.update_time = FromUnixMillis(1'764'000'100'456);
  v.ttl_seconds = 1800;
  v.planner.name = "npfkct";
  v.planner.particles = 300;
  v.planner.model = "filter.pt";
  v.planner.options = {{"k", 4}, {"search.reuse_tree", 1}, {"w1", 1.5}};
  v.planner.option_is_bool = {false, true, false};
  v.seed = 18446744073709551615ull;
  v.target_description = "blue box";
  v.photo_count = 2;
  v.perception_tracks = 3;
  v.step = 7;
  v.robot.x = 1.25;
  v.robot.tilt = -0.3;
  v.object_count = 5;
  ActionView a;
  a.type = ActionView::Type::kDeclareObstacle;
  a.object_id = "box-3";
  v.pending = std::make_pair("a7-abcdef", a);
  v.total_simulations = 123456;
  v.planning_seconds_used = 12.5;
  const std::string summary = EncodeSessionSummary(v);
  EXPECT_LT(summary.size(), 1000u);
  auto back = DecodeSessionSummary(summary, kLimits);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(RenderSession(*back), RenderSession(v));
  v.pending.reset();
  v.perception_tracks.reset();
  EXPECT_EQ(RenderSession(DecodeSessionSummary(EncodeSessionSummary(v), kLimits).value()),
            RenderSession(v));
  // Corrupt or oversized summaries are DATA_LOSS (the store then reads the record).
  EXPECT_EQ(DecodeSessionSummary("{", kLimits).status().code(), StatusCode::kDataLoss);
  EXPECT_EQ(DecodeSessionSummary(std::string(kMaxSummaryBytes + 1, ' '), kLimits).status().code(),
            StatusCode::kDataLoss);
  json j = json::parse(summary);
  j["id"] = "../x";
  EXPECT_EQ(DecodeSessionSummary(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
  j = json::parse(summary);
  j["planner"]["particles"] = 1'000'000'000;
  EXPECT_EQ(DecodeSessionSummary(j.dump(), kLimits).status().code(), StatusCode::kDataLoss);
}

TEST(Replies, ErrorsCarryFieldViolationsAndRetryInfo) {
  Status s = InvalidFieldError("budget.timeMs", "must be <= 60000");
  s.WithFieldViolation("budget.cpuMs", "must be <= 60000");
  const json e = json::parse(RenderError(s));
  EXPECT_EQ(e["error"]["code"], 400);
  EXPECT_EQ(e["error"]["status"], "INVALID_ARGUMENT");
  EXPECT_EQ(e["error"]["details"][0]["fieldViolations"].size(), 2u);
  EXPECT_EQ(e["error"]["details"][0]["fieldViolations"][1]["field"], "budget.cpuMs");
  const json busy = json::parse(RenderError(ResourceExhaustedError("planning queue full"), 0, 2));
  EXPECT_EQ(busy["error"]["code"], 429);
  EXPECT_EQ(busy["error"]["details"][0]["retryDelay"], "2s");
  const json moved = json::parse(RenderError(InvalidArgumentError("x"), 415));
  EXPECT_EQ(moved["error"]["code"], 415);
}

TEST(Replies, BeliefPngStaysWithinItsPixelBudget) {
  WorldSpec spec;
  spec.room_min = {-500, -500};
  spec.room_max = {500, 500};
  spec.map_resolution = 1.0;
  spec.furniture.push_back({"t", object_search::Box{{0, 0, 0.4}, 0, {1, 1, 0.8}}, true});
  spec.base_regions.push_back({{-2, -2}, {2, 2}});
  spec.start.x = 3;
  auto world = BuildWorld(spec, kLimits);
  ASSERT_TRUE(world.ok()) << world.status().ToString();
  auto png = RenderBeliefPng(*world, nullptr, 1'000'000);
  ASSERT_TRUE(png.ok());
  auto info = ProbeImage(*png, "png").value();
  EXPECT_LE(info.width * info.height, 1'000'000);
}

}  // namespace
}  // namespace npfkct::api
