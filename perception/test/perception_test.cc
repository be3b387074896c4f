// Perception on frames rendered by the simulator, where the truth is known.
#include "npfkct/perception/perception.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <set>
#include <tuple>
#include <vector>

#include "npfkct/sim/frame_io.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::perception {
namespace {

using object_search::RobotConfig;
using object_search::Vec3;
using sim::Simulator;

sim::Scenario Load(const std::string& name) {
  auto s = sim::LoadScenario(std::string(NPFKCT_SCENARIO_DIR) + "/" + name + ".json").value();
  s.noise.pose_xy = 0.0;  // the tests place the robot exactly
  s.noise.pose_yaw = 0.0;
  return s;
}

RobotConfig Config(double x, double y, double yaw, double tilt = 0.45) {
  RobotConfig c;
  c.x = x;
  c.y = y;
  c.yaw = yaw;
  c.lift = 0.2;
  c.tilt = tilt;
  return c;
}

// Moves the simulated robot and returns the frame it renders, reported at `reported`.
SensorFrame Capture(Simulator* sim, const RobotConfig& truth, const RobotConfig& reported) {
  Rng rng(1);
  const auto world = sim->InitialWorld().value();
  EXPECT_FALSE(sim->ExecuteMove(truth, world.params, rng).illegal);
  const sim::Frame f = sim->Render(640, 480);
  SensorFrame frame;
  frame.cloud = sim::FrameCloud(f, /*world_frame=*/false);
  frame.image = sim::FrameBgr(f);
  frame.intrinsics = {f.width, f.height, f.fx, f.fy, f.cx, f.cy};
  frame.reported = reported;
  return frame;
}

// The frame of the view from the room's side of the table (0.4, 0), reported exactly.
SensorFrame FrontView(Simulator* sim) {
  const RobotConfig at = Config(0.4, 0.0, 0.0);
  return Capture(sim, at, at);
}

TargetModel TargetOf(const Simulator& sim) {
  return {sim::ObjectPhotos(sim.objects()[sim.target_index()])};
}

// The scene object whose box holds (or is nearest to) a detected box's center.
int SceneObjectOf(const Simulator& sim, const object_search::Box& box) {
  int best = -1;
  double best_d = 1e9;
  for (size_t i = 0; i < sim.objects().size(); ++i) {
    const double d = (sim.objects()[i].box.center - box.center).head<2>().norm();
    if (d < best_d) {
      best_d = d;
      best = static_cast<int>(i);
    }
  }
  return best;
}

TEST(PerceptionTest, IcpRecoversAKnownPoseOffset) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  // From here the table's front face, its top and the floor beyond constrain the pose.
  const RobotConfig truth = Config(0.05, 0.1, 0.05);
  RobotConfig reported = truth;
  reported.x += 0.06;
  reported.y -= 0.04;
  reported.yaw += 0.03;
  auto r = p.Process(Capture(&sim, truth, reported));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_NEAR(r->observation.achieved.x, truth.x, 0.015);
  EXPECT_NEAR(r->observation.achieved.y, truth.y, 0.015);
  EXPECT_NEAR(r->observation.achieved.yaw, truth.yaw, 0.01);
  EXPECT_LT(r->fitness, 1e-3);
}

TEST(PerceptionTest, RansacRescuesABadReportedPose) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  const RobotConfig truth = Config(0.05, 0.0, 0.0);
  RobotConfig reported = truth;
  reported.x += 0.3;
  reported.yaw -= 0.25;
  auto r = p.Process(Capture(&sim, truth, reported));
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->observation.achieved.x, truth.x, 0.03);
  EXPECT_NEAR(r->observation.achieved.yaw, truth.yaw, 0.03);
}

