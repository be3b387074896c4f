// Hand-computed checks of the object-search model: frustum, occlusion, face-grid updates,
// rewards, illegal actions and the grid-world update.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <queue>
#include <set>
#include <tuple>

#include "npfkct/object_search/discrete.h"
#include "npfkct/object_search/model.h"
#include "npfkct/object_search/planner_registry.h"
#include "npfkct/object_search/policies.h"
#include "npfkct/object_search/proposals.h"
#include "npfkct/solver/kct.h"
#include "npfkct/solver/pomcp.h"

namespace npfkct::object_search {
namespace {

// A built-in planner (the registry's Make as the server and the bench call it).
StatusOr<std::unique_ptr<SearchPlanner>> MakeSearchPlanner(
    const std::string& name, const ObjectSearchModel& model, OptionList options,
    std::shared_ptr<CandidateSampler<State>> sampler = nullptr) {
  return PlannerRegistry::BuiltIn().Make(name, {&model, std::move(options), std::move(sampler)});
}

// A 1 m x 1 m table top at height 0.75 centered at (1.2, 0); the robot stands left of it.
World TestWorld() {
  SearchParams params;
  params.eta_std = 0.0;
  params.c_o = 0.5;
  Box table;
  table.center = Vec3(1.2, 0.0, 0.375);
  table.size = Vec3(1.0, 1.0, 0.75);
  OccupancyMap map(Vec2(-2, -2), Vec2(3, 2), 0.05);
  map.AddBox(table);
  Workspace top;
  top.name = "table";
  top.center = Vec2(1.2, 0.0);
  top.length = 1.0;
  top.width = 1.0;
  top.height = 0.75;
  BaseRegion region;
  region.min = Vec2(-0.5, -0.6);
  region.max = Vec2(0.4, 0.6);
  return World::Make(RobotDescription::Fetch(), params, {table}, map, {region},
                     GridWorld({top}, 0.02), RobotConfig{});
}

ObjectKnowledge Object(const std::string& key, Vec3 center, Vec3 size, float odds) {
  ObjectKnowledge o;
  o.key = key;
  o.box.center = center;
  o.box.size = size;
  o.odds.fill(odds);
  return o;
}

TEST(GeometryTest, FrustumMatchesHandComputedLimits) {
  const RobotDescription fetch = RobotDescription::Fetch();
  const CameraModel cam;
  const CameraPose pose = CameraPoseFor(fetch, RobotConfig{});
  EXPECT_TRUE(pose.position.isApprox(Vec3(0.15, 0.0, 1.08)));
  const double z = 1.08;
  EXPECT_TRUE(InFrustum(cam, pose, Vec3(1.0, 0.0, z)));
  EXPECT_FALSE(InFrustum(cam, pose, Vec3(0.6, 0.0, z)));  // depth 0.45 < near 0.5
  EXPECT_FALSE(InFrustum(cam, pose, Vec3(1.9, 0.0, z)));  // depth 1.75 > far 1.7
  // At depth 1: |lateral| <= tan 30 deg = 0.577, |vertical| <= 0.8 tan 30 deg = 0.462.
  EXPECT_TRUE(InFrustum(cam, pose, Vec3(1.15, 0.57, z)));
  EXPECT_FALSE(InFrustum(cam, pose, Vec3(1.15, 0.59, z)));
  EXPECT_TRUE(InFrustum(cam, pose, Vec3(1.15, 0.0, z - 0.45)));
  EXPECT_FALSE(InFrustum(cam, pose, Vec3(1.15, 0.0, z - 0.47)));
  // Positive tilt looks down: the optical axis pitches by the tilt angle.
  RobotConfig down;
  down.tilt = 0.5;
  const CameraPose tilted = CameraPoseFor(fetch, down);
  EXPECT_TRUE(tilted.forward.isApprox(Vec3(std::cos(0.5), 0.0, -std::sin(0.5))));
  // Yaw and pan add up; the lift raises Fetch's camera but not Stretch's.
  RobotConfig turned;
  turned.yaw = 0.3;
  turned.pan = 0.2;
  turned.lift = 0.4;
  const CameraPose t = CameraPoseFor(fetch, turned);
  EXPECT_NEAR(std::atan2(t.forward.y(), t.forward.x()), 0.5, 1e-12);
  EXPECT_NEAR(t.position.z(), 1.48, 1e-12);
  EXPECT_NEAR(CameraPoseFor(RobotDescription::Stretch(), turned).position.z(), 1.29, 1e-12);
}

TEST(GeometryTest, BoxesBlockSegmentsThatCrossThem) {
  Box occluder;
  occluder.center = Vec3(0.8, 0.0, 0.9);
  occluder.size = Vec3(0.1, 0.3, 0.3);
  const Vec3 camera(0.15, 0.0, 1.08);
  // At x = 0.8 the segment to (1.2, 0, 0.8) is at z = 1.08 - 0.28 * 0.65 / 1.05 = 0.907.
  EXPECT_TRUE(occluder.BlocksSegment(camera, Vec3(1.2, 0.0, 0.8)));
  EXPECT_FALSE(occluder.BlocksSegment(camera, Vec3(1.2, 0.4, 0.8)));  // passes beside it
  EXPECT_FALSE(occluder.BlocksSegment(camera, Vec3(0.6, 0.0, 0.9)));  // ends before it
  // Rotated by 45 degrees, the box's long side (0.3 along its y) runs along (-1, 1) / sqrt(2):
  // the offset (-0.1, 0.1) is at local (0, 0.141), inside; unrotated it is outside.
  Box rotated = occluder;
  rotated.yaw = std::acos(-1.0) / 4;
  EXPECT_TRUE(rotated.Contains(Vec3(0.8 - 0.1, 0.1, 0.9)));
  EXPECT_FALSE(occluder.Contains(Vec3(0.8 - 0.1, 0.1, 0.9)));
  const auto corners = occluder.Corners();
  EXPECT_TRUE(corners[7].isApprox(Vec3(0.85, 0.15, 1.05)));
  EXPECT_TRUE(corners[0].isApprox(Vec3(0.75, -0.15, 0.75)));
}

// The occlusion checks test many sight lines against precomputed BoxFrames and skip the exact
// slab test when a segment passes outside the bounding sphere; both must give what the exact
// test alone gives, including segments that graze a box's corners and edges.
TEST(GeometryTest, BoxFramesAnswerAsTheExactSlabTest) {
  Rng rng(7);
  int blocked = 0, grazing = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Box box;
    box.center = Vec3(rng.Uniform(-1, 1), rng.Uniform(-1, 1), rng.Uniform(0, 1));
    box.yaw = rng.Uniform(-4, 4);
    box.size = Vec3(rng.Uniform(0.01, 1), rng.Uniform(0.01, 1), rng.Uniform(0.01, 1));
    const BoxFrame frame(box);
    const auto corners = box.Corners();
    for (int k = 0; k < 8; ++k) EXPECT_EQ(frame.Corners()[k], corners[k]);
    const Vec3 a(rng.Uniform(-3, 3), rng.Uniform(-3, 3), rng.Uniform(-1, 2));
    // Half the segments end at a corner pushed out by a hair: the closest calls.
    Vec3 b(rng.Uniform(-3, 3), rng.Uniform(-3, 3), rng.Uniform(-1, 2));
    if (trial % 2 == 0) {
      const Vec3& corner = corners[trial % 8];
      b = corner + (corner - box.center) * rng.Uniform(1e-9, 1e-3) + (corner - a) * 0.5;
      ++grazing;
    }
    const Vec3 dir = b - a;
    const double length = dir.norm();
    const bool exact = box.Intersect(a, dir / length, 1e-6, length - 1e-6) >= 0.0;
    ASSERT_EQ(frame.BlocksSegment(a, b), exact) << "trial " << trial;
    ASSERT_EQ(box.BlocksSegment(a, b), exact) << "trial " << trial;
    EXPECT_EQ(frame.Contains(b), box.Contains(b));
    blocked += exact;
  }
  // Both outcomes occur often enough for the comparison to mean something.
  EXPECT_GT(blocked, 2000);
  EXPECT_LT(blocked, 18000);
  EXPECT_EQ(grazing, 10000);
}

TEST(ObjectSearchModelTest, ObservationUpdatesTheFourNearestGridsByTheMeanOdds) {
  World w = TestWorld();
  // Object 1: a box on the table believed to be the target; object 2: believed an obstacle;
  // object 3: undecided.
  w.objects.push_back(Object("a", Vec3(1.0, 0.2, 0.8), Vec3(0.1, 0.1, 0.1), 0.3f));
  w.objects.push_back(Object("b", Vec3(1.0, -0.2, 0.8), Vec3(0.1, 0.1, 0.1), -0.3f));
  w.objects.push_back(Object("c", Vec3(1.0, 0.0, 0.8), Vec3(0.1, 0.1, 0.1), 0.0f));
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(1);
  State s = model.SampleInitialState(rng);
  s.target = Vec3(1.6, 0.4, 0.8);  // behind the view's far corner? (depth 1.45, lateral 0.4)
  HybridAction look;
  look.kind = kMoveKind;
  RobotConfig c;
  c.tilt = 0.3;
  look.x = ObjectSearchModel::VecOf(c);
  auto r = model.Step(s, look, rng);
  EXPECT_EQ(r.reward, -1.0);
  EXPECT_EQ(r.observation.visible & 0b1110u, 0b1110u);
  EXPECT_EQ(r.observation.positive & 0b1110u, 0b0010u);
  EXPECT_EQ(r.observation.negative & 0b1110u, 0b0100u);
  // The 4 grids facing the robot (the -x side: corners with bit 0 clear) move by +-c_o = 0.5.
  for (int k = 0; k < 8; ++k) {
    const bool near = !(k & 1);
    EXPECT_FLOAT_EQ(r.state.objects[1].odds[k], near ? 0.8f : 0.3f) << k;
    EXPECT_FLOAT_EQ(r.state.objects[2].odds[k], near ? -0.8f : -0.3f) << k;
    EXPECT_FLOAT_EQ(r.state.objects[3].odds[k], 0.0f) << k;
  }
}

TEST(ObjectSearchModelTest, OccludedAndOutOfViewObjectsAreNotObserved) {
  World w = TestWorld();
  // Object 1 hides object 2 (same line of sight, closer); object 3 is behind the robot.
  w.objects.push_back(Object("front", Vec3(0.85, 0.0, 0.9), Vec3(0.1, 0.4, 0.3), 0.0f));
  w.objects.push_back(Object("hidden", Vec3(1.3, 0.0, 0.8), Vec3(0.1, 0.1, 0.1), 0.3f));
  w.objects.push_back(Object("behind", Vec3(-1.0, 0.0, 0.8), Vec3(0.1, 0.1, 0.1), 0.3f));
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(2);
  State s = model.SampleInitialState(rng);
  s.target = Vec3(1.3, 0.3, 0.8);  // also behind the front box (the ray passes y = 0.18 there)
  RobotConfig c;
  c.tilt = 0.3;
  std::array<std::array<int, 4>, 64> nearest;
  const uint64_t visible = model.VisibleObjects(s, c, &nearest);
  EXPECT_EQ(visible, 0b0010u);
  // Once the front box is removed both become visible.
  s.objects[1].status = kRemoved;
  EXPECT_EQ(model.VisibleObjects(s, c, &nearest), 0b0101u);
  // A guessed target inside a real box (a covered target) is never seen.
  s.target = Vec3(-1.0, 0.0, 0.8);
  EXPECT_EQ(model.VisibleObjects(s, c, &nearest) & 1u, 0u);
}

// The model keeps the boxes of the world it was given in precomputed form; a new world (after a
// real step) must replace them: the same object moved out of the sight line, and a new occluder.
TEST(ObjectSearchModelTest, ANewWorldReplacesTheOccluders) {
  World w = TestWorld();
  w.objects.push_back(Object("front", Vec3(0.85, 0.0, 0.9), Vec3(0.1, 0.4, 0.3), 0.0f));
  w.objects.push_back(Object("hidden", Vec3(1.3, 0.0, 0.8), Vec3(0.1, 0.1, 0.1), 0.3f));
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(2);
  State s = model.SampleInitialState(rng);
  s.target = Vec3(-1.0, 0.0, 0.8);  // behind the robot
  RobotConfig c;
  c.tilt = 0.3;
  EXPECT_FALSE(model.SeesObject(s, c, 2));
  World moved = w;
  moved.objects[1].box.center = Vec3(0.85, 0.6, 0.9);  // beside the sight line now
  model.SetWorld(std::make_shared<World>(moved));
  EXPECT_TRUE(model.SeesObject(s, c, 2));
  moved.furniture.push_back(moved.objects[1].box);
  moved.furniture.back().center = Vec3(0.85, 0.0, 0.9);  // furniture where the box was
  model.SetWorld(std::make_shared<World>(moved));
  EXPECT_FALSE(model.SeesObject(s, c, 2));
}

TEST(ObjectSearchModelTest, RewardTableAndIllegalActions) {
  World w = TestWorld();
  w.objects.push_back(Object("t", Vec3(1.0, 0.2, 0.8), Vec3(0.1, 0.1, 0.1), 0.0f));
  w.objects.push_back(Object("o", Vec3(1.0, -0.2, 0.8), Vec3(0.1, 0.1, 0.1), 0.0f));
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(3);
  State s = model.SampleInitialState(rng);
  for (auto& p : s.objects) p.moveable = true;
  // Five grids past the threshold are not enough to declare (n_odds = 6): illegal.
  s.objects[1].odds = {1, 1, 1, 1, 1, 0, 0, 0};
  auto r = model.Step(s, HybridAction{DeclareTargetKind(1), {}}, rng);
  EXPECT_EQ(r.reward, -1000.0);
  EXPECT_EQ(r.state.objects[1].status, kUpdating);
  s.objects[1].odds = {1, 1, 1, 1, 1, 1, 0, 0};
  r = model.Step(s, HybridAction{DeclareTargetKind(1), {}}, rng);
  EXPECT_EQ(r.reward, 5e4);
  EXPECT_EQ(r.state.objects[1].status, kDeclaredTarget);
  // Declaring it again, or as an obstacle, is illegal.
  EXPECT_EQ(model.Step(r.state, HybridAction{DeclareTargetKind(1), {}}, rng).reward, -1000.0);
  EXPECT_EQ(model.Step(r.state, HybridAction{DeclareObstacleKind(1), {}}, rng).reward, -1000.0);
  // Removing the declared target ends the episode with R_max.
  auto done = model.Step(r.state, HybridAction{RemoveKind(1), {}}, rng);
  EXPECT_EQ(done.reward, 1e5);
  EXPECT_TRUE(done.terminal);
  // Obstacles: declare (R_co), remove (2 R_min), re-removal illegal.
  s.objects[2].odds.fill(-1.0f);
  auto ob = model.Step(s, HybridAction{DeclareObstacleKind(2), {}}, rng);
  EXPECT_EQ(ob.reward, 1e4);
  auto removed = model.Step(ob.state, HybridAction{RemoveKind(2), {}}, rng);
  EXPECT_EQ(removed.reward, -2.0);
  EXPECT_EQ(removed.state.objects[2].status, kRemoved);
  EXPECT_FALSE(removed.terminal);
  EXPECT_EQ(model.Step(removed.state, HybridAction{RemoveKind(2), {}}, rng).reward, -1000.0);
  // Removing an undeclared object, or one this particle cannot move, is illegal.
  EXPECT_EQ(model.Step(s, HybridAction{RemoveKind(1), {}}, rng).reward, -1000.0);
  State stuck = ob.state;
  stuck.objects[2].moveable = false;
  EXPECT_EQ(model.Step(stuck, HybridAction{RemoveKind(2), {}}, rng).reward, -1000.0);
  // A base pose inside the table (occupied) is illegal and the robot stays.
  RobotConfig inside;
  inside.x = 1.2;
  auto bump = model.Step(s, HybridAction{kMoveKind, ObjectSearchModel::VecOf(inside)}, rng);
  EXPECT_EQ(bump.reward, -1000.0);
  EXPECT_EQ(bump.state.robot, s.robot);
  EXPECT_FALSE(model.IsFeasible(s, HybridAction{kMoveKind, ObjectSearchModel::VecOf(inside)}));
  // Nonexistent objects and the guessed target are not feasible for real execution.
  EXPECT_EQ(model.Step(s, HybridAction{DeclareTargetKind(9), {}}, rng).reward, -1000.0);
  EXPECT_FALSE(model.IsFeasible(s, HybridAction{DeclareTargetKind(0), {}}));
  EXPECT_TRUE(model.IsFeasible(s, HybridAction{DeclareTargetKind(1), {}}));
}

TEST(ObjectSearchModelTest, InitialStatesSampleTheGuessedTargetFromTheGrid) {
  World w = TestWorld();
  // Make only the table's far half likely.
  for (int c = 0; c < w.grid.num_cells(); ++c) {
    w.grid.set_log_odds(c, w.grid.CellCenter(c).x() > 1.2 ? 4.0f : -6.0f);
  }
  w.grid.RebuildSampler();
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(4);
  int far = 0;
  for (int i = 0; i < 2000; ++i) {
    State s = model.SampleInitialState(rng);
    EXPECT_NEAR(s.target.z(), 0.75 + 0.05, 1e-12);
    EXPECT_EQ(s.objects[0].odds[3], 0.2f);
    far += s.target.x() > 1.2;
  }
  // sigmoid(4) / (sigmoid(4) + sigmoid(-6)) = 0.9975
  EXPECT_GT(far, 1980);
}

// The aimed rollout looks where the belief puts the target, but not inside a box still standing:
// with the likely cells under a cover, its moves find the spot once the cover is removed in the
// state, and no more often than the greedy rollout's random moves while it stands.
TEST(ObjectSearchModelTest, AimedRolloutLooksBeneathARemovedCoverOnly) {
  World w = TestWorld();
  const Vec3 spot(1.55, 0.25, 0.8);
  for (int c = 0; c < w.grid.num_cells(); ++c) {
    const Vec3 p = w.grid.CellCenter(c);
    const bool under = std::abs(p.x() - spot.x()) < 0.05 && std::abs(p.y() - spot.y()) < 0.05;
    w.grid.set_log_odds(c, under ? 6.0f : -12.0f);
  }
  w.grid.RebuildSampler();
  w.objects.push_back(Object("cover", spot, Vec3(0.2, 0.2, 0.15), -3.0f));
  w.objects[1].status = kDeclaredObstacle;
  auto world = std::make_shared<World>(w);
  // The share of 2,000 rollout moves from `s` whose camera would see a target at the spot with
  // the cover gone.
  auto share = [&](SearchRollout rollout, int8_t cover_status) {
    ObjectSearchModel model(world, rollout);
    Rng rng(11);
    State s = model.SampleInitialState(rng);
    s.objects[1].status = cover_status;
    State open = s;
    open.objects[1].status = kRemoved;
    open.target = spot;
    int moves = 0, seen = 0;
    for (int i = 0; i < 2000; ++i) {
      const HybridAction a = model.RolloutAction(s, rng);
      if (a.kind != kMoveKind) continue;
      ++moves;
      seen += model.SeesObject(open, ObjectSearchModel::ConfigOf(a.x), 0);
    }
    EXPECT_GT(moves, 1000);
    return static_cast<double>(seen) / moves;
  };
  const double greedy = share(SearchRollout::kGreedy, kRemoved);
  const double aimed_removed = share(SearchRollout::kAimed, kRemoved);
  const double aimed_standing = share(SearchRollout::kAimed, kDeclaredObstacle);
  EXPECT_LT(greedy, 0.1);
  EXPECT_GT(aimed_removed, greedy + 0.25);
  EXPECT_LT(aimed_standing, greedy + 0.04);
}

TEST(GridWorldTest, TheOddsRuleWeighsASeenCellLessThanTheProbabilityRule) {
  // Two workspaces of one cell each; the second seen empty once (log-odds -2).
  GridWorld grid({Workspace{"a", Vec2(0, 0), 0.0, 0.02, 0.02, 0.7},
                  Workspace{"b", Vec2(1, 0), 0.0, 0.02, 0.02, 0.7}},
                 0.02);
  ASSERT_EQ(grid.num_cells(), 2);
  grid.set_log_odds(1, -2.0f);
  grid.RebuildSampler();
  const double sigmoid = 1.0 / (1.0 + std::exp(2.0));
  EXPECT_NEAR(grid.WorkspaceMass()[1], sigmoid / (0.5 + sigmoid), 1e-9);
  grid.SetSampling(GridSampling::kOdds);
  EXPECT_NEAR(grid.WorkspaceMass()[1], std::exp(-2.0) / (1.0 + std::exp(-2.0)), 1e-9);
}

TEST(RobotTest, TheShippedChainsGiveThePosesOfTheirFormerClosedForm) {
  // Before descriptions the camera stood at a fixed offset (raised by the lift on Fetch only),
  // turned by yaw + pan and pitched down by the tilt.
  auto closed_form = [](const Vec3& offset, bool lift_moves, const RobotConfig& c) {
    CameraPose p;
    const double cy = std::cos(c.yaw), sy = std::sin(c.yaw), h = c.yaw + c.pan;
    p.position =
        Vec3(c.x + cy * offset.x() - sy * offset.y(), c.y + sy * offset.x() + cy * offset.y(),
             offset.z() + (lift_moves ? c.lift : 0.0));
    p.forward =
        Vec3(std::cos(h) * std::cos(c.tilt), std::sin(h) * std::cos(c.tilt), -std::sin(c.tilt));
    p.left = Vec3(-std::sin(h), std::cos(h), 0.0);
    p.up = p.forward.cross(p.left);
    return p;
  };
  Rng rng(5);
  for (int i = 0; i < 200; ++i) {
    const RobotConfig c{rng.Uniform(-3, 3),  rng.Uniform(-3, 3),     rng.Uniform(-4, 4),
                        rng.Uniform(0, 0.4), rng.Uniform(-0.3, 0.3), rng.Uniform(-0.5, 0.5)};
    for (bool fetch : {true, false}) {
      const CameraPose a =
          CameraPoseFor(fetch ? RobotDescription::Fetch() : RobotDescription::Stretch(), c);
      const CameraPose b = closed_form(fetch ? Vec3(0.15, 0, 1.08) : Vec3(0.05, 0, 1.29), fetch, c);
      EXPECT_LT((a.position - b.position).norm(), 1e-12);
      EXPECT_LT((a.forward - b.forward).norm(), 1e-12);
      EXPECT_LT((a.left - b.left).norm(), 1e-12);
      EXPECT_LT((a.up - b.up).norm(), 1e-12);
    }
  }
  EXPECT_TRUE(RobotDescription::Fetch().has_lift());
  EXPECT_FALSE(RobotDescription::Stretch().has_lift());  // plans in one dimension fewer
  RobotDescription bad = RobotDescription::Fetch();
  bad.chain.push_back(bad.chain[0]);  // a second lift
  EXPECT_EQ(bad.Validate().field_violations()[0].field, "joints[3].role");
  bad = RobotDescription::Fetch();
  bad.chain[1].axis = Vec3::Zero();
  EXPECT_EQ(bad.Validate().field_violations()[0].field, "joints[1].axis");
  bad = RobotDescription::Fetch();
  bad.chain.resize(RobotDescription::kMaxJoints + 1);
  EXPECT_EQ(bad.Validate().field_violations()[0].field, "joints");
}

TEST(GridWorldTest, ViewLowersVisibleCellsOnly) {
  World w = TestWorld();
  RobotConfig c;
  c.tilt = 0.45;
  const CameraPose pose = CameraPoseFor(w.robot, c);
  Box blocker;
  blocker.center = Vec3(1.0, 0.0, 0.9);
  blocker.size = Vec3(0.1, 0.2, 0.3);
  GridWorld grid = w.grid;
  const int updated = grid.UpdateFromView(w.camera, pose, {blocker}, 0.05, -1.0f, -6.0f, 6.0f);
  EXPECT_GT(updated, 100);
  int lowered = 0, kept_in_view = 0;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    const Vec3 p = grid.CellCenter(cell, 0.05);
    const bool in_view = InFrustum(w.camera, pose, p);
    const bool hidden = blocker.Contains(p) || blocker.BlocksSegment(pose.position, p);
    if (grid.log_odds(cell) < 0) ++lowered;
    if (!in_view || hidden) {
      EXPECT_EQ(grid.log_odds(cell), 0.0f);
    } else {
      EXPECT_EQ(grid.log_odds(cell), -1.0f);
    }
    if (in_view && hidden) ++kept_in_view;
  }
  EXPECT_EQ(lowered, updated);
  EXPECT_GT(kept_in_view, 10);  // the shadow behind the blocker keeps its odds
  // The sampler follows: the remaining mass sits outside the seen area.
  Rng rng(5);
  int in_seen = 0;
  for (int i = 0; i < 1000; ++i) {
    const Vec3 p = grid.Sample(rng, 0.05);
    const bool seen = InFrustum(w.camera, pose, p) && !blocker.Contains(p) &&
                      !blocker.BlocksSegment(pose.position, p);
    in_seen += seen;
  }
  // Seen cells weigh sigmoid(-1) = 0.269 against sigmoid(0) = 0.5 for the others.
  const double f = static_cast<double>(updated) / grid.num_cells();
  const double expected = f * 0.2689 / (f * 0.2689 + (1 - f) * 0.5);
  EXPECT_NEAR(in_seen / 1000.0, expected, 0.05);
}

