// The scene generator: every seed gives a valid, solvable scenario file, reproducibly, and the
// scenes vary as documented.
#include "npfkct/sim/scenegen.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
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
    robots.insert(s->robot.name);
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

TEST(ScenegenTest, VersionTwoHasDecoysAnyYawAndAStratifiedHeldOutSet) {
  std::set<std::string> variants;
  int cover_not_largest = 0, covered = 0, immovable = 0, yawed_hidden = 0, with_decoys = 0;
  for (uint64_t i = 1; i <= 60; ++i) {
    const uint64_t seed = kHeldOutV2SeedBase + i;
    SceneSummary summary;
    const std::string text = GenerateScenarioJson(seed, &summary, V2Options(seed));
    const StatusOr<Scenario> s = ParseScenario(text);
    ASSERT_TRUE(s.ok()) << "seed " << seed << ": " << s.status().ToString();
    // 1-20 in the open, 21-40 hidden, 41-60 covered.
    EXPECT_EQ(static_cast<int>(summary.placement), static_cast<int>((i - 1) / 20)) << seed;
    with_decoys += summary.decoys > 0;
    variants.insert(summary.variant);
    double cover_area = 0.0, largest_other = 0.0;
    for (const SceneObject& o : s->objects) {
      const double area = o.box.size.x() * o.box.size.y();
      if (o.name == "cover") {
        cover_area = area;
      } else if (!o.target) {
        largest_other = std::max(largest_other, area);
      }
      immovable += !o.moveable && o.name.rfind("heavy-", 0) == 0;
      if (o.name == "wall-1" && std::abs(std::remainder(o.box.yaw, 1.5707963)) > 0.05) {
        ++yawed_hidden;
      }
    }
    if (summary.placement == TargetPlacement::kCovered) {
      ++covered;
      cover_not_largest += largest_other > cover_area;
    }
  }
  EXPECT_EQ(covered, 20);
  EXPECT_GE(with_decoys, 50);  // a small table may have no room for one
  EXPECT_GE(cover_not_largest, 10);  // the cover is often not the largest box
  EXPECT_GE(immovable, 5);
  EXPECT_GE(yawed_hidden, 10);
  for (const char* v : {"open", "walls", "pocket", "cover", "stacked covers", "walled cover"}) {
    EXPECT_TRUE(variants.count(v)) << v;
  }
}

// FNV-1a, 64 bits.
uint64_t Digest(const std::string& text) {
  uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : text) h = (h ^ c) * 0x100000001b3ULL;
  return h;
}

TEST(ScenegenTest, VersionOneScenesAreUnchangedByVersionTwo) {
  // Version 1 is the first held-out set's law: its files stay byte for byte what they were when
  // its benchmarks were measured (the digest of gen-900012 then).
  const std::string text = GenerateScenarioJson(kHeldOutSeedBase + 12);
  EXPECT_EQ(text, GenerateScenarioJson(kHeldOutSeedBase + 12, nullptr, SceneOptions{}));
  EXPECT_EQ(Digest(text), 0xca6b545715cf0869ULL);
}

}  // namespace
}  // namespace npfkct::sim
