#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "npfkct/render/belief_picture.h"

namespace npfkct::render {
namespace {

using object_search::Box;
using object_search::PriorMap;
using object_search::RobotConfig;
using object_search::Vec2;
using object_search::Vec3;
using object_search::World;

// A 7 x 6 m room with one 1.2 x 0.8 m table (rotated by `yaw`) 1.6 m ahead of the robot.
World TableWorld(double yaw = 0.0) {
  PriorMap prior;
  prior.room_min = Vec2(-3, -3);
  prior.room_max = Vec2(4, 3);
  prior.furniture.push_back({"table", {Vec3(1.6, 0, 0.375), yaw, Vec3(1.2, 0.8, 0.75)}, true});
  prior.base_regions.push_back({Vec2(-0.5, -0.5), Vec2(0.5, 0.5)});
  auto w = object_search::BuildWorld(prior);
  EXPECT_TRUE(w.ok()) << w.status().ToString();
  return *std::move(w);
}

// Pixels within `tolerance` (per channel) of `color`.
int CountNear(const cv::Mat& img, const cv::Vec3b& color, int tolerance) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b& c = img.at<cv::Vec3b>(y, x);
      n += std::abs(c[0] - color[0]) <= tolerance && std::abs(c[1] - color[1]) <= tolerance &&
           std::abs(c[2] - color[2]) <= tolerance;
    }
  }
  return n;
}

int CountColor(const cv::Mat& img, const cv::Vec3b& color) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y) {
    for (int x = 0; x < img.cols; ++x) n += img.at<cv::Vec3b>(y, x) == color;
  }
  return n;
}

TEST(ColorMap, GoesFromPaleThroughOrangeToDarkRed) {
  const auto& stops = ColorStops();
  ASSERT_GE(stops.size(), 3u);
  EXPECT_EQ(ProbabilityColor(0.0), cv::Vec3b(stops.front().b, stops.front().g, stops.front().r));
  EXPECT_EQ(ProbabilityColor(1.0), cv::Vec3b(stops.back().b, stops.back().g, stops.back().r));
  EXPECT_EQ(ProbabilityColor(-1.0), ProbabilityColor(0.0));
  EXPECT_EQ(ProbabilityColor(std::nan("")), ProbabilityColor(0.0));
  // Darker (smaller sum) as the probability grows: a person reads dark as likely.
  int previous = 1000;
  for (double p = 0.0; p <= 1.0; p += 0.05) {
    const cv::Vec3b c = ProbabilityColor(p);
    const int sum = c[0] + c[1] + c[2];
    EXPECT_LE(sum, previous) << p;
    previous = sum;
  }
}

TEST(Frustum, LiesAheadOfTheCameraBetweenNearAndFar) {
  const World world = TableWorld();
  RobotConfig c;
  c.yaw = 0.5;
  const auto hull = FrustumFootprint(world, c);
  ASSERT_GE(hull.size(), 4u);
  const Vec2 heading(std::cos(c.yaw), std::sin(c.yaw));
  double area = 0.0;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Vec2 &a = hull[i], &b = hull[(i + 1) % hull.size()];
    area += a.x() * b.y() - a.y() * b.x();
    EXPECT_GT(a.dot(heading), 0.0);  // ahead of the robot
    // The far plane's corners: far * sqrt(1 + tan^2 h + tan^2 v) from the camera.
    const double th = world.camera.TanHalfHorizontal(), tv = world.camera.TanHalfVertical();
    EXPECT_LT(a.norm(), world.camera.far * std::sqrt(1 + th * th + tv * tv) + 0.2);
  }
  EXPECT_GT(area, 0.0);  // counter-clockwise
  // A point 1.1 m straight ahead is inside.
  const Vec2 probe = 1.1 * heading + Vec2(world.robot.chain.front().xyz.x(), 0);
  bool inside = true;
  for (size_t i = 0; i < hull.size(); ++i) {
    const Vec2 e = hull[(i + 1) % hull.size()] - hull[i], q = probe - hull[i];
    inside &= e.x() * q.y() - e.y() * q.x() >= 0.0;
  }
  EXPECT_TRUE(inside);
}