TEST(WorldTest, RealObservationAppendsObjectsAndUpdatesOdds) {
  World w = TestWorld();
  RealObservation obs;
  obs.achieved.tilt = 0.4;
  ObjectDetection d;
  d.key = "cluster-7";
  d.box.center = Vec3(1.1, 0.1, 0.8);
  d.box.size = Vec3(0.1, 0.1, 0.1);
  d.faces = {{0, 0.8}, {2, 0.95}, {4, 0.5}};
  obs.objects.push_back(d);
  ASSERT_TRUE(ApplyRealObservation(&w, obs).ok());
  ASSERT_EQ(w.objects.size(), 2u);
  EXPECT_NEAR(w.objects[1].odds[0], std::log(4.0), 1e-6);
  EXPECT_NEAR(w.objects[1].odds[2], 2.0, 1e-6);  // log(19) clamped to detection_max_step
  EXPECT_NEAR(w.objects[1].odds[4], 0.0, 1e-6);
  EXPECT_EQ(w.objects[1].odds[1], 0.0f);
  EXPECT_EQ(w.steps, 1);
  // The same key updates the same object.
  ASSERT_TRUE(ApplyRealObservation(&w, obs).ok());
  EXPECT_EQ(w.objects.size(), 2u);
  EXPECT_NEAR(w.objects[1].odds[0], 2 * std::log(4.0), 1e-6);
  // Bad input names the field and changes nothing.
  RealObservation bad = obs;
  bad.objects[0].faces[1].corner = 9;
  const World before = w;
  Status s = ApplyRealObservation(&w, bad);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.message().find("objects[0].faces[1].corner"), std::string::npos);
  EXPECT_EQ(w.objects.size(), before.objects.size());
  EXPECT_EQ(w.steps, before.steps);
  bad = obs;
  bad.achieved.x = std::nan("");
  EXPECT_NE(ApplyRealObservation(&w, bad).message().find("robot state"), std::string::npos);
}

