#include "npfkct/sim/scenario.h"

#include <gtest/gtest.h>

#include <string>

namespace npfkct::sim {
namespace {

std::string Dir() { return NPFKCT_SCENARIO_DIR; }

TEST(ScenarioTest, ShippedScenariosLoad) {
  for (const char* name : {"loose1", "loose2", "hidden1", "covered1", "complex1", "fig16"}) {
    auto s = LoadScenario(Dir() + "/" + name + ".json");
    ASSERT_TRUE(s.ok()) << name << ": " << s.status().ToString();
    auto world = InitialWorld(*s);
    ASSERT_TRUE(world.ok()) << name << ": " << world.status().ToString();
    // Every discrete pose and base region center must be a feasible base pose.
    for (const auto& pose : s->discrete_poses) {
      EXPECT_TRUE(world->BaseFeasible(pose.x, pose.y))
          << name << " pose " << pose.x << "," << pose.y;
    }
  }
  auto loose1 = LoadScenario(Dir() + "/loose1.json");
  EXPECT_EQ(loose1->objects.size(), 4u);
  EXPECT_EQ(LoadScenario(Dir() + "/loose2.json")->Workspaces().size(), 2u);
  EXPECT_EQ(LoadScenario(Dir() + "/hidden1.json")->objects.size(), 7u);
  EXPECT_EQ(LoadScenario(Dir() + "/covered1.json")->objects.size(), 7u);
  EXPECT_EQ(LoadScenario(Dir() + "/complex1.json")->objects.size(), 15u);
  EXPECT_EQ(LoadScenario(Dir() + "/fig16.json")->Workspaces().size(), 4u);
  EXPECT_EQ(LoadScenario(Dir() + "/fig16.json")->objects.size(), 6u);
}

TEST(ScenarioTest, CoveredTargetIsInsideItsCover) {
  auto s = LoadScenario(Dir() + "/covered1.json");
  ASSERT_TRUE(s.ok());
  const SceneObject* target = nullptr;
  const SceneObject* cover = nullptr;
  for (const auto& o : s->objects) {
    if (o.target) target = &o;
    if (o.name == "cover") cover = &o;
  }
  ASSERT_TRUE(target && cover);
  for (const auto& c : target->box.Corners()) EXPECT_TRUE(cover->box.Contains(c, 1e-9));
}

std::string Minimal() {
  return R"({"name": "m", "furniture": [{"name": "t", "center": [1, 0], "size": [1, 1, 0.7],
    "workspace": true}], "baseRegions": [{"min": [-0.5, -0.5], "max": [0.1, 0.5]}],
    "objects": [{"name": "a", "on": "t", "position": [0, 0], "size": [0.1, 0.1, 0.1],
    "target": true}]})";
}

TEST(ScenarioTest, MinimalScenarioDefaults) {
  auto s = ParseScenario(Minimal());
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->robot.name, "fetch");
  EXPECT_NEAR(s->objects[0].box.center.z(), 0.75, 1e-12);
  EXPECT_EQ(s->params.n_odds, 6);
}

TEST(ScenarioTest, MalformedFilesNameTheField) {
  struct Case {
    std::string from, to, field;
  };
  const std::vector<Case> cases = {
      {R"("size": [0.1, 0.1, 0.1])", R"("size": [0.1, 0.1])", "objects[0].size: expected 3"},
      {R"("size": [0.1, 0.1, 0.1])", R"("size": [0.1, -1, 0.1])", "objects[0].size: each"},
      {R"("on": "t")", R"("on": "nowhere")", "objects[0].on"},
      {R"("position": [0, 0])", R"("position": [2, 0])", "objects[0].position: outside"},
      {R"("position": [0, 0])", R"("position": [0, "x"])", "objects[0].position[1]"},
      {R"("target": true)", R"("target": false)", "objects: exactly one object"},
      {R"("target": true)", R"("target": 1)", "objects[0].target: expected true or false"},
      {R"("max": [0.1, 0.5])", R"("max": [-1, 0.5])", "baseRegions[0].max"},
      {R"("workspace": true)", R"("workspace": false)", "objects[0].on: 't' is not a workspace"},
      {R"("name": "m")", R"("name": 3)", "name: expected a string"},
      {R"("name": "a")", R"("name": "t")", "objects[0].name: duplicate"},
      {R"("center": [1, 0])", R"("center": [1, 0], "colour": [1, 2, 3])",
       "furniture[0].colour: unknown field"},
  };
  for (const Case& c : cases) {
    std::string text = Minimal();
    const size_t at = text.find(c.from);
    ASSERT_NE(at, std::string::npos) << c.from;
    text.replace(at, c.from.size(), c.to);
    auto s = ParseScenario(text);
    ASSERT_FALSE(s.ok()) << c.to;
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(s.status().message().find(c.field), std::string::npos)
        << "got: " << s.status().message() << " want: " << c.field;
  }
  EXPECT_NE(ParseScenario("{not json").status().message().find("not valid JSON"),
            std::string::npos);
  EXPECT_NE(ParseScenario(Minimal().replace(1, 0, R"("params": {"nOdds": 9}, )"))
                .status()
                .message()
                .find("params: n_odds"),
            std::string::npos);
  EXPECT_EQ(LoadScenario("/nonexistent.json").status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace npfkct::sim