TEST(Crop, IsTheWorkspacesAndTheRobotNotTheRoom) {
  const World world = TableWorld();
  const auto [lo, hi] = CropBounds(world, std::nullopt, 0.3);
  EXPECT_LE(lo.x(), -0.3 - 0.29);  // the robot's footprint at the origin
  EXPECT_GE(hi.x(), 2.2 + 0.29);   // the table's far edge
  EXPECT_LE(lo.y(), -0.4);
  EXPECT_LT((hi - lo).prod(), 0.4 * 7 * 6);  // a small part of the room
  RobotConfig far;
  far.x = 3.9;
  far.y = 2.9;
  const auto [lo2, hi2] = CropBounds(world, far, 0.3);
  EXPECT_DOUBLE_EQ(hi2.x(), 4.0);  // clipped to the room
  EXPECT_DOUBLE_EQ(hi2.y(), 3.0);
  EXPECT_DOUBLE_EQ(lo2.x(), lo.x());
}

TEST(Picture, HeatMapFillsTheMapAndCellsLandWhereTheyAre) {
  for (double yaw : {0.0, 0.7}) {
    World world = TableWorld(yaw);
    world.robot_config.yaw = M_PI;  // looking away: no frustum over the table
    // One 2 cm cell of the table's (+x, +y) corner is certain; the rest stays unseen (0.5).
    const int nx = world.grid.cells_x(0), ny = world.grid.cells_y(0);
    for (int iy = ny - 5; iy < ny; ++iy) {
      for (int ix = nx - 5; ix < nx; ++ix) world.grid.set_log_odds(world.grid.Index(0, ix, iy), 6);
    }
    BeliefPictureOptions options;
    options.title = "session test - step 0";
    options.map_pixels = 600;
    const cv::Mat img = RenderBelief(world, options);
    ASSERT_EQ(img.type(), CV_8UC3);
    const auto [lo, hi] = CropBounds(world, std::nullopt, options.margin);
    const double ppm = 600.0 / std::max(hi.x() - lo.x(), hi.y() - lo.y());
    // The table top (1.2 x 0.8 m) in "not seen" colour: its share of the map panel.
    const double table_px = 1.2 * 0.8 * ppm * ppm;
    const int unseen = CountColor(img, ProbabilityColor(0.5));
    EXPECT_GT(unseen, 0.8 * table_px) << "yaw " << yaw;
    EXPECT_LT((hi - lo).prod(), 0.2 * 7 * 6);  // the table and the robot, not the room
    // The certain corner cells are drawn at the table's (+x, +y) corner, rotated with it.
    const Vec3 corner = world.grid.CellCenter(world.grid.Index(0, nx - 3, ny - 3));
    const int title_height = 38;
    const cv::Point at(cvRound((corner.x() - lo.x()) * ppm),
                       title_height + cvRound((hi.y() - corner.y()) * ppm));
    EXPECT_EQ(img.at<cv::Vec3b>(at), ProbabilityColor(1.0 / (1.0 + std::exp(-6.0))))
        << "yaw " << yaw;
  }
}

// Base regions reaching 10 km past a small room: their outlines are drawn where they cross the
// picture, dash by dash only there (drawing 64 such outlines dash by dash took 32 s of CPU).
TEST(Picture, DrawsTheVisiblePartOfOutlinesFarLargerThanThePicture) {
  World world = TableWorld();
  world.robot_config.yaw = M_PI;
  BeliefPictureOptions options;
  options.map_pixels = 600;
  const cv::Mat plain = RenderBelief(world, options);
  world.base_regions.clear();
  for (int i = 0; i < 64; ++i) world.base_regions.push_back({Vec2(-0.2, -0.1), Vec2(1e4, 1e4)});
  const cv::Mat drawn = RenderBelief(world, options);
  ASSERT_EQ(drawn.size(), plain.size());
  const auto [lo, hi] = CropBounds(world, std::nullopt, options.margin);
  const double ppm = 600.0 / std::max(hi.x() - lo.x(), hi.y() - lo.y());
  const int title_height = 38;
  // Changed pixels along the left edge (x = -0.2, inside the crop) and the bottom edge
  // (y = -0.1) up to the picture's right side.
  auto changed_near = [&](double x, double y) {
    const cv::Point at(cvRound((x - lo.x()) * ppm), title_height + cvRound((hi.y() - y) * ppm));
    int n = 0;
    for (int dy = -3; dy <= 3; ++dy) {
      for (int dx = -12; dx <= 12; ++dx) {
        const cv::Point p = at + cv::Point(dx, dy);
        if (p.x >= 0 && p.y >= 0 && p.x < drawn.cols && p.y < drawn.rows) {
          n += drawn.at<cv::Vec3b>(p) != plain.at<cv::Vec3b>(p);
        }
      }
    }
    return n;
  };
  EXPECT_GT(changed_near(-0.2, 0.3 * lo.y() + 0.7 * hi.y()), 0);
  EXPECT_GT(changed_near(hi.x() - 0.1, -0.1), 0);
}