// A removal the robot reports failed: the object keeps its status, becomes unremovable in every
// particle, and later detections do not make it moveable again; a failed declaration changes
// nothing.
TEST(WorldTest, AFailedRemovalLeavesTheObjectUnremovable) {
  World w = TestWorld();
  w.objects.push_back(Object("box", Vec3(1.1, 0.1, 0.8), Vec3(0.1, 0.1, 0.1), -3.0f));
  w.objects[1].moveability = 0.9;
  ASSERT_TRUE(ApplyDiscreteOutcome(&w, 1, kDeclareObstacleOffset, false).ok());
  EXPECT_EQ(w.objects[1].status, kUpdating);
  ASSERT_TRUE(ApplyDiscreteOutcome(&w, 1, kDeclareObstacleOffset, true).ok());
  ASSERT_EQ(w.objects[1].status, kDeclaredObstacle);
  ASSERT_TRUE(ApplyDiscreteOutcome(&w, 1, kRemoveOffset, false).ok());
  EXPECT_EQ(w.objects[1].status, kDeclaredObstacle);
  EXPECT_TRUE(w.objects[1].removal_failed);
  EXPECT_EQ(w.objects[1].moveability, 0.0);
  RealObservation obs;
  obs.achieved.tilt = 0.4;
  ObjectDetection d;
  d.key = "box";
  d.box = w.objects[1].box;
  d.moveability = 0.95;
  obs.objects.push_back(d);
  ASSERT_TRUE(ApplyRealObservation(&w, obs).ok());
  EXPECT_EQ(w.objects[1].moveability, 0.0);
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(5);
  for (int k = 0; k < 100; ++k) {
    const State s = model.SampleInitialState(rng);
    ASSERT_FALSE(s.objects[1].moveable);
    EXPECT_EQ(model.Step(s, HybridAction{RemoveKind(1), {}}, rng).reward, -1000.0);
  }
  EXPECT_FALSE(ApplyDiscreteOutcome(&w, 1, 3, false).ok());
  EXPECT_FALSE(ApplyDiscreteOutcome(&w, 2, kRemoveOffset, false).ok());
}

