#include "npfkct/sim/simulator.h"

#include <gtest/gtest.h>

#include "npfkct/sim/frame_io.h"

namespace npfkct::sim {
namespace {

using object_search::DeclareObstacleKind;
using object_search::DeclareTargetKind;
using object_search::kMoveKind;
using object_search::ObjectSearchModel;
using object_search::RemoveKind;

Scenario Load(const std::string& name) {
  return LoadScenario(std::string(NPFKCT_SCENARIO_DIR) + "/" + name + ".json").value();
}

// Moves the robot to the front of the table, looking down at it.
void LookAtTable(Simulator* sim, const object_search::World& world, Rng& rng) {
  object_search::RobotConfig c;
  c.x = 0.45;
  c.lift = 0.2;
  c.tilt = 0.45;
  ASSERT_FALSE(
      sim->Execute(HybridAction{kMoveKind, ObjectSearchModel::VecOf(c)}, world, rng).illegal);
}

TEST(SimulatorTest, SeedsReproduceTheWorld) {
  Scenario sc = Load("loose1");
  sc.noise.object_jitter = 0.05;
  Simulator a(sc, 7), b(sc, 7), c(sc, 8);
  for (size_t i = 0; i < a.objects().size(); ++i) {
    EXPECT_EQ(a.objects()[i].box.center, b.objects()[i].box.center);
  }
  EXPECT_NE(a.objects()[0].box.center, c.objects()[0].box.center);
  Rng r1(3), r2(3);
  const auto o1 = a.Observe(r1);
  const auto o2 = b.Observe(r2);
  ASSERT_EQ(o1.objects.size(), o2.objects.size());
  for (size_t i = 0; i < o1.objects.size(); ++i) {
    EXPECT_EQ(o1.objects[i].key, o2.objects[i].key);
    EXPECT_EQ(o1.objects[i].faces.size(), o2.objects[i].faces.size());
  }
}

TEST(SimulatorTest, FrontViewSeesTheLooseObjectsWithDetectionScores) {
  Simulator sim(Load("loose1"), 1);
  Rng rng(2);
  LookAtTable(&sim, sim.InitialWorld().value(), rng);
  const auto obs = sim.Observe(rng);
  EXPECT_GE(obs.objects.size(), 3u);
  double target = 0, others = 0;
  int nt = 0, no = 0;
  for (const auto& d : obs.objects) {
    EXPECT_LE(d.faces.size(), 4u);
    for (const auto& f : d.faces) {
      if (d.key == "target") {
        target += f.score;
        ++nt;
      } else {
        others += f.score;
        ++no;
      }
    }
  }
  ASSERT_GT(nt, 0);
  ASSERT_GT(no, 0);
  EXPECT_GT(target / nt, 0.6);
  EXPECT_LT(others / no, 0.4);
}

TEST(SimulatorTest, CoverHidesTheTargetUntilRemoved) {
  Simulator sim(Load("covered1"), 1);
  auto world = sim.InitialWorld().value();
  Rng rng(3);
  LookAtTable(&sim, world, rng);
  for (const auto& d : sim.Observe(rng).objects) EXPECT_NE(d.key, "target");
  ASSERT_TRUE(object_search::ApplyRealObservation(&world, sim.Observe(rng)).ok());
  const int cover = world.FindObject("cover");
  ASSERT_GT(cover, 0);
  // Removing an undeclared object is illegal; after declaring it an obstacle it works.
  EXPECT_TRUE(sim.Execute(HybridAction{RemoveKind(cover), {}}, world, rng).illegal);
  auto declared = sim.Execute(HybridAction{DeclareObstacleKind(cover), {}}, world, rng);
  EXPECT_EQ(declared.reward, world.params.r_co);
  ASSERT_TRUE(object_search::ApplyDiscreteOutcome(&world, cover, 1, true).ok());
  auto removed = sim.Execute(HybridAction{RemoveKind(cover), {}}, world, rng);
  EXPECT_EQ(removed.reward, 2 * world.params.r_min);
  bool seen = false;
  for (const auto& d : sim.Observe(rng).objects) seen |= d.key == "target";
  EXPECT_TRUE(seen);
  // Declaring the target an obstacle is illegal; as the target it pays R_ct; removing it ends.
  ASSERT_TRUE(object_search::ApplyRealObservation(&world, sim.Observe(rng)).ok());
  const int target = world.FindObject("target");
  ASSERT_GT(target, 0);
  EXPECT_TRUE(sim.Execute(HybridAction{DeclareObstacleKind(target), {}}, world, rng).illegal);
  EXPECT_EQ(sim.Execute(HybridAction{DeclareTargetKind(target), {}}, world, rng).reward,
            world.params.r_ct);
  ASSERT_TRUE(object_search::ApplyDiscreteOutcome(&world, target, 0, true).ok());
  auto done = sim.Execute(HybridAction{RemoveKind(target), {}}, world, rng);
  EXPECT_TRUE(done.terminal);
  EXPECT_EQ(done.reward, world.params.r_max);
}

TEST(SimulatorTest, MovesAreNoisyAndCollisionsIllegal) {
  Simulator sim(Load("loose1"), 1);
  auto world = sim.InitialWorld().value();
  Rng rng(4);
  object_search::RobotConfig c;
  c.x = 0.4;
  c.y = 0.1;
  c.tilt = 0.4;
  auto out = sim.Execute(HybridAction{kMoveKind, ObjectSearchModel::VecOf(c)}, world, rng);
  EXPECT_EQ(out.reward, -1.0);
  EXPECT_NEAR(sim.robot().x, 0.4, 0.1);
  EXPECT_NE(sim.robot().x, 0.4);
  EXPECT_EQ(sim.robot().tilt, 0.4);
  object_search::RobotConfig inside;
  inside.x = 1.6;  // the table
  EXPECT_TRUE(
      sim.Execute(HybridAction{kMoveKind, ObjectSearchModel::VecOf(inside)}, world, rng).illegal);
  EXPECT_NEAR(sim.robot().x, 0.4, 0.1);
  object_search::RobotConfig tilt = c;
  tilt.tilt = 1.2;  // beyond the joint limit
  EXPECT_TRUE(
      sim.Execute(HybridAction{kMoveKind, ObjectSearchModel::VecOf(tilt)}, world, rng).illegal);
}

TEST(SimulatorTest, RenderedFrameMatchesTheGeometry) {
  Simulator sim(Load("loose1"), 1);
  Rng rng(5);
  LookAtTable(&sim, sim.InitialWorld().value(), rng);
  const Frame f = sim.Render(640, 480);
  ASSERT_EQ(f.rgb.size(), 640u * 480u * 3u);
  // The target is visible from the start: some pixels carry its id, at plausible depths.
  int target_pixels = 0, table_pixels = 0;
  for (size_t i = 0; i < f.ids.size(); ++i) {
    if (f.ids[i] == sim.target_index()) {
      ++target_pixels;
      EXPECT_GT(f.depth[i], 0.5f);
      EXPECT_LT(f.depth[i], 3.0f);
    }
    table_pixels += f.ids[i] == 1000;
  }
  EXPECT_GT(target_pixels, 200);
  EXPECT_GT(table_pixels, 5000);
  // Back-projected points of the target lie on its box.
  auto cloud = FrameCloud(f, /*world_frame=*/true);
  EXPECT_GT(cloud->size(), 100000u);
  const auto& box = sim.objects()[sim.target_index()].box;
  int on_box = 0, checked = 0;
  for (size_t i = 0, k = 0; i < f.ids.size(); ++i) {
    if (!(f.depth[i] > 0)) continue;
    if (f.ids[i] == sim.target_index()) {
      ++checked;
      on_box += box.Contains((*cloud)[k].getVector3fMap().cast<double>(), 0.01);
    }
    ++k;
  }
  EXPECT_EQ(on_box, checked);
  cv::Mat bgr = FrameBgr(f);
  EXPECT_EQ(bgr.cols, 640);
  cv::Mat step = RenderStep(sim.InitialWorld().value(), f, "test");
  EXPECT_GT(step.cols, 640);
}

}  // namespace
}  // namespace npfkct::sim