TEST(Picture, StaysWithinThePixelBudget) {
  const World world = TableWorld();
  BeliefPictureOptions options;
  options.max_pixels = 300'000;
  options.map_pixels = 4000;
  const cv::Mat img = RenderBelief(world, options);
  EXPECT_LE(static_cast<int64_t>(img.total()), options.max_pixels);
  EXPECT_GT(img.cols, 330);
}

TEST(Picture, ShowsTheColourBarAndTheNextView) {
  World world = TableWorld();
  object_search::ObjectKnowledge cup;
  cup.key = "cup";
  cup.box = Box{Vec3(1.5, 0.1, 0.8), 0.0, Vec3(0.1, 0.1, 0.1)};
  cup.odds.fill(3.0f);
  world.objects.push_back(cup);
  BeliefPictureOptions options;
  RobotConfig next;
  next.x = 0.3;
  next.y = 0.3;
  options.next_view = next;
  const cv::Mat with = RenderBelief(world, options);
  options.next_view.reset();
  const cv::Mat without = RenderBelief(world, options);
  // The colour bar holds the whole colour map, dark end included.
  EXPECT_GT(CountNear(with, ProbabilityColor(1.0), 4), 10);
  EXPECT_GT(CountNear(with, ProbabilityColor(0.0), 2), 10);
  // The next view is drawn in its own colour (purple: BGR 150, 40, 150).
  EXPECT_GT(CountColor(with, cv::Vec3b(150, 40, 150)),
            CountColor(without, cv::Vec3b(150, 40, 150)));
  // The object's face odds are drawn in their colour at its corners.
  EXPECT_GT(CountColor(with, ProbabilityColor(1.0 / (1.0 + std::exp(-3.0)))), 20);
}

// A box's interior is hatched (not seen, not "likely"), the table around it keeps the heat map's
// colour, and the map's top edge carries tick marks of the map frame's metres.
TEST(Picture, HatchesBoxInteriorsAndMarksTheAxes) {
  World world = TableWorld();
  world.robot_config.yaw = M_PI;  // looking away: the table stays unseen (0.5)
  object_search::ObjectKnowledge box;
  box.key = "box";
  box.box = Box{Vec3(1.6, 0.0, 0.85), 0.0, Vec3(0.4, 0.4, 0.2)};
  world.objects.push_back(box);
  BeliefPictureOptions options;
  options.map_pixels = 600;
  const cv::Mat img = RenderBelief(world, options);
  const auto [lo, hi] = CropBounds(world, std::nullopt, options.margin);
  const double ppm = 600.0 / std::max(hi.x() - lo.x(), hi.y() - lo.y());
  const int title_height = 38;
  auto px = [&](double x, double y) {
    return cv::Point(cvRound((x - lo.x()) * ppm), title_height + cvRound((hi.y() - y) * ppm));
  };
  const cv::Vec3b unseen = ProbabilityColor(0.5);
  // Inside the box (its middle 0.3 x 0.3 m): no pixel of the unseen colour; hatch lines there.
  const cv::Rect inside(px(1.45, 0.15), px(1.75, -0.15));
  EXPECT_EQ(CountColor(img(inside), unseen), 0);
  EXPECT_GT(CountNear(img(inside), cv::Vec3b(110, 110, 110), 30), 10);
  // Beside it on the table: the unseen colour.
  const cv::Rect beside(px(1.05, 0.35), px(1.3, 0.2));
  EXPECT_GT(CountColor(img(beside), unseen), beside.area() / 2);
  // Ticks every 0.5 m (the view is about 3 m wide) along the map's top edge.
  int ticks = 0;
  for (double x = std::ceil(lo.x() / 0.5) * 0.5; x <= hi.x(); x += 0.5) {
    ticks += img.at<cv::Vec3b>(title_height + 3, px(x, 0).x) == cv::Vec3b(40, 40, 40);
  }
  EXPECT_GE(ticks, 4);
}

}  // namespace
}  // namespace npfkct::render