// A 3D box detector's one score per box: the faces the camera sees get it, hidden ones do not.
TEST(WorldTest, AWholeBoxScoreGoesToTheFacesTheCameraSees) {
  World w = TestWorld();
  RealObservation obs;
  obs.achieved.tilt = 0.4;
  ObjectDetection d;
  d.key = "box-1";
  d.box.center = Vec3(1.1, 0.1, 0.8);
  d.box.size = Vec3(0.1, 0.1, 0.1);
  d.score = 0.8;
  obs.objects.push_back(d);
  const CameraPose pose = CameraPoseFor(w.robot, obs.achieved);
  const std::vector<int> seen = SeenCorners(d.box, w.camera, pose, w.furniture);
  ASSERT_FALSE(seen.empty());
  ASSERT_TRUE(ApplyRealObservation(&w, obs).ok());
  ASSERT_EQ(w.objects.size(), 2u);
  for (int k = 0; k < 8; ++k) {
    const bool got = std::find(seen.begin(), seen.end(), k) != seen.end();
    EXPECT_NEAR(w.objects[1].odds[k], got ? std::log(4.0) : 0.0, 1e-6) << "corner " << k;
  }
  // A box detected in front of it hides it: no face of it gets the score.
  World hidden = TestWorld();
  RealObservation behind = obs;
  ObjectDetection wall;
  wall.key = "wall";
  wall.box.center = Vec3(0.8, 0.1, 0.8);
  wall.box.size = Vec3(0.05, 1.0, 1.0);
  wall.score = 0.1;
  behind.objects.push_back(wall);
  ASSERT_TRUE(ApplyRealObservation(&hidden, behind).ok());
  const int box = hidden.FindObject("box-1");
  ASSERT_GE(box, 0);
  for (int k = 0; k < 8; ++k) EXPECT_EQ(hidden.objects[box].odds[k], 0.0f) << "corner " << k;
  // One score and per-face scores together, or a score beyond [0, 1], name the field.
  RealObservation bad = obs;
  bad.objects[0].faces = {{0, 0.8}};
  EXPECT_NE(ApplyRealObservation(&w, bad).message().find("objects[0].score"), std::string::npos);
  bad = obs;
  bad.objects[0].score = 1.5;
  EXPECT_NE(ApplyRealObservation(&w, bad).message().find("objects[0].score"), std::string::npos);
}