TEST(PerceptionTest, ClustersBoxesAndDetectsTheTarget) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  auto frame = FrontView(&sim);
  // The truth: scene objects with enough pixels in the rendered frame.
  const sim::Frame f = sim.Render(640, 480);
  std::map<int, int> pixels;
  for (int16_t id : f.ids) {
    if (id >= 0 && id < 1000) ++pixels[id];
  }
  std::set<int> visible;
  for (auto [id, n] : pixels) {
    if (n > 300) visible.insert(id);
  }
  auto r = p.Process(frame);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->observation.objects.size(), visible.size());
  std::set<int> found;
  for (const auto& d : r->observation.objects) {
    const int i = SceneObjectOf(sim, d.box);
    found.insert(i);
    const auto& truth = sim.objects()[i];
    EXPECT_LT((d.box.center - truth.box.center).head<2>().norm(), 0.06) << truth.name;
    EXPECT_NEAR(d.box.size.z(), truth.box.size.z(), 0.02) << truth.name;
    ASSERT_FALSE(d.faces.empty()) << truth.name;
    for (const auto& face : d.faces) {
      if (truth.target) {
        EXPECT_GT(face.score, 0.6) << "target face " << face.corner;
      } else {
        EXPECT_LT(face.score, 0.4) << truth.name;
      }
    }
    EXPECT_GT(d.moveability, 0.5);
  }
  EXPECT_EQ(found, visible);
}

// The robot's own detector: a box around the target's pixels scores the target's faces with the
// box's score, every other object in view gets unboxed_score; SIFT is not consulted (no photos).
TEST(PerceptionTest, TheRobotsDetectorBoxesScoreTheObjects) {
  Simulator sim(Load("loose1"), 1);
  PerceptionOptions options;
  Perception p(sim.InitialWorld().value(), TargetModel{}, options);
  SensorFrame frame = FrontView(&sim);
  frame.image = cv::Mat();  // depth only: the detector ran on the image
  const sim::Frame f = sim.Render(640, 480);
  cv::Rect target_pixels;
  for (int v = 0; v < f.height; ++v) {
    for (int u = 0; u < f.width; ++u) {
      if (f.ids[static_cast<size_t>(v) * f.width + u] == sim.target_index()) {
        target_pixels |= cv::Rect(u, v, 1, 1);
      }
    }
  }
  ASSERT_GT(target_pixels.area(), 100);
  frame.image_boxes =
      std::vector<ImageBox>{{1.0 * target_pixels.x, 1.0 * target_pixels.y,
                             1.0 * target_pixels.width, 1.0 * target_pixels.height, 0.9},
                            {0.0, 0.0, 20.0, 20.0, 0.8}};  // a box on nothing (the wall's corner)
  auto r = p.Process(frame);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_GE(r->observation.objects.size(), 2u);
  ASSERT_EQ(r->box_objects.size(), 2u);
  EXPECT_EQ(r->box_objects[1], "");
  bool saw_target = false;
  for (const auto& d : r->observation.objects) {
    const bool target = SceneObjectOf(sim, d.box) == sim.target_index();
    saw_target |= target;
    if (target) {
      EXPECT_EQ(r->box_objects[0], d.key);
    }
    ASSERT_FALSE(d.faces.empty());
    for (const auto& face : d.faces) {
      EXPECT_DOUBLE_EQ(face.score, target ? 0.9 : options.unboxed_score) << d.key;
    }
  }
  EXPECT_TRUE(saw_target);

  // No boxes at all: the detector saw no target, every object in view is probably not it.
  frame.image_boxes = std::vector<ImageBox>{};
  r = p.Process(frame);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->box_objects.empty());
  for (const auto& d : r->observation.objects) {
    for (const auto& face : d.faces) EXPECT_DOUBLE_EQ(face.score, options.unboxed_score);
  }

  // Boxes outside the image, NaN or too many are refused naming the box and its field.
  const std::vector<std::pair<ImageBox, std::string>> bad = {
      {{630, 10, 20, 10, 0.5}, "imageBoxes[0].x"},
      {{10, 10, 20, 480, 0.5}, "imageBoxes[0].y"},
      {{10, 10, std::nan(""), 10, 0.5}, "imageBoxes[0].width"},
      {{10, 10, 20, 10, std::nan("")}, "imageBoxes[0].score"},
      {{10, 10, 20, -1, 0.5}, "imageBoxes[0].height"},
  };
  for (const auto& [box, field] : bad) {
    frame.image_boxes = std::vector<ImageBox>{box};
    auto refused = p.Process(frame);
    EXPECT_EQ(refused.status().code(), StatusCode::kInvalidArgument) << field;
    EXPECT_EQ(refused.status().message().rfind(field, 0), 0u) << refused.status().message();
  }
  frame.image_boxes = std::vector<ImageBox>(options.max_image_boxes + 1, {10, 10, 5, 5, 0.5});
  EXPECT_EQ(p.Process(frame).status().message().rfind("imageBoxes:", 0), 0u);
}

