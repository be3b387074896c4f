// The scene generator: every seed gives a valid, solvable scenario file, reproducibly, and the
// scenes vary as documented.
#include "npfkct/sim/scenegen.h"

#include <gtest/gtest.h>

#include <set>

#include "npfkct/sim/scenario.h"

namespace npfkct::sim {
namespace {

TEST(ScenegenTest, ThousandSeedsGiveValidScenarioFiles) {
  std::set<std::string> robots;
  std::set<int> placements, furniture;
  int min_objects = 1000, max_objects = 0;
  for (uint64_t seed = 1; seed <= 1000; ++seed) {
    SceneSummary summary;
    const std::string text = GenerateScenarioJson(seed, &summary);
    const StatusOr<Scenario> s = ParseScenario(text);
    ASSERT_TRUE(s.ok()) << "seed " << seed << ": " << s.status().ToString();
    EXPECT_EQ(s->name, "gen-" + std::to_string(seed));
    EXPECT_EQ(static_cast<int>(s->objects.size()), summary.objects);
    EXPECT_GE(summary.objects, 3) << "seed " << seed;
    EXPECT_LE(summary.objects, 40) << "seed " << seed;
    EXPECT_GE(summary.furniture, 1);
    EXPECT_LE(summary.furniture, 4);
    for (const Furniture& f : s->furniture) {
      EXPECT_GE(f.box.size.z(), 0.4 - 1e-9);
      EXPECT_LE(f.box.size.z(), 1.1 + 1e-9);
    }
    ASSERT_TRUE(InitialWorld(*s).ok()) << "seed " << seed;
    robots.insert(s->robot);
    placements.insert(static_cast<int>(summary.placement));
    furniture.insert(summary.furniture);
    min_objects = std::min(min_objects, summary.objects);
    max_objects = std::max(max_objects, summary.objects);
  }
  EXPECT_EQ(robots, (std::set<std::string>{"fetch", "stretch"}));
  EXPECT_EQ(placements.size(), 3u);  // open, hidden and covered targets all occur
  EXPECT_EQ(furniture, (std::set<int>{1, 2, 3, 4}));
  EXPECT_LE(min_objects, 5);
  EXPECT_GE(max_objects, 30);
}

TEST(ScenegenTest, TheSameSeedGivesTheSameFile) {
  for (uint64_t seed : {uint64_t{1}, uint64_t{77}, kHeldOutSeedBase + 1, kHeldOutSeedBase + 30}) {
    EXPECT_EQ(GenerateScenarioJson(seed), GenerateScenarioJson(seed));
  }
  EXPECT_NE(GenerateScenarioJson(5), GenerateScenarioJson(6));
}

}  // namespace
}  // namespace npfkct::sim