TEST(ObjectSearchModelTest, PlannersDeclareAndRemoveAConfirmedTarget) {
  World w = TestWorld();
  w.objects.push_back(Object("t", Vec3(1.0, 0.2, 0.8), Vec3(0.1, 0.1, 0.1), 2.0f));
  auto world = std::make_shared<World>(w);
  ObjectSearchModel model(world);
  Rng rng(6);
  KctOptions ko;
  ko.observations.enabled = false;
  ko.search.num_particles = 200;
  KCenterTree<ObjectSearchModel> kct(model, ko);
  kct.Reset(rng);
  auto d = kct.Plan(Budget::Simulations(2000), rng);
  ASSERT_TRUE(d.status.ok()) << d.status.ToString();
  EXPECT_EQ(d.action.kind, DeclareTargetKind(1));
  DiscreteObjectSearch discrete(model, DiscreteActionSet::kJoint);
  PomcpOptions po;
  po.search.num_particles = 200;
  Pomcp<DiscreteObjectSearch> pomcp(discrete, po);
  pomcp.Reset(rng);
  auto pd = pomcp.Plan(Budget::Simulations(2000), rng);
  ASSERT_TRUE(pd.status.ok());
  EXPECT_EQ(discrete.ToHybrid(pd.action, w.robot_config).kind, DeclareTargetKind(1));
  EXPECT_EQ(discrete.num_moves(), 1 * 3 * 9);
}

// Four base regions around the table, so that the manual set has the paper's four poses.
World FourSidedWorld() {
  World w = TestWorld();
  w.base_regions = {{Vec2(-0.5, -0.6), Vec2(0.4, 0.6)},
                    {Vec2(2.0, -0.6), Vec2(2.6, 0.6)},
                    {Vec2(0.7, 0.8), Vec2(1.7, 1.4)},
                    {Vec2(0.7, -1.4), Vec2(1.7, -0.8)}};
  return w;
}

TEST(DiscreteActionSetTest, ARobotWithoutALiftHasNoLiftActions) {
  World w = FourSidedWorld();
  w.robot = RobotDescription::Stretch();
  ObjectSearchModel model(std::make_shared<World>(w));
  DiscreteObjectSearch primitive(model, DiscreteActionSet::kPrimitive);
  DiscreteObjectSearch joint(model, DiscreteActionSet::kJoint);
  EXPECT_EQ(w.ManualLifts(), std::vector<double>{0.0});
  EXPECT_EQ(primitive.num_moves(), 4 + 1 + 9);
  EXPECT_EQ(joint.num_moves(), 4 * 1 * 9);
  std::set<std::tuple<double, double, double, double, double, double>> distinct;
  for (int a = 0; a < joint.num_moves(); ++a) {
    const RobotConfig c = joint.MoveTarget(a, RobotConfig{});
    EXPECT_EQ(c.lift, 0.0);
    distinct.insert({c.x, c.y, c.yaw, c.lift, c.pan, c.tilt});
  }
  EXPECT_EQ(distinct.size(), 36u);  // no configuration twice
}

TEST(DiscreteActionSetTest, PrimitiveActionsChangeOnePartAndAViewCanTakeThreeSteps) {
  const World w = FourSidedWorld();
  ObjectSearchModel model(std::make_shared<World>(w));
  DiscreteObjectSearch primitive(model, DiscreteActionSet::kPrimitive);
  DiscreteObjectSearch joint(model, DiscreteActionSet::kJoint);
  ASSERT_EQ(primitive.poses().size(), 4u);
  EXPECT_EQ(primitive.num_moves(), 4 + 3 + 9);
  EXPECT_EQ(joint.num_moves(), 4 * 3 * 9);
  RobotConfig from;
  from.x = -0.3;
  from.y = 0.1;
  from.yaw = 0.2;
  from.lift = 0.13;
  from.pan = 0.05;
  from.tilt = 0.21;
  // Every primitive action changes exactly one part: the base pose, the lift, or the head.
  for (int a = 0; a < primitive.num_moves(); ++a) {
    const RobotConfig to = primitive.MoveTarget(a, from);
    const bool base = to.x != from.x || to.y != from.y || to.yaw != from.yaw;
    const bool lift = to.lift != from.lift;
    const bool head = to.pan != from.pan || to.tilt != from.tilt;
    EXPECT_EQ(base + lift + head, 1) << "action " << a;
  }
  // Breadth-first search over primitive actions: reaching a joint configuration that differs in
  // base, lift and head takes three steps, and none of the 108 takes fewer than the parts that
  // differ.
  auto key = [](const RobotConfig& c) {
    return std::make_tuple(c.x, c.y, c.yaw, c.lift, c.pan, c.tilt);
  };
  std::map<decltype(key(from)), int> depth;
  std::queue<RobotConfig> frontier;
  depth[key(from)] = 0;
  frontier.push(from);
  while (!frontier.empty()) {
    const RobotConfig c = frontier.front();
    frontier.pop();
    for (int a = 0; a < primitive.num_moves(); ++a) {
      const RobotConfig n = primitive.MoveTarget(a, c);
      if (depth.emplace(key(n), depth[key(c)] + 1).second) frontier.push(n);
    }
  }
  int three = 0;
  for (int a = 0; a < joint.num_moves(); ++a) {
    const RobotConfig target = joint.MoveTarget(a, from);
    ASSERT_TRUE(depth.count(key(target))) << "joint configuration " << a << " unreachable";
    const int parts = (target.x != from.x || target.y != from.y || target.yaw != from.yaw) +
                      (target.lift != from.lift) +
                      (target.pan != from.pan || target.tilt != from.tilt);
    EXPECT_EQ(depth[key(target)], parts) << "joint configuration " << a;
    three += depth[key(target)] == 3;
  }
  EXPECT_EQ(three, 4 * 3 * 9);  // from this start every new view needs all three parts changed
  // A joint action reaches any of them in one step.
  EXPECT_EQ(ObjectSearchModel::ConfigOf(joint.ToHybrid(57, from).x), joint.MoveTarget(57, from));
}

TEST(DiscreteActionSetTest, PomcpPlansWithoutTheGuessedTargetAndGpomcpWithIt) {
  // Nothing detected yet: only the guessed target, sampled on the table, can make a view
  // valuable. GPOMCP sees the value of looking; the paper's POMCP has no guessed target and
  // values every action at the step cost.
  const World w = FourSidedWorld();
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(11);
  auto belief = ParticleBelief<State>::FromInitial(model, 300, rng);
  auto pomcp = MakeSearchPlanner("pomcp", model, {}).value();
  auto gpomcp = MakeSearchPlanner("gpomcp", model, {}).value();
  pomcp->SetBelief(belief);
  gpomcp->SetBelief(belief);
  const auto dp = pomcp->Plan(Budget::Simulations(3000), rng);
  const auto dg = gpomcp->Plan(Budget::Simulations(3000), rng);
  ASSERT_TRUE(dp.status.ok() && dg.status.ok());
  EXPECT_LT(dp.value, 0.0);     // only step costs
  EXPECT_GT(dg.value, 1000.0);  // declaring the guessed target is within reach
  EXPECT_FALSE(MakeSearchPlanner("oracle", model, {}).ok());
  EXPECT_FALSE(MakeSearchPlanner("oracle-cover-unknown", model, {}).ok());
  EXPECT_FALSE(MakeSearchPlanner("nope", model, {}).ok());
  for (const std::string& name : PlannerRegistry::BuiltIn().Names(/*servable_only=*/true)) {
    auto p = MakeSearchPlanner(name, model, {});
    ASSERT_TRUE(p.ok()) << name;
    (*p)->SetBelief(belief);
    EXPECT_TRUE((*p)->Plan(Budget::Simulations(200), rng).status.ok()) << name;
  }
}