TEST(PerceptionTest, BoxesConvergeAndIdsStayWhenTheRobotMoves) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  const RobotConfig front = Config(0.4, 0.0, 0.0);
  const RobotConfig side = Config(1.6, -1.05, std::numbers::pi / 2);
  auto a = p.Process(Capture(&sim, front, front));
  ASSERT_TRUE(a.ok());
  auto b = p.Process(Capture(&sim, side, side));
  ASSERT_TRUE(b.ok());
  std::map<int, std::string> id_of;
  for (const auto& d : a->observation.objects) id_of[SceneObjectOf(sim, d.box)] = d.key;
  int common = 0;
  for (const auto& d : b->observation.objects) {
    const int i = SceneObjectOf(sim, d.box);
    if (!id_of.count(i)) continue;
    ++common;
    EXPECT_EQ(d.key, id_of[i]) << sim.objects()[i].name;
    // Seen from two sides, the box's horizontal extents match the object's.
    const auto& truth = sim.objects()[i].box;
    const double big = std::max(truth.size.x(), truth.size.y());
    const double small = std::min(truth.size.x(), truth.size.y());
    EXPECT_NEAR(std::max(d.box.size.x(), d.box.size.y()), big, 0.03) << sim.objects()[i].name;
    EXPECT_NEAR(std::min(d.box.size.x(), d.box.size.y()), small, 0.03) << sim.objects()[i].name;
    // Yaw, modulo the box's quarter-turn symmetry.
    const double dyaw = std::remainder(d.box.yaw - truth.yaw, std::numbers::pi / 2);
    EXPECT_LT(std::abs(dyaw), 0.12) << sim.objects()[i].name;
  }
  EXPECT_GE(common, 2);
  EXPECT_EQ(p.tracks(), static_cast<int>(sim.objects().size()));
}

TEST(PerceptionTest, SavedTracksRestoreIntoAFreshPipelineAndDroppedOnesAreForgotten) {
  Simulator sim(Load("loose1"), 1);
  const auto world = sim.InitialWorld().value();
  Perception first(world, TargetOf(sim), {});
  const RobotConfig front = Config(0.4, 0.0, 0.0);
  auto a = first.Process(Capture(&sim, front, front));
  ASSERT_TRUE(a.ok());
  ASSERT_GE(a->observation.objects.size(), 2u);
  int next_id = -1;
  const std::vector<TrackState> saved = first.SaveTracks(&next_id);
  EXPECT_EQ(next_id, first.tracks());

  // A restarted server: a fresh pipeline with the saved tracks gives the same ids.
  Perception second(world, TargetOf(sim), {});
  ASSERT_TRUE(second.RestoreTracks(saved, next_id).ok());
  const std::string dropped = a->observation.objects[0].key;
  EXPECT_TRUE(second.DropTrack(dropped));
  EXPECT_FALSE(second.DropTrack(dropped));
  auto b = second.Process(Capture(&sim, front, front));
  ASSERT_TRUE(b.ok());
  std::set<std::string> keys;
  for (const auto& d : b->observation.objects) keys.insert(d.key);
  for (size_t i = 1; i < a->observation.objects.size(); ++i) {
    EXPECT_TRUE(keys.count(a->observation.objects[i].key)) << a->observation.objects[i].key;
  }
  // The object of the dropped track (still in view here) comes back under a new id.
  EXPECT_FALSE(keys.count(dropped));
  EXPECT_EQ(keys.size(), a->observation.objects.size());

  std::vector<TrackState> bad = saved;
  bad[0].points.pop_back();
  EXPECT_FALSE(second.RestoreTracks(bad, next_id).ok());
  bad = saved;
  bad[0].surface = 99;
  EXPECT_FALSE(second.RestoreTracks(bad, next_id).ok());
}

TEST(PerceptionTest, SiftMatchesTheTargetAndRejectsLookAlikes) {
  Simulator sim(Load("loose1"), 1);
  sim::SceneObject target = sim.objects()[sim.target_index()];
  Perception p(sim.InitialWorld().value(), {sim::ObjectPhotos(target)}, {});
  // A view of the target's face, smaller and blurred: still the target.
  cv::Mat face = sim::ObjectPhotos(target, 300)[1], view;
  cv::resize(face, view, cv::Size(), 0.6, 0.6);
  cv::GaussianBlur(view, view, cv::Size(3, 3), 0.8);
  bool colour = true;
  EXPECT_GT(p.TargetScore(view, &colour), 0.8);
  EXPECT_FALSE(colour);
  // The same colours printed in another pattern: a look-alike.
  sim::SceneObject fake = target;
  fake.texture_seed = 777;
  EXPECT_LT(p.TargetScore(sim::ObjectPhotos(fake, 300)[1], &colour), 0.3);
  EXPECT_FALSE(colour);
  // A plain box: too few features, the colour decides (blue target photos, red box).
  cv::Mat red(120, 120, CV_8UC3, cv::Scalar(40, 50, 200));
  EXPECT_LT(p.TargetScore(red, &colour), 0.4);
  EXPECT_TRUE(colour);
}

TEST(PerceptionTest, LargePhotosAreScaledDownAndStillMatch) {
  // Photos 1,600 pixels wide are scaled down to options.max_sift_pixels before SIFT (its pyramid
  // of a 4-megapixel photo takes about a gigabyte); the target is still recognised (unscaled,
  // these photos gave the same view 0.18).
  Simulator sim(Load("loose1"), 1);
  sim::SceneObject target = sim.objects()[sim.target_index()];
  Perception p(sim.InitialWorld().value(), {sim::ObjectPhotos(target, 1600)}, {});
  cv::Mat face = sim::ObjectPhotos(target, 300)[1], view;
  cv::resize(face, view, cv::Size(), 0.6, 0.6);
  bool colour = true;
  EXPECT_GT(p.TargetScore(view, &colour), 0.8);
  EXPECT_FALSE(colour);
}

TEST(PerceptionTest, BadFramesGetClearErrorsAndChangeNothing) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  SensorFrame good = FrontView(&sim);
  SensorFrame empty = good;
  empty.cloud = pcl::make_shared<Cloud>();
  EXPECT_NE(p.Process(empty).status().message().find("pointCloud.data: the cloud is empty"),
            std::string::npos);
  auto nan_cloud = pcl::make_shared<Cloud>(*good.cloud);
  (*nan_cloud)[10].x = std::nanf("");
  SensorFrame nan = good;
  nan.cloud = nan_cloud;
  EXPECT_NE(p.Process(nan).status().message().find("point 10 is not finite"), std::string::npos);
  // A map-frame cloud sent as a camera-frame one: many points "behind" the camera.
  SensorFrame wrong = good;
  auto map_cloud = pcl::make_shared<Cloud>();
  for (const auto& q : *good.cloud) {
    auto w = q;
    w.z = -q.z;
    map_cloud->push_back(w);
  }
  wrong.cloud = map_cloud;
  EXPECT_NE(p.Process(wrong).status().message().find("pointCloud.frame"), std::string::npos);
  // The real map-frame cloud of the same view.
  SensorFrame in_map = good;
  in_map.cloud = sim::FrameCloud(sim.Render(640, 480), /*world_frame=*/true);
  EXPECT_NE(p.Process(in_map).status().message().find("pointCloud.frame"), std::string::npos);
  // Points in front of the camera but outside its field of view.
  SensorFrame wide = good;
  auto wide_cloud = pcl::make_shared<Cloud>(*good.cloud);
  for (auto& q : *wide_cloud) q.x = 3.0f * q.z;
  wide.cloud = wide_cloud;
  EXPECT_NE(p.Process(wide).status().message().find("field of view"), std::string::npos);
  // Declared as a map-frame cloud, it is fine.
  in_map.cloud_in_map_frame = true;
  Perception q(sim.InitialWorld().value(), TargetOf(sim), {});
  EXPECT_TRUE(q.Process(in_map).ok());
  SensorFrame small = good;
  cv::resize(good.image, small.image, cv::Size(320, 240));
  EXPECT_NE(p.Process(small).status().message().find("image.data: the image is 320x240"),
            std::string::npos);
  EXPECT_EQ(p.tracks(), 0);
  EXPECT_TRUE(p.Process(good).ok());
  EXPECT_GT(p.tracks(), 0);
}