TEST(SearchPlannerTest, ProposalOptionsAreRefusedWhereTheFilterDrawsTheCandidates) {
  // npfkct with a sampler (the neural filter in the server and the benchmark) takes its
  // candidates from it: proposals.* would be options given and not used.
  const World w = FourSidedWorld();
  ObjectSearchModel model(std::make_shared<World>(w));
  auto sampler = std::make_shared<AimedCandidateSampler>(model);
  const std::vector<std::pair<std::string, double>> share = {{"proposals.object_share", 0.1}};
  const auto refused = MakeSearchPlanner("npfkct", model, share, sampler);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find("proposals.object_share"), std::string::npos);
  EXPECT_NE(refused.status().message().find("filter"), std::string::npos);
  EXPECT_TRUE(MakeSearchPlanner("npfkct", model, share).ok());  // no filter: its own proposals
  EXPECT_TRUE(MakeSearchPlanner("kct", model, share, sampler).ok());
}

TEST(HybridBaselinesTest, NewActionsAreFeasibleConfigurations) {
  // With the reasonability check the continuous baselines never waste a simulation on a base
  // outside the base regions: every root action they try is feasible.
  const World w = FourSidedWorld();
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(12);
  auto belief = ParticleBelief<State>::FromInitial(model, 300, rng);
  for (const char* name : {"pomcpow", "vomcpow", "advt"}) {
    auto p = MakeSearchPlanner(name, model, {}).value();
    p->SetBelief(belief);
    const auto d = p->Plan(Budget::Simulations(2000), rng);
    ASSERT_TRUE(d.status.ok()) << name;
    int moves = 0;
    for (const auto& r : d.root) {
      if (r.action.kind != kMoveKind) continue;
      ++moves;
      EXPECT_TRUE(model.IsFeasible(belief.particle(0), r.action))
          << name << ": " << r.action.ToString();
    }
    EXPECT_GT(moves, 3) << name;
  }
}

TEST(WorldTest, AddBoxMarksExactlyTheCellsWhoseCentersTheBoxCovers) {
  // Checked against every cell of the map, for boxes at random poses.
  Rng rng(21);
  OccupancyMap map(Vec2(-3, -2), Vec2(4, 3), 0.05);
  for (int i = 0; i < 30; ++i) {
    Box b;
    b.center = Vec3(rng.Uniform(-3.5, 4.5), rng.Uniform(-2.5, 3.5), 0.4);
    b.size = Vec3(rng.Uniform(0.05, 2.0), rng.Uniform(0.05, 2.0), 0.8);
    b.yaw = rng.Uniform(-3.2, 3.2);
    const double margin = i % 3 == 0 ? 0.1 : 0.0;
    map.AddBox(b, margin);
    for (int iy = 0; iy < map.ny(); ++iy) {
      for (int ix = 0; ix < map.nx(); ++ix) {
        const Vec3 l = b.ToLocal(Vec3(-3 + (ix + 0.5) * 0.05, -2 + (iy + 0.5) * 0.05, 0.4));
        if (std::abs(l.x()) <= 0.5 * b.size.x() + margin &&
            std::abs(l.y()) <= 0.5 * b.size.y() + margin) {
          ASSERT_TRUE(map.Occupied(ix, iy)) << "box " << i << " cell " << ix << "," << iy;
        }
      }
    }
  }
}

// A rectangular base (0.9 m x 0.3 m) between two boxes 0.5 m apart: it fits lengthwise along the
// gap, not across it, where the disc around it fits neither way; its polygon's checks name the
// vertex; a robot without a polygon is the disc at any heading.
TEST(WorldTest, AFootprintPolygonFitsWhereItsHeadingLetsIt) {
  OccupancyMap map(Vec2(-2, -2), Vec2(2, 2), 0.05);
  Box left, right;
  left.center = Vec3(0, 0.75, 0.4);
  right.center = Vec3(0, -0.75, 0.4);
  left.size = right.size = Vec3(2.0, 1.0, 0.8);  // the gap: |y| < 0.25
  map.AddBox(left);
  map.AddBox(right);
  RobotDescription robot = RobotDescription::Fetch();
  robot.footprint = {Vec2(0.45, 0.15), Vec2(-0.45, 0.15), Vec2(-0.45, -0.15), Vec2(0.45, -0.15)};
  ASSERT_TRUE(robot.Validate().ok());
  EXPECT_NEAR(robot.footprint_radius, std::hypot(0.45, 0.15), 1e-12);
  EXPECT_TRUE(map.FootprintFree(robot, 0.0, 0.0, 0.0, 0.0));
  EXPECT_TRUE(map.FootprintFree(robot, 0.0, 0.0, std::numbers::pi, 0.05));
  EXPECT_FALSE(map.FootprintFree(robot, 0.0, 0.0, 0.0, 0.15));  // the clearance touches
  EXPECT_FALSE(map.FootprintFree(robot, 0.0, 0.0, 0.5 * std::numbers::pi, 0.0));
  EXPECT_FALSE(map.FootprintFree(robot, 0.0, 0.12, 0.0, 0.0));  // its side in the box
  EXPECT_FALSE(map.FootprintFree(robot, 1.8, 0.0, 0.0, 0.0));   // past the map's edge
  RobotDescription disc = RobotDescription::Fetch();
  disc.footprint_radius = robot.footprint_radius;
  for (double yaw : {0.0, 0.5 * std::numbers::pi}) {
    EXPECT_FALSE(map.FootprintFree(disc, 0.0, 0.0, yaw, 0.0));
  }
  disc.footprint_radius = 0.2;
  EXPECT_EQ(map.FootprintFree(disc, 0.0, 0.0, 1.0, 0.0), map.DiscFree(0.0, 0.0, 0.2));
  // The polygon's checks.
  auto field = [](std::vector<Vec2> footprint) {
    RobotDescription r = RobotDescription::Fetch();
    r.footprint = std::move(footprint);
    const Status s = r.Validate();
    return s.ok() ? std::string("ok") : s.field_violations()[0].field;
  };
  EXPECT_EQ(field({Vec2(0, 0), Vec2(0.4, 0.2), Vec2(0.4, 0), Vec2(0, 0.4)}),
            "footprint[2]");  // a bow tie: its edges cross
  EXPECT_EQ(field({Vec2(0, 0), Vec2(1, 0)}), "footprint");
  EXPECT_EQ(field({Vec2(0, 0), Vec2(1, 0), Vec2(2, 0)}), "footprint");  // no area
  EXPECT_EQ(field({Vec2(0, 0), Vec2(6, 0), Vec2(0, 1)}), "footprint[1]");
  EXPECT_EQ(field({Vec2(0, 0), Vec2(std::nan(""), 0), Vec2(0, 1)}), "footprint[1]");
  EXPECT_EQ(field({Vec2(0.3, 0), Vec2(-0.2, 0.2), Vec2(-0.2, -0.2)}), "ok");
}

TEST(WorldTest, BuildWorldNamesThePartOfThePriorMap) {
  PriorMap prior;
  prior.furniture.push_back({"table", {Vec3(1.5, 0, 0.375), 0.0, Vec3(1, 1, 0.75)}, true});
  prior.base_regions.push_back({Vec2(-0.5, -0.5), Vec2(0.5, 0.5)});
  auto w = BuildWorld(prior);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  EXPECT_EQ(w->grid.workspaces().size(), 1u);
  EXPECT_TRUE(w->occupancy.Occupied(static_cast<int>((1.5 + 3) / 0.05), 60));
  prior.start.x = 1.5;  // inside the table
  auto bad = BuildWorld(prior);
  ASSERT_FALSE(bad.ok());
  ASSERT_EQ(bad.status().field_violations().size(), 1u);
  EXPECT_EQ(bad.status().field_violations()[0].field, "start");
  prior.start.x = 0;
  prior.robot.footprint_radius = -1.0;
  EXPECT_EQ(BuildWorld(prior).status().field_violations()[0].field, "robot.footprintRadius");
}