TEST(PerceptionTest, HugeFiniteCoordinatesAndTooManyPointsAreRefusedBeforePcl) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  const SensorFrame good = Capture(&sim, Config(0.05, 0.0, 0.0), Config(0.05, 0.0, 0.0));
  // Three camera-frame points at depth 3e38 (once a SIGABRT inside PCL), and map-frame points at
  // 1e37: finite, so only the coordinate bound stops them.
  for (const bool in_map : {false, true}) {
    SensorFrame far = good;
    auto cloud = pcl::make_shared<Cloud>(*good.cloud);
    for (int i = 0; i < 3; ++i) (*cloud)[i].z = in_map ? 1e37f : 3e38f;
    far.cloud = cloud;
    far.cloud_in_map_frame = in_map;
    auto r = p.Process(far);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("point 0 has a coordinate beyond 10000 m"),
              std::string::npos)
        << r.status().message();
  }
  PerceptionOptions few;
  few.max_points = 100;
  Perception q(sim.InitialWorld().value(), TargetOf(sim), few);
  EXPECT_NE(q.Process(good).status().message().find("more than 100 points"), std::string::npos);
  EXPECT_EQ(p.tracks(), 0);
  EXPECT_TRUE(p.Process(good).ok());
}

TEST(PerceptionTest, PointsFarAwayChangeNothingNearby) {
  // A map-frame view with a dense blob above the table, sent with and without three points
  // 9,999 m away. PCL's voxel grid cannot number the voxels of so wide a cloud and used to leave
  // it unfiltered: the blob's 20,000 points became an object of their own (a cluster the frame
  // without far points never has) and the frame took 45 s instead of 0.4 s.
  Simulator sim(Load("loose1"), 1);
  SensorFrame near = FrontView(&sim);
  auto blob = sim::FrameCloud(sim.Render(640, 480), /*world_frame=*/true);
  Rng rng(3);
  for (int i = 0; i < 20000; ++i) {
    pcl::PointXYZRGB q;
    q.x = 1.2f + 0.001f * static_cast<float>(rng.Uniform());
    q.y = -0.3f + 0.001f * static_cast<float>(rng.Uniform());
    q.z = 0.8f + 0.001f * static_cast<float>(rng.Uniform());
    blob->push_back(q);
  }
  near.cloud = blob;
  near.cloud_in_map_frame = true;
  SensorFrame far = near;
  auto wide = pcl::make_shared<Cloud>(*blob);
  for (const auto& [x, y, z] :
       {std::tuple{9999.0f, 9999.0f, 9999.0f}, std::tuple{-9999.0f, 9999.0f, 0.5f},
        std::tuple{0.001f, -9999.0f, 9999.0f}}) {
    pcl::PointXYZRGB q;
    q.x = x;
    q.y = y;
    q.z = z;
    wide->push_back(q);
  }
  far.cloud = wide;
  const auto world = sim.InitialWorld().value();
  Perception without(world, TargetOf(sim), {}), with(world, TargetOf(sim), {});
  const PerceptionResult a = without.Process(near).value();
  const PerceptionResult b = with.Process(far).value();
  EXPECT_GT(a.clusters, 0);
  EXPECT_EQ(a.clusters, b.clusters);
  auto centers = [](const PerceptionResult& r) {
    std::vector<std::array<double, 3>> c;
    for (const auto& d : r.observation.objects) {
      c.push_back({d.box.center.x(), d.box.center.y(), d.box.center.z()});
    }
    std::sort(c.begin(), c.end());
    return c;
  };
  const auto ca = centers(a), cb = centers(b);
  ASSERT_EQ(ca.size(), cb.size());
  for (size_t i = 0; i < ca.size(); ++i) {
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(ca[i][k], cb[i][k], 1e-4) << i;
  }
}

// A map-frame frame of the given points, the robot reported at the room's centre.
SensorFrame MapFrame(Cloud::Ptr cloud) {
  SensorFrame frame;
  frame.cloud = std::move(cloud);
  frame.cloud_in_map_frame = true;
  frame.intrinsics = {640, 480, 500.0, 500.0, 320.0, 240.0};
  frame.reported = Config(0.3, 0.0, 0.0);
  return frame;
}

void AddPoint(Cloud* cloud, double x, double y, double z) {
  pcl::PointXYZRGB q;
  q.x = static_cast<float>(x);
  q.y = static_cast<float>(y);
  q.z = static_cast<float>(z);
  cloud->push_back(q);
}

// The surface of a 0.6 m cube off loose1's table, which the map does not hold (ICP fits it badly
// and RANSAC runs), 20,000 points less a small hole.
pcl::shared_ptr<Cloud> CubeOffTheTable() {
  auto cloud = pcl::make_shared<Cloud>();
  Rng rng(1);
  for (int i = 0; i < 20000; ++i) {
    const double u = rng.Uniform(-0.3, 0.3), v = rng.Uniform(-0.3, 0.3);
    const int64_t face = rng.UniformInt(6);
    const double a = face % 2 == 1 ? 0.3 : -0.3;
    const Vec3 l = face / 2 == 0 ? Vec3(a, u, v) : face / 2 == 1 ? Vec3(u, a, v) : Vec3(u, v, a);
    const Vec3 q(l.x(), -1.5 + l.y(), 0.6 + l.z());
    if (std::abs(q.x()) < 0.06 && q.y() > -1.53 && q.y() < -1.44 && q.z() > 0.87) continue;
    AddPoint(cloud.get(), q.x(), q.y(), q.z());
  }
  return cloud;
}

// A refinement of RANSAC's alignment that moved the camera more than max_correction used to
// replace ICP's own correction, be thrown away (the pose fell back to the reported one) and be
// reported as used (RANSAC_ICP). Used now means kept: the correction is the refinement, within
// max_correction. The cube frames below do not reach the far case in this pose (the hostile
// suite's version of the denormal frame does, test_hostile.py); here it is an invariant.
void ExpectRansacUsedOnlyWhereKept(const PerceptionResult& r) {
  const double moved = r.correction.block<3, 1>(0, 3).norm();
  EXPECT_LE(moved, PerceptionOptions{}.max_correction);
  if (r.used_ransac) {
    EXPECT_GT(moved, 0.0);
  }
}

TEST(PerceptionTest, ARansacRefinementIsKeptOnlyWhereItIsPlausible) {
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  auto r = p.Process(MapFrame(CubeOffTheTable()));
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_GT(r->fitness, 0.0);
  ExpectRansacUsedOnlyWhereKept(*r);
}

TEST(PerceptionTest, FeaturesOfPointsADenormalApartAreDropped) {
  // The cube off the table (RANSAC runs) with two points 2e-20 m apart on either side of a RANSAC
  // voxel boundary, alone in their voxels. PCL weights an FPFH neighbour by 1 / squared distance,
  // inf here: the feature was NaN, and the consensus' feature k-d tree asserted and aborted the
  // process.
  Simulator sim(Load("loose1"), 1);
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  auto cloud = CubeOffTheTable();
  AddPoint(cloud.get(), 1e-20, -1.485, 0.915);
  AddPoint(cloud.get(), -1e-20, -1.485, 0.915);
  auto r = p.Process(MapFrame(cloud));
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_GT(r->fitness, 0.0);
  ExpectRansacUsedOnlyWhereKept(*r);
}