TEST(WorldTest, AGuessedTargetDeclarableBeforeItIsSeenIsRefused) {
  // Its faces restart at guess_odds every step: at or past the threshold the planners offered
  // to declare it, and no observation could follow that action.
  SearchParams p;
  EXPECT_TRUE(p.Validate().ok());
  p.guess_odds = 1.0;
  p.declare_threshold = 0.6;
  EXPECT_FALSE(p.Validate().ok());
  p.guess_odds = -0.6;
  EXPECT_FALSE(p.Validate().ok());
  p.guess_odds = 0.2;
  p.declare_threshold = 0.1;
  EXPECT_FALSE(p.Validate().ok());
  p.declare_threshold = 0.3;
  EXPECT_TRUE(p.Validate().ok());
  // The faces are floats: 0.599999995 rounds to 0.6000000238, past a threshold of 0.6.
  p.declare_threshold = 0.6;
  p.guess_odds = 0.599999995;
  EXPECT_FALSE(p.Validate().ok());
  p.guess_odds = -0.599999995;
  EXPECT_FALSE(p.Validate().ok());
  p.guess_odds = 0.59999;
  EXPECT_TRUE(p.Validate().ok());
  // Odds clamped below the threshold could never be declared.
  p.face_odds_limit = 0.5;
  EXPECT_FALSE(p.Validate().ok());
}

TEST(WorldTest, BaseRegionsAreCutToTheRoomAndMustLeaveRoomForTheBase) {
  PriorMap prior;  // the room is [-3, 3] x [-3, 3]
  prior.furniture.push_back({"table", {Vec3(1.5, 0, 0.375), 0.0, Vec3(1, 1, 0.75)}, true});
  prior.base_regions.push_back({Vec2(-1e4, -1e4), Vec2(0.5, 1e4)});
  auto w = BuildWorld(prior);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  EXPECT_EQ(w->base_regions[0].min, Vec2(-3, -3));
  EXPECT_EQ(w->base_regions[0].max, Vec2(0.5, 3));
  prior.base_regions.push_back({Vec2(5, 5), Vec2(6, 6)});  // outside the room
  auto outside = BuildWorld(prior);
  ASSERT_FALSE(outside.ok());
  EXPECT_EQ(outside.status().field_violations()[0].field, "baseRegions[1]");
  prior.base_regions = {{Vec2(1.2, -0.3), Vec2(1.8, 0.3)}};  // inside the table
  auto blocked = BuildWorld(prior);
  ASSERT_FALSE(blocked.ok());
  EXPECT_EQ(blocked.status().field_violations()[0].field, "baseRegions");
  prior.base_regions.push_back({Vec2(-2.5, 1.0), Vec2(-2.4, 1.1)});  // a small free corner
  EXPECT_TRUE(BuildWorld(prior).ok());
}

// A SLAM map: its occupied cells keep the base out; without base regions, four strips around
// each workspace from the footprint (plus clearance) to the reach.
TEST(WorldTest, AnOccupancyGridBlocksTheBaseAndRegionsGoAroundTheWorkspaces) {
  PriorMap prior;  // the room is [-3, 3] x [-3, 3] at 5 cm: 120 x 120 cells
  prior.furniture.push_back({"table", {Vec3(1.5, 0, 0.375), 0.0, Vec3(1, 1, 0.75)}, true});
  const auto regions = BaseRegionsAround(prior);
  ASSERT_EQ(regions.size(), 4u);
  const double inner = prior.robot.footprint_radius + prior.params.base_clearance;
  EXPECT_NEAR(regions[0].min.x(), 1.0 - prior.robot.reach, 1e-12);
  EXPECT_NEAR(regions[0].max.x(), 1.0 - inner, 1e-12);
  EXPECT_NEAR(regions[3].min.y(), 0.5 + inner, 1e-12);
  prior.occupied.assign(120 * 120, 0);
  // A wall along x = 0.5 (columns 70-71) the whole height of the room.
  for (int row = 0; row < 120; ++row)
    prior.occupied[row * 120 + 70] = prior.occupied[row * 120 + 71] = 1;
  auto w = BuildWorld(prior);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  EXPECT_EQ(w->base_regions.size(), 4u);      // derived
  EXPECT_FALSE(w->BaseFeasible(0.55, -0.8));  // on the wall
  EXPECT_TRUE(w->BaseFeasible(2.4, 0.0));     // the table's far side
  prior.occupied.resize(100);                 // not the room's cells
  EXPECT_EQ(BuildWorld(prior).status().field_violations()[0].field, "occupancyGrid");
}

TEST(GeometryTest, TheBoxAroundAPolygonIsItsSmallestRectangle) {
  // A 1.2 x 0.8 table turned by 30 degrees, traced with an extra point on one side.
  const double yaw = 0.5235987755982988, c = std::cos(yaw), s = std::sin(yaw);
  std::vector<Vec2> polygon;
  for (const Vec2& p : {Vec2(-0.6, -0.4), Vec2(0.0, -0.4), Vec2(0.6, -0.4), Vec2(0.6, 0.4),
                        Vec2(-0.6, 0.4), Vec2(0.1, 0.1)}) {
    polygon.emplace_back(2.0 + c * p.x() - s * p.y(), 1.0 + s * p.x() + c * p.y());
  }
  auto box = BoxAroundPolygon(polygon, 0.75);
  ASSERT_TRUE(box.ok()) << box.status().ToString();
  EXPECT_NEAR(box->center.x(), 2.0, 1e-9);
  EXPECT_NEAR(box->center.y(), 1.0, 1e-9);
  EXPECT_NEAR(box->center.z(), 0.375, 1e-12);
  EXPECT_NEAR(box->size.x() * box->size.y(), 1.2 * 0.8, 1e-9);
  EXPECT_NEAR(std::max(box->size.x(), box->size.y()), 1.2, 1e-9);
  const double turn = std::fmod(box->yaw - yaw + 4 * M_PI, M_PI / 2);  // a quarter turn's rest
  EXPECT_NEAR(std::min(turn, M_PI / 2 - turn), 0.0, 1e-9);
  EXPECT_FALSE(BoxAroundPolygon({Vec2(0, 0), Vec2(1, 1), Vec2(2, 2)}, 0.7).ok());  // no area
  EXPECT_FALSE(BoxAroundPolygon({Vec2(0, 0), Vec2(1, 1)}, 0.7).ok());
}

TEST(PlannerRegistryTest, BuiltInPlannersAreListedInTableOrderWithValidNames) {
  const PlannerRegistry& r = PlannerRegistry::BuiltIn();
  EXPECT_EQ(r.Names(), (std::vector<std::string>{"npfkct", "kct", "pomcp", "gpomcp", "pomcp-joint",
                                                 "pomcpow", "vomcpow", "advt", "nbv", "rollout",
                                                 "oracle", "oracle-cover-unknown"}));
  EXPECT_EQ(r.Names(/*servable_only=*/true).size(), 10u);
  PlannerRegistry copy = r;
  for (const PlannerEntry& e : r.entries()) {
    EXPECT_FALSE(copy.Add(e).ok()) << e.name;  // taken
  }
  PlannerEntry bad = r.entries()[0];
  for (const char* name : {"", "Upper", "with space", "x/y"}) {
    bad.name = name;
    EXPECT_FALSE(copy.Add(bad).ok()) << name;
  }
  bad.name = "fine-name2";
  bad.make = nullptr;
  EXPECT_FALSE(copy.Add(bad).ok());
  EXPECT_TRUE(r.Find("npfkct")->takes_sampler);
  EXPECT_FALSE(r.Find("kct")->takes_sampler);
  EXPECT_TRUE(r.Find("oracle")->needs_truth);
}

// Equal keys and values, NaN (an automatic value) equal to NaN.
bool SameOptions(const OptionList& a, const OptionList& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].first != b[i].first) return false;
    const bool both_nan = std::isnan(a[i].second) && std::isnan(b[i].second);
    if (!both_nan && a[i].second != b[i].second) return false;
  }
  return true;
}