TEST(PerceptionTest, FramesWithMoreClustersThanASessionKnowsAreRefusedFirst) {
  // 8 x 8 blocks of 50 points on the table, 12 cm and 10 cm apart: 64 clusters.
  Simulator sim(Load("loose1"), 1);
  auto cloud = pcl::make_shared<Cloud>();
  for (int i = 0; i < 8; ++i) {
    for (int j = 0; j < 8; ++j) {
      for (int k = 0; k < 50; ++k) {
        AddPoint(cloud.get(), 1.105 + 0.12 * i + 0.01 * (k % 5),
                 -0.345 + 0.1 * j + 0.01 * (k / 5 % 5), 0.785 + 0.01 * (k / 25));
      }
    }
  }
  Perception p(sim.InitialWorld().value(), TargetOf(sim), {});
  auto r = p.Process(MapFrame(cloud));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(
      r.status().message().find("pointCloud.data: 64 object clusters in one frame; at most 63"),
      std::string::npos)
      << r.status().message();
  EXPECT_EQ(p.tracks(), 0);
  PerceptionOptions more;
  more.max_clusters = 64;
  Perception q(sim.InitialWorld().value(), TargetOf(sim), more);
  r = q.Process(MapFrame(cloud));
  ASSERT_TRUE(r.ok()) << r.status().message();
  EXPECT_EQ(r->clusters, 64);
  EXPECT_EQ(q.tracks(), 64);
}

TEST(PerceptionTest, TracksAreThinnedToTheirBound) {
  Simulator sim(Load("loose1"), 1);
  const SensorFrame frame = FrontView(&sim);
  auto largest = [&](const PerceptionOptions& options) {
    Perception p(sim.InitialWorld().value(), TargetOf(sim), options);
    EXPECT_TRUE(p.Process(frame).ok());
    int next = 0;
    size_t most = 0;
    for (const TrackState& t : p.SaveTracks(&next)) most = std::max(most, t.points.size() / 3);
    return most;
  };
  PerceptionOptions few;
  few.max_track_points = 100;
  EXPECT_GT(largest({}), 100u);
  EXPECT_LE(largest(few), 100u);
  EXPECT_GT(largest(few), 20u);
}

TEST(PerceptionTest, AllTracksTogetherAreThinnedToTheirBound) {
  Simulator sim(Load("loose1"), 1);
  const SensorFrame frame = FrontView(&sim);
  auto held = [&](const PerceptionOptions& options) {
    Perception p(sim.InitialWorld().value(), TargetOf(sim), options);
    EXPECT_TRUE(p.Process(frame).ok());
    int next = 0;
    size_t total = 0, tracks = 0;
    for (const TrackState& t : p.SaveTracks(&next)) {
      total += t.points.size() / 3;
      ++tracks;
    }
    EXPECT_GE(tracks, 3u);
    return total;
  };
  PerceptionOptions few;
  few.max_total_track_points = 300;
  EXPECT_GT(held({}), 300u);
  EXPECT_LE(held(few), 300u);
  EXPECT_GT(held(few), 60u);
}

TEST(PerceptionTest, SiftStopsAtItsBudgetAndColourStillScores) {
  Simulator sim(Load("loose1"), 1);
  const SensorFrame frame = FrontView(&sim);
  // The mean face score of the target's detection.
  auto target_score = [&](const PerceptionOptions& options) {
    Perception p(sim.InitialWorld().value(), TargetOf(sim), options);
    auto r = p.Process(frame);
    EXPECT_TRUE(r.ok());
    double score = -1.0;
    for (const auto& d : r->observation.objects) {
      if (!sim.objects()[SceneObjectOf(sim, d.box)].target || d.faces.empty()) continue;
      score = 0.0;
      for (const auto& face : d.faces) score += face.score / static_cast<double>(d.faces.size());
    }
    return score;
  };
  PerceptionOptions no_pairs, no_pixels, small_regions;
  no_pairs.max_sift_pairs = 0;
  no_pixels.max_sift_frame_pixels = 0;
  small_regions.max_sift_pixels = 400;
  const double full = target_score({});
  EXPECT_GT(full, 0.6);
  // Colour alone gives at most sigmoid(0.5).
  EXPECT_LT(target_score(no_pairs), 0.63);
  EXPECT_LT(target_score(no_pixels), 0.63);
  EXPECT_GT(target_score(no_pixels), 0.05);
  const double small = target_score(small_regions);
  EXPECT_GE(small, 0.05);
  EXPECT_LE(small, 0.95);
}

TEST(PerceptionTest, PriorMapPointsBoundsTheMapBeforeItIsBuilt) {
  Simulator sim(Load("loose1"), 1);
  const auto world = sim.InitialWorld().value();
  const int64_t estimate = PriorMapPoints(world, {});
  Perception p(world, TargetOf(sim), {});
  EXPECT_EQ(p.map_tiles(), 0);  // nothing is built before a frame needs it
  ASSERT_TRUE(p.Process(FrontView(&sim)).ok());
  EXPECT_GT(p.map()->size(), 0u);
  EXPECT_GE(estimate, static_cast<int64_t>(p.map()->size()));
  EXPECT_LT(estimate, 4'000'000);  // the scenarios fit the documented limit
  // A 200 m room costs no more than the largest square a frame can need.
  auto big = world;
  big.occupancy = object_search::OccupancyMap({-100, -100}, {100, 100}, 1.0);
  auto wide = world;
  wide.occupancy = object_search::OccupancyMap({-30, -30}, {30, 30}, 1.0);
  EXPECT_EQ(PriorMapPoints(big, {}), PriorMapPoints(wide, {}));
  EXPECT_LT(PriorMapPoints(big, {}), 4'000'000);
  // A box is counted up to that square's diagonal (about 26 m): a 200 m wall 2 m high adds the
  // points of 26 m of it (4.2 million), not of all of it (33 million).
  auto walled = world;
  walled.furniture.push_back({object_search::Vec3(0, 0, 1), 0.0, object_search::Vec3(200, 0.1, 2)});
  const int64_t wall = PriorMapPoints(walled, {}) - PriorMapPoints(world, {});
  EXPECT_GT(wall, 4'000'000);
  EXPECT_LT(wall, 5'000'000);
}

TEST(PerceptionTest, AHouseSizedRoomCostsWhatTheCameraSees) {
  // The same frame in Loose1 and in Loose1 grown to a 40 m x 40 m house: the same objects, and
  // only the tiles of the prior map around the view are built (a whole-room map was 4 million
  // floor points and 7 s of CPU before the first frame).
  Simulator sim(Load("loose1"), 1);
  const auto world = sim.InitialWorld().value();
  auto house = world;
  house.occupancy = object_search::OccupancyMap({-20, -20}, {20, 20}, 0.05);
  const SensorFrame frame = FrontView(&sim);
  Perception room(world, TargetOf(sim), {}), grown(house, TargetOf(sim), {});
  const PerceptionResult a = room.Process(frame).value();
  const PerceptionResult b = grown.Process(frame).value();
  EXPECT_GT(a.clusters, 0);
  EXPECT_EQ(a.clusters, b.clusters);
  ASSERT_EQ(a.observation.objects.size(), b.observation.objects.size());
  for (size_t i = 0; i < a.observation.objects.size(); ++i) {
    EXPECT_LT((a.observation.objects[i].box.center - b.observation.objects[i].box.center).norm(),
              0.01);
  }
  // At most the tiles of a registration reach (2 m tiles; 400 in the house).
  EXPECT_LE(grown.map_tiles(), 64);
  EXPECT_LT(grown.map()->size(), 2'000'000u);
  // A bound on the tiles kept: past it the least recently used go, the frame's own stay.
  PerceptionOptions small;
  small.max_map_points = 1;
  Perception bounded(house, TargetOf(sim), small);
  ASSERT_TRUE(bounded.Process(frame).ok());
  const int64_t needed = bounded.map_tiles();
  EXPECT_GT(needed, 0);
  SensorFrame elsewhere = frame;
  elsewhere.reported.x += 8.0;  // a view of the empty floor 8 m away
  ASSERT_TRUE(bounded.Process(elsewhere).ok());
  ASSERT_TRUE(bounded.Process(frame).ok());
  EXPECT_EQ(bounded.map_tiles(), needed);
}

}  // namespace
}  // namespace npfkct::perception