TEST(PlannerRegistryTest, OptionsUsedAreTheDefaultsWithTheOverridesApplied) {
  const World w = FourSidedWorld();
  ObjectSearchModel model(std::make_shared<World>(w));
  for (const std::string& name : PlannerRegistry::BuiltIn().Names(/*servable_only=*/true)) {
    const PlannerEntry* e = PlannerRegistry::BuiltIn().Find(name);
    const OptionList defaults = e->defaults(w.params);
    auto plain = MakeSearchPlanner(name, model, {});
    ASSERT_TRUE(plain.ok()) << name;
    EXPECT_TRUE(SameOptions((*plain)->OptionsUsed(), defaults)) << name;
    const bool searches = std::any_of(defaults.begin(), defaults.end(), [](const auto& kv) {
      return kv.first == "search.max_depth";
    });
    if (!searches) continue;  // the references without a tree have no depth
    auto deeper = MakeSearchPlanner(name, model, {{"search.max_depth", 20}});
    ASSERT_TRUE(deeper.ok()) << name;
    OptionList expected = defaults;
    for (auto& [key, value] : expected) {
      if (key == "search.max_depth") value = 20;
    }
    EXPECT_TRUE(SameOptions((*deeper)->OptionsUsed(), expected)) << name;
  }
  // The object-search defaults every planner shares: depth 12, 300 particles.
  const OptionList kct = PlannerRegistry::BuiltIn().Find("kct")->defaults(w.params);
  EXPECT_NE(
      std::find(kct.begin(), kct.end(), std::pair<std::string, double>("search.max_depth", 12)),
      kct.end());
  // A bad override names the option.
  auto bad = MakeSearchPlanner("kct", model, {{"k", 1}});
  ASSERT_FALSE(bad.ok());
  EXPECT_NE(bad.status().message().find("k must be >= 2"), std::string::npos);
}

TEST(PlannerRegistryTest, PlannersThatNeedTheTruthAreRefusedWithoutIt) {
  const World w = FourSidedWorld();
  ObjectSearchModel model(std::make_shared<World>(w));
  auto oracle = MakeSearchPlanner("oracle", model, {});
  ASSERT_FALSE(oracle.ok());
  EXPECT_NE(oracle.status().message().find("true world"), std::string::npos);
  auto unknown = MakeSearchPlanner("nope", model, {});
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().message().find("expected one of npfkct, kct"), std::string::npos);
}

TEST(RolloutTest, TheClearingRolloutDeclaresOnlyTheCoverOfTheParticlesTarget) {
  World w = FourSidedWorld();
  // Two boxes, each confirmed an obstacle on every face; the particle's target is in the first.
  w.objects.push_back(Object("cover", Vec3(1.2, 0.2, 0.85), Vec3(0.2, 0.2, 0.2), -3.0f));
  w.objects.push_back(Object("other", Vec3(1.2, -0.25, 0.85), Vec3(0.2, 0.2, 0.2), -3.0f));
  ObjectSearchModel clear(std::make_shared<World>(w), SearchRollout::kClear);
  ObjectSearchModel aimed(std::make_shared<World>(w), SearchRollout::kAimed);
  Rng rng(7);
  State s = clear.SampleInitialState(rng);
  s.target = Vec3(1.2, 0.2, 0.8);
  ASSERT_EQ(clear.CoverOf(s), 1);
  EXPECT_EQ(clear.RolloutAction(s, rng).kind, DeclareObstacleKind(1));
  // The aimed rollout declares whichever obstacle it can, the clearing one only the cover.
  s.target = Vec3(0.9, 0.0, 0.8);
  ASSERT_EQ(clear.CoverOf(s), -1);
  EXPECT_EQ(clear.RolloutAction(s, rng).kind, kMoveKind);
  EXPECT_NE(aimed.RolloutAction(s, rng).kind, kMoveKind);
  // A declared cover is removed; a declared other obstacle is left standing.
  s.target = Vec3(1.2, 0.2, 0.8);
  s.objects[1].status = kDeclaredObstacle;
  EXPECT_EQ(clear.RolloutAction(s, rng).kind, RemoveKind(1));
}

TEST(ObstacleRewardTest, CoversOnlyPaysForTheObstacleThatHidesTheParticlesTarget) {
  World w = FourSidedWorld();
  w.objects.push_back(Object("cover", Vec3(1.2, 0.2, 0.85), Vec3(0.2, 0.2, 0.2), -3.0f));
  w.objects.push_back(Object("other", Vec3(1.2, -0.25, 0.85), Vec3(0.2, 0.2, 0.2), -3.0f));
  ObjectSearchModel model(std::make_shared<World>(w));
  Rng rng(3);
  State s = model.SampleInitialState(rng);
  s.target = Vec3(1.2, 0.2, 0.8);
  HybridAction declare_cover, declare_other;
  declare_cover.kind = DeclareObstacleKind(1);
  declare_other.kind = DeclareObstacleKind(2);
  // The paper's reward pays R_co for either.
  EXPECT_EQ(model.Step(s, declare_cover, rng).reward, w.params.r_co);
  EXPECT_EQ(model.Step(s, declare_other, rng).reward, w.params.r_co);
  model.SetObstacleReward(ObstacleReward::kCovers);
  EXPECT_EQ(model.Step(s, declare_cover, rng).reward, w.params.r_co);
  EXPECT_EQ(model.Step(s, declare_other, rng).reward, w.params.r_min);
}

TEST(NextBestViewTest, RemovesWhatWasDeclaredAndDeclaresAConfirmedTarget) {
  World w = FourSidedWorld();
  w.objects.push_back(Object("box", Vec3(1.0, 0.2, 0.8), Vec3(0.1, 0.1, 0.1), 0.0f));
  Rng rng(3);
  auto plan = [&](const World& world) {
    ObjectSearchModel model(std::make_shared<World>(world));
    NextBestView nbv(model, NextBestViewOptions{});
    nbv.SetBelief(ParticleBelief<State>::FromInitial(model, 50, rng));
    return nbv.Plan(Budget::Cpu(200), rng);
  };
  // Nothing is known of the box: look.
  auto look = plan(w);
  ASSERT_TRUE(look.status.ok()) << look.status.ToString();
  EXPECT_EQ(look.action.kind, kMoveKind);
  EXPECT_GT(look.value, 0.0);  // some view shows the guessed target
  // Every face confirmed as the target's: declare it; declared: remove it.
  World confirmed = w;
  confirmed.objects[1].odds.fill(3.0f);
  EXPECT_EQ(plan(confirmed).action.kind, DeclareTargetKind(1));
  World declared = confirmed;
  declared.objects[1].status = kDeclaredTarget;
  EXPECT_EQ(plan(declared).action.kind, RemoveKind(1));
  declared.objects[1].status = kDeclaredObstacle;
  EXPECT_EQ(plan(declared).action.kind, RemoveKind(1));
  // The robot could not remove it: not again.
  ASSERT_TRUE(ApplyDiscreteOutcome(&declared, 1, kRemoveOffset, false).ok());
  EXPECT_NE(plan(declared).action.kind, RemoveKind(1));
}

TEST(NextBestViewTest, ClearsTheBoxThatHoldsTheTargetsMassWhenNothingElseCanBeSeen) {
  World w = FourSidedWorld();
  // A large box over most of the table, confirmed as an obstacle on every face, and the grid
  // world's mass left only beneath it (everything around it seen empty).
  w.objects.push_back(Object("cover", Vec3(1.2, 0.0, 0.9), Vec3(0.6, 0.6, 0.3), -3.0f));
  for (int c = 0; c < w.grid.num_cells(); ++c) {
    const Vec3 p = w.grid.CellCenter(c);
    const bool under = std::abs(p.x() - 1.2) < 0.28 && std::abs(p.y()) < 0.28;
    w.grid.set_log_odds(c, under ? 2.0f : -8.0f);
  }
  w.grid.RebuildSampler();
  ObjectSearchModel model(std::make_shared<World>(w));
  NextBestView nbv(model, NextBestViewOptions{});
  Rng rng(5);
  nbv.SetBelief(ParticleBelief<State>::FromInitial(model, 100, rng));
  const auto d = nbv.Plan(Budget::Cpu(500), rng);
  ASSERT_TRUE(d.status.ok());
  EXPECT_EQ(d.action.kind, DeclareObstacleKind(1));
  // The rollout reference plays the model's rollout policy: the same declaration.
  RolloutPolicy rollout(model);
  rollout.SetBelief(ParticleBelief<State>::FromInitial(model, 100, rng));
  EXPECT_EQ(rollout.Plan(Budget::Cpu(10), rng).action.kind, DeclareObstacleKind(1));
}

}  // namespace
}  // namespace npfkct::object_search
