#include "npfkct/render/belief_picture.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

namespace npfkct::render {
namespace {

using object_search::Box;
using object_search::RobotConfig;
using object_search::Vec2;
using object_search::Vec3;
using object_search::World;

const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kMuted(110, 110, 110);
const cv::Scalar kFurniture(222, 222, 222);
const cv::Scalar kFurnitureEdge(170, 170, 170);
const cv::Scalar kRegion(230, 200, 170);
const cv::Scalar kRobot(160, 90, 20);      // blue
const cv::Scalar kNextView(150, 40, 150);  // purple
const cv::Scalar kTarget(40, 150, 20);     // green
const cv::Scalar kObstacle(20, 20, 20);    // black
const cv::Scalar kObject(100, 100, 100);   // grey
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

double Sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

double MeanOdds(const object_search::ObjectKnowledge& o) {
  double mean = 0.0;
  for (float v : o.odds) mean += v;
  return mean / 8.0;
}

std::string Format(const char* fmt, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

// Text with a white halo box behind it, so that it reads on top of the heat map.
void Label(cv::Mat& img, const std::string& text, cv::Point at, double scale,
           const cv::Scalar& color, bool halo = true, int thickness = 1) {
  int base = 0;
  const cv::Size size = cv::getTextSize(text, kFont, scale, thickness, &base);
  if (halo) {
    cv::rectangle(img, cv::Point(at.x - 2, at.y - size.height - 3),
                  cv::Point(at.x + size.width + 2, at.y + base), cv::Scalar(255, 255, 255),
                  cv::FILLED);
  }
  cv::putText(img, text, at, kFont, scale, color, thickness, cv::LINE_AA);
}

// The part [t0, t1] (in units of the segment's length, within [0, 1]) of the segment a-b inside
// `r` (Liang-Barsky); false when none of it is.
bool ClipSegment(cv::Point2d a, cv::Point2d b, const cv::Rect2d& r, double* t0, double* t1) {
  const cv::Point2d d = b - a;
  *t0 = 0.0;
  *t1 = 1.0;
  const double p[4] = {-d.x, d.x, -d.y, d.y};
  const double q[4] = {a.x - r.x, r.x + r.width - a.x, a.y - r.y, r.y + r.height - a.y};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0.0) {
      if (q[i] < 0.0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0.0) {
      *t0 = std::max(*t0, t);
    } else {
      *t1 = std::min(*t1, t);
    }
  }
  return *t0 <= *t1;
}

// Dashes of `dash` pixels from a to b, drawn only where they cross the image: an outline
// millions of pixels long (a base region far outside a small room) costs what its visible part
// costs.
void DashedLine(cv::Mat& img, cv::Point2d a, cv::Point2d b, const cv::Scalar& color, int thickness,
                double dash = 8.0) {
  const cv::Point2d d = b - a;
  const double length = std::hypot(d.x, d.y);
  if (!(length >= 1e-9 && length < 1e12)) return;
  const double margin = thickness + 2.0;
  double t0 = 0.0, t1 = 1.0;
  if (!ClipSegment(a, b, cv::Rect2d(-margin, -margin, img.cols + 2 * margin, img.rows + 2 * margin),
                   &t0, &t1)) {
    return;
  }
  const cv::Point2d step = d * (1.0 / length);
  // The first dash that reaches the visible part, in the pattern that starts at a.
  const double first = std::floor(std::max(0.0, t0 * length - dash) / (2.0 * dash)) * 2.0 * dash;
  const double end = std::min(length, t1 * length + dash);
  for (double t = first; t < end; t += 2.0 * dash) {
    const cv::Point2d p = a + step * t, q = a + step * std::min(length, t + dash);
    cv::line(img, cv::Point(cvRound(p.x), cvRound(p.y)), cv::Point(cvRound(q.x), cvRound(q.y)),
             color, thickness, cv::LINE_AA);
  }
}

void DashedPolygon(cv::Mat& img, const std::vector<cv::Point>& poly, const cv::Scalar& color,
                   int thickness) {
  for (size_t i = 0; i < poly.size(); ++i) {
    DashedLine(img, poly[i], poly[(i + 1) % poly.size()], color, thickness);
  }
}

// The picture's frame: world (x, y) to pixels of the map panel, whose top-left is `origin`.
struct Frame {
  Vec2 lo, hi;
  double ppm = 100.0;
  cv::Point origin;
  cv::Point2d At(double x, double y) const {
    return {origin.x + (x - lo.x()) * ppm, origin.y + (hi.y() - y) * ppm};
  }
  // Pixels as integers, within a million pixels of the picture (world coordinates up to 1e4 m
  // at a small room's scale would not fit an int; OpenCV clips what lies outside the image).
  cv::Point Px(double x, double y) const {
    const cv::Point2d p = At(x, y);
    constexpr double kFar = 1e6;
    return {cvRound(std::clamp(p.x, -kFar, kFar)), cvRound(std::clamp(p.y, -kFar, kFar))};
  }
  int width() const { return std::max(1, cvRound((hi.x() - lo.x()) * ppm)); }
  int height() const { return std::max(1, cvRound((hi.y() - lo.y()) * ppm)); }
};

std::vector<cv::Point> Footprint(const Frame& f, const Box& box) {
  const auto k = box.Corners();
  return {f.Px(k[0].x(), k[0].y()), f.Px(k[1].x(), k[1].y()), f.Px(k[3].x(), k[3].y()),
          f.Px(k[2].x(), k[2].y())};
}

// Paints `colors` (ny x nx cells, BGR) into `map` (the map panel) where cell (u, v) has its
// center at world (a + u * du + v * dv); the affine map is exact, rotation included.
void PaintCells(cv::Mat& map, const Frame& f, const cv::Mat& colors, const Vec2& a, const Vec2& du,
                const Vec2& dv) {
  // Pixel centers sit at integer coordinates in warpAffine: world x maps to (x - lo) * ppm - 0.5.
  cv::Mat m =
      (cv::Mat_<double>(2, 3) << du.x() * f.ppm, dv.x() * f.ppm, (a.x() - f.lo.x()) * f.ppm - 0.5,
       -du.y() * f.ppm, -dv.y() * f.ppm, (f.hi.y() - a.y()) * f.ppm - 0.5);
  cv::Mat warped, mask;
  cv::warpAffine(colors, warped, m, map.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  cv::warpAffine(cv::Mat(colors.size(), CV_8U, cv::Scalar(255)), mask, m, map.size(),
                 cv::INTER_NEAREST, cv::BORDER_CONSTANT);
  warped.copyTo(map, mask);
}

std::vector<cv::Point> FrustumPixels(const Frame& f, const World& world, const RobotConfig& c) {
  std::vector<cv::Point> poly;
  for (const Vec2& p : FrustumFootprint(world, c)) poly.push_back(f.Px(p.x(), p.y()));
  return poly;
}

// The camera's view as a light fill, drawn under the heat map so that its colours stay true.
void FillFrustum(cv::Mat& img, const Frame& f, const World& world, const RobotConfig& c,
                 const cv::Scalar& color) {
  const auto poly = FrustumPixels(f, world, c);
  if (poly.empty()) return;
  cv::Mat overlay = img.clone();
  cv::fillPoly(overlay, std::vector<std::vector<cv::Point>>{poly}, color, cv::LINE_AA);
  cv::addWeighted(overlay, 0.14, img, 0.86, 0.0, img);
}

void DrawRobot(cv::Mat& img, const Frame& f, const World& world, const RobotConfig& c,
               const cv::Scalar& color, bool dashed) {
  const auto poly = FrustumPixels(f, world, c);
  if (dashed) {
    DashedPolygon(img, poly, color, 2);
  } else if (!poly.empty()) {
    cv::polylines(img, poly, true, color, 1, cv::LINE_AA);
  }
  const int radius = std::max(2, cvRound(world.robot.footprint_radius * f.ppm));
  const cv::Point center = f.Px(c.x, c.y);
  if (!world.robot.footprint.empty()) {  // the base's outline at its heading
    const Eigen::Rotation2Dd turn(c.yaw);
    std::vector<cv::Point> outline;
    for (const auto& v : world.robot.footprint) {
      const Eigen::Vector2d p = Eigen::Vector2d(c.x, c.y) + turn * v;
      outline.push_back(f.Px(p.x(), p.y()));
    }
    if (dashed) {
      DashedPolygon(img, outline, color, 2);
    } else {
      cv::polylines(img, outline, true, color, 2, cv::LINE_AA);
    }
  } else if (dashed) {
    const int n = 24;
    for (int i = 0; i < n; i += 2) {
      cv::ellipse(img, center, cv::Size(radius, radius), 0, 360.0 * i / n, 360.0 * (i + 1) / n,
                  color, 2, cv::LINE_AA);
    }
  } else {
    cv::circle(img, center, radius, color, 2, cv::LINE_AA);
  }
  const double length = std::max(0.25, 0.8 * world.robot.footprint_radius);
  cv::arrowedLine(img, center, f.Px(c.x + length * std::cos(c.yaw), c.y + length * std::sin(c.yaw)),
                  color, 2, cv::LINE_AA, 0, 0.3);
}

// Places labels where they cover as little as possible of each other and of the objects: the
// candidate spot around an anchor rectangle with the least overlap with what is already taken.
class LabelPlacer {
 public:
  explicit LabelPlacer(cv::Size bounds) : bounds_(bounds) {}
  cv::Point Place(const std::string& text, double scale, const cv::Rect& anchor) {
    int base = 0;
    const cv::Size size = cv::getTextSize(text, kFont, scale, 1, &base);
    const int h = size.height + base + 4, w = size.width + 4, gap = 3;
    std::vector<cv::Point> candidates;
    for (int ring = 0; ring < 3; ++ring) {
      const int up = anchor.y - gap - h - ring * h,
                down = anchor.y + anchor.height + gap + ring * h;
      for (int dx : {0, -w / 2, anchor.width - w, -w + anchor.width / 2}) {
        candidates.emplace_back(anchor.x + dx, up);
        candidates.emplace_back(anchor.x + dx, down);
      }
      candidates.emplace_back(anchor.x + anchor.width + gap + ring * w / 2, anchor.y);
      candidates.emplace_back(anchor.x - gap - w - ring * w / 2, anchor.y);
    }
    cv::Rect best;
    int64_t best_overlap = -1;
    for (const cv::Point& c : candidates) {
      cv::Rect r(c, cv::Size(w, h));
      r.x = std::clamp(r.x, 0, std::max(0, bounds_.width - w));
      r.y = std::clamp(r.y, 0, std::max(0, bounds_.height - h));
      int64_t overlap = 0;
      for (const cv::Rect& taken : taken_) overlap += (r & taken).area();
      if (best_overlap < 0 || overlap < best_overlap) best = r, best_overlap = overlap;
      if (overlap == 0) break;
    }
    taken_.push_back(best);
    return {best.x + 2, best.y + size.height + 2};
  }
  void Reserve(const cv::Rect& r) { taken_.push_back(r); }

 private:
  cv::Size bounds_;
  std::vector<cv::Rect> taken_;
};

// A "nice" scale-bar length (m) close to `target` pixels.
double ScaleLength(double ppm, double target = 120.0) {
  double best = 1.0, best_error = 1e300;
  for (double l : {0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0}) {
    const double error = std::abs(std::log(l * ppm / target));
    if (error < best_error) best = l, best_error = error;
  }
  return best;
}

// Where the target probably is, in words: a declared target, an object whose faces look like the
// target, or the workspace holding most of the grid world's mass.
std::string BestGuess(const World& world) {
  int best = -1;
  double best_p = 0.0;
  for (size_t i = 1; i < world.objects.size(); ++i) {
    const auto& o = world.objects[i];
    if (o.status == object_search::kDeclaredTarget) return "declared target: " + o.key;
    if (o.status == object_search::kRemoved) continue;
    const double p = Sigmoid(MeanOdds(o));
    if (p > best_p) best = static_cast<int>(i), best_p = p;
  }
  if (best > 0 && best_p >= 0.6) {
    return "object " + world.objects[best].key + Format(" (P %.2f)", best_p);
  }
  const auto mass = world.grid.WorkspaceMass();
  if (mass.empty()) return "unknown";
  const size_t w = std::max_element(mass.begin(), mass.end()) - mass.begin();
  return "on " + world.grid.workspaces()[w].name + Format(" (%.0f%% of the mass)", 100 * mass[w]);
}

}  // namespace

const std::vector<ColorStop>& ColorStops() {
  static const std::vector<ColorStop> stops = {{0.0, 0xee, 0xf3, 0xf8},
                                               {0.25, 0xfe, 0xe0, 0x8b},
                                               {0.5, 0xf4, 0x6d, 0x43},
                                               {1.0, 0x67, 0x00, 0x1f}};
  return stops;
}

cv::Vec3b ProbabilityColor(double p) {
  const auto& stops = ColorStops();
  if (!(p >= 0.0)) p = 0.0;
  p = std::min(1.0, p);
  for (size_t i = 1; i < stops.size(); ++i) {
    if (p <= stops[i].p) {
      const ColorStop &a = stops[i - 1], &b = stops[i];
      const double t = (p - a.p) / (b.p - a.p);
      auto mix = [t](int x, int y) { return static_cast<uint8_t>(std::lround(x + t * (y - x))); };
      return {mix(a.b, b.b), mix(a.g, b.g), mix(a.r, b.r)};
    }
  }
  const ColorStop& last = stops.back();
  return {static_cast<uint8_t>(last.b), static_cast<uint8_t>(last.g), static_cast<uint8_t>(last.r)};
}

std::vector<Vec2> FrustumFootprint(const World& world, const RobotConfig& config) {
  const object_search::CameraPose pose = object_search::CameraPoseFor(world.robot, config);
  const double th = world.camera.TanHalfHorizontal(), tv = world.camera.TanHalfVertical();
  std::vector<cv::Point2f> corners;
  for (double d : {world.camera.near, world.camera.far}) {
    for (double sx : {-1.0, 1.0}) {
      for (double sy : {-1.0, 1.0}) {
        const Vec3 p = pose.position + d * (pose.forward + sx * th * pose.left + sy * tv * pose.up);
        corners.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
      }
    }
  }
  std::vector<cv::Point2f> hull;
  cv::convexHull(corners, hull, /*clockwise=*/false);
  std::vector<Vec2> out;
  for (const auto& p : hull) out.emplace_back(p.x, p.y);
  return out;
}

std::pair<Vec2, Vec2> CropBounds(const World& world, const std::optional<RobotConfig>& next_view,
                                 double margin) {
  Vec2 lo(1e300, 1e300), hi(-1e300, -1e300);
  auto add = [&](double x, double y, double r = 0.0) {
    lo = lo.cwiseMin(Vec2(x - r, y - r));
    hi = hi.cwiseMax(Vec2(x + r, y + r));
  };
  for (const auto& ws : world.grid.workspaces()) {
    const double c = std::cos(ws.yaw), s = std::sin(ws.yaw);
    for (double sx : {-0.5, 0.5}) {
      for (double sy : {-0.5, 0.5}) {
        const double lx = sx * ws.length, ly = sy * ws.width;
        add(ws.center.x() + c * lx - s * ly, ws.center.y() + s * lx + c * ly);
      }
    }
  }
  for (size_t i = 1; i < world.objects.size(); ++i) {
    for (const Vec3& k : world.objects[i].box.Corners()) add(k.x(), k.y());
  }
  const double r = world.robot.footprint_radius;
  add(world.robot_config.x, world.robot_config.y, r);
  if (next_view) add(next_view->x, next_view->y, r);
  const Vec2 room_lo = world.occupancy.min(), room_hi = world.occupancy.max();
  if (lo.x() > hi.x()) return {room_lo, room_hi};  // nothing to show: the room
  lo -= Vec2(margin, margin);
  hi += Vec2(margin, margin);
  if (room_hi.x() > room_lo.x() && room_hi.y() > room_lo.y()) {
    lo = lo.cwiseMax(room_lo);
    hi = hi.cwiseMin(room_hi);
    if (!(hi.x() > lo.x() && hi.y() > lo.y())) return {room_lo, room_hi};
  }
  return {lo, hi};
}

namespace {

constexpr int kLegendWidth = 330;
constexpr int kLegendHeight = 540;

// Where everything goes: the crop, the map's scale, and the panels' sizes (pixels).
struct Layout {
  Vec2 lo, hi;  // the floor shown
  double ppm = 100.0;
  int title_height = 38;
  int map_w = 1, map_h = 1;   // the map panel, below the title
  int width = 1, height = 1;  // the whole picture
};

// Layout: takes the world and the options, gives the crop and a scale that fits: the longest
// side at map_pixels, within max_pixels for the whole picture.
Layout PlanLayout(const World& world, const BeliefPictureOptions& options) {
  Layout l;
  const auto [lo, hi] = CropBounds(world, options.next_view, options.margin);
  l.lo = lo;
  l.hi = hi;
  const double ex = std::max(1e-3, l.hi.x() - l.lo.x()), ey = std::max(1e-3, l.hi.y() - l.lo.y());
  l.title_height = options.subtitle.empty() ? 38 : 60;
  double ppm = options.map_pixels / std::max(ex, ey);
  const double budget = std::max<double>(1.0, static_cast<double>(options.max_pixels));
  for (int i = 0; i < 40; ++i) {
    const double w = ex * ppm + kLegendWidth,
                 h = std::max(ey * ppm, double{kLegendHeight}) + l.title_height;
    if (w * h <= budget || ppm < 1e-3) break;
    ppm *= 0.85;
  }
  l.ppm = ppm;
  const Frame f{l.lo, l.hi, ppm, cv::Point(0, l.title_height)};
  l.map_w = std::min(8192, f.width());
  l.map_h = std::min(8192, f.height());
  l.width = l.map_w + kLegendWidth;
  l.height = std::max(l.map_h, kLegendHeight) + l.title_height;
  return l;
}

// The room: takes the map panel, gives it the occupied cells of the map, the base regions
// (dashed) and the furniture.
void DrawRoom(cv::Mat& map, const Frame& local, const World& world) {
  const auto& occ = world.occupancy;
  if (occ.nx() > 0 && occ.ny() > 0) {
    cv::Mat cells(occ.ny(), occ.nx(), CV_8UC3, cv::Scalar(250, 250, 250));
    cells.setTo(cv::Scalar(232, 232, 232),
                cv::Mat(occ.ny(), occ.nx(), CV_8U, const_cast<uint8_t*>(occ.cells().data())) > 0);
    const double r = occ.resolution();
    PaintCells(map, local, cells, occ.min() + Vec2(0.5 * r, 0.5 * r), Vec2(r, 0), Vec2(0, r));
  }
  for (const auto& region : world.base_regions) {
    DashedPolygon(
        map,
        {local.Px(region.min.x(), region.min.y()), local.Px(region.max.x(), region.min.y()),
         local.Px(region.max.x(), region.max.y()), local.Px(region.min.x(), region.max.y())},
        kRegion, 1);
  }
  for (const Box& b : world.furniture) {
    const auto poly = Footprint(local, b);
    cv::fillPoly(map, std::vector<std::vector<cv::Point>>{poly}, kFurniture, cv::LINE_AA);
    cv::polylines(map, poly, true, kFurnitureEdge, 1, cv::LINE_AA);
  }
}

// Takes a workspace, gives its corners in pixels, counter-clockwise from (-x, -y).
std::vector<cv::Point> WorkspaceOutline(const Frame& local, const object_search::Workspace& ws) {
  const double c = std::cos(ws.yaw), s = std::sin(ws.yaw);
  std::vector<cv::Point> outline;
  for (auto [sx, sy] : {std::pair{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}}) {
    const double px = sx * ws.length, py = sy * ws.width;
    outline.push_back(local.Px(ws.center.x() + c * px - s * py, ws.center.y() + s * px + c * py));
  }
  return outline;
}

// The heat map: takes the map panel, gives it the grid world's odds, one affine-painted image
// per workspace, each outlined.
void DrawOdds(cv::Mat& map, const Frame& local, const object_search::GridWorld& grid) {
  for (size_t wi = 0; wi < grid.workspaces().size(); ++wi) {
    const int w = static_cast<int>(wi), nx = grid.cells_x(w), ny = grid.cells_y(w);
    const auto& ws = grid.workspaces()[wi];
    cv::Mat colors(ny, nx, CV_8UC3);
    for (int iy = 0; iy < ny; ++iy) {
      for (int ix = 0; ix < nx; ++ix) {
        colors.at<cv::Vec3b>(iy, ix) =
            ProbabilityColor(Sigmoid(grid.log_odds(grid.Index(w, ix, iy))));
      }
    }
    const double c = std::cos(ws.yaw), s = std::sin(ws.yaw);
    const double cx = ws.length / nx, cy = ws.width / ny;
    const double lx = -0.5 * ws.length + 0.5 * cx, ly = -0.5 * ws.width + 0.5 * cy;
    PaintCells(map, local, colors,
               Vec2(ws.center.x() + c * lx - s * ly, ws.center.y() + s * lx + c * ly),
               Vec2(c * cx, s * cx), Vec2(-s * cy, c * cy));
    cv::polylines(map, WorkspaceOutline(local, ws), true, kMuted, 1, cv::LINE_AA);
  }
}

// Inside a box the camera cannot see: takes the map panel and a footprint, gives the footprint
// lightened and hatched, so that the heat map's "not seen" colour under it does not read as
// "likely here".
void Hatch(cv::Mat& map, const std::vector<cv::Point>& poly) {
  const cv::Rect r = cv::boundingRect(poly) & cv::Rect(0, 0, map.cols, map.rows);
  if (r.area() <= 0) return;
  cv::Mat mask = cv::Mat::zeros(r.size(), CV_8U);
  std::vector<cv::Point> local;
  for (const cv::Point& p : poly) local.push_back(p - r.tl());
  cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{local}, cv::Scalar(255), cv::LINE_AA);
  cv::Mat roi = map(r);
  cv::Mat hatched;
  roi.convertTo(hatched, -1, 0.45, 0.55 * 255);
  for (int d = -r.height; d < r.width; d += 7) {
    cv::line(hatched, cv::Point(d, r.height), cv::Point(d + r.height, 0), kMuted, 1, cv::LINE_AA);
  }
  hatched.copyTo(roi, mask);
}

// The axes: takes the map panel, gives it ticks in metres of the map frame along its top and
// left edges (a round step, six to ten ticks) and the frame's name in the top-right corner.
void DrawAxes(cv::Mat& map, const Frame& local) {
  const double span = std::max(local.hi.x() - local.lo.x(), local.hi.y() - local.lo.y());
  double step = 0.1;
  for (double s : {0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0, 10.0, 20.0, 50.0, 100.0, 250.0, 500.0,
                   1000.0, 2500.0, 5000.0}) {
    step = s;
    if (span / s <= 10.0) break;
  }
  const char* fmt = step < 1.0 ? "%.2f" : "%.0f";
  const std::string frame = "map frame, m (x right, y up)";
  int base = 0;
  const int frame_x = map.cols - cv::getTextSize(frame, kFont, 0.38, 1, &base).width - 8;
  for (double x = std::ceil(local.lo.x() / step) * step; x <= local.hi.x(); x += step) {
    const int px = local.Px(x, local.hi.y()).x;
    cv::line(map, cv::Point(px, 0), cv::Point(px, 6), kInk, 1);
    if (px > 44 && px + 48 < frame_x) {
      Label(map, Format(fmt, std::abs(x) < 1e-9 ? 0.0 : x), cv::Point(px + 2, 17), 0.35, kInk,
            true);
    }
  }
  for (double y = std::ceil(local.lo.y() / step) * step; y <= local.hi.y(); y += step) {
    const int py = local.Px(local.lo.x(), y).y;
    cv::line(map, cv::Point(0, py), cv::Point(6, py), kInk, 1);
    if (py > 26 && py < map.rows - 40) {
      Label(map, Format(fmt, std::abs(y) < 1e-9 ? 0.0 : y), cv::Point(8, py + 4), 0.35, kInk, true);
    }
  }
  Label(map, frame, cv::Point(frame_x, 17), 0.38, kMuted, true);
}

// Takes an object, gives the colour of its status.
cv::Scalar StatusColor(const object_search::ObjectKnowledge& o) {
  return o.status == object_search::kDeclaredTarget     ? kTarget
         : o.status == object_search::kDeclaredObstacle ? kObstacle
                                                        : kObject;
}

// The objects: takes the map panel, gives it each known object's footprint by status and its
// face odds at the corners (`dot` pixels); reserves their rectangles in `placer` and gives them
// as the anchors of the labels (with the object's index).
std::vector<std::pair<cv::Rect, size_t>> DrawObjects(cv::Mat& map, const Frame& local,
                                                     const World& world, int dot,
                                                     LabelPlacer* placer) {
  std::vector<std::pair<cv::Rect, size_t>> anchors;
  for (size_t i = 1; i < world.objects.size(); ++i) {
    const auto& o = world.objects[i];
    const auto poly = Footprint(local, o.box);
    if (o.status == object_search::kRemoved) {
      DashedPolygon(map, poly, cv::Scalar(160, 160, 160), 1);
    } else {
      Hatch(map, poly);
      cv::polylines(map, poly, true, StatusColor(o), 2, cv::LINE_AA);
      const auto k = o.box.Corners();
      for (int corner = 0; corner < 4; ++corner) {
        const cv::Point at = local.Px(k[corner].x(), k[corner].y());
        const cv::Vec3b lower = ProbabilityColor(Sigmoid(o.odds[corner]));
        const cv::Vec3b upper = ProbabilityColor(Sigmoid(o.odds[corner + 4]));
        cv::circle(map, at, dot + 2, cv::Scalar(lower[0], lower[1], lower[2]), cv::FILLED,
                   cv::LINE_AA);
        cv::circle(map, at, dot - 1, cv::Scalar(upper[0], upper[1], upper[2]), cv::FILLED,
                   cv::LINE_AA);
        cv::circle(map, at, dot + 2, kInk, 1, cv::LINE_AA);
      }
    }
    const cv::Rect box = cv::boundingRect(poly);
    const cv::Rect with_dots(box.x - dot - 2, box.y - dot - 2, box.width + 2 * dot + 4,
                             box.height + 2 * dot + 4);
    placer->Reserve(with_dots);
    anchors.emplace_back(with_dots, i);
  }
  return anchors;
}

// The labels: takes the map panel and the objects' anchors, gives it each object's label (id,
// P(target), status), then each workspace's name with its share of the target mass, placed so
// that they do not cover each other.
void DrawLabels(cv::Mat& map, const Frame& local, const World& world,
                const std::vector<std::pair<cv::Rect, size_t>>& anchors, LabelPlacer* placer) {
  for (const auto& [anchor, i] : anchors) {
    const auto& o = world.objects[i];
    const bool removed = o.status == object_search::kRemoved;
    const std::string status = o.status == object_search::kDeclaredTarget     ? " TARGET"
                               : o.status == object_search::kDeclaredObstacle ? " obstacle"
                               : removed                                      ? " removed"
                                                                              : "";
    const std::string text = o.key + Format(" P%.2f", Sigmoid(MeanOdds(o))) + status;
    Label(map, text, placer->Place(text, 0.42, anchor), 0.42, removed ? kMuted : StatusColor(o));
  }
  const auto& grid = world.grid;
  const auto mass = grid.WorkspaceMass();
  for (size_t wi = 0; wi < grid.workspaces().size(); ++wi) {
    const auto& ws = grid.workspaces()[wi];
    const cv::Rect r = cv::boundingRect(WorkspaceOutline(local, ws));
    const std::string text =
        ws.name + Format(" %.0f%%", 100.0 * (wi < mass.size() ? mass[wi] : 0.0));
    Label(map, text, placer->Place(text, 0.42, cv::Rect(r.x, r.y + r.height, 1, 1)), 0.42, kMuted);
  }
}

// The scale bar: takes the map panel, gives it a bar of a round length, bottom left.
void DrawScaleBar(cv::Mat& map, double ppm) {
  const double meters = ScaleLength(ppm);
  const int length = cvRound(meters * ppm);
  const cv::Point a(12, map.rows - 14), b(12 + length, map.rows - 14);
  cv::rectangle(map, cv::Point(a.x - 6, a.y - 22), cv::Point(b.x + 6, a.y + 8),
                cv::Scalar(255, 255, 255), cv::FILLED);
  cv::line(map, a, b, kInk, 2);
  cv::line(map, a + cv::Point(0, -5), a + cv::Point(0, 5), kInk, 2);
  cv::line(map, b + cv::Point(0, -5), b + cv::Point(0, 5), kInk, 2);
  Label(map, meters >= 1.0 ? Format("%.0f m", meters) : Format("%.0f cm", 100 * meters),
        cv::Point(a.x, a.y - 8), 0.42, kInk, false);
}

// The map panel: takes it blank, gives it the room, the camera's views, the heat map, the robot
// and the next view, the axes, the objects (hatched inside) and the labels, the scale bar and a
// border, in that order (each drawn over the ones before).
void DrawMap(cv::Mat& map, const Frame& local, const World& world,
             const BeliefPictureOptions& options) {
  map.setTo(cv::Scalar(250, 250, 250));
  DrawRoom(map, local, world);
  // The camera's views, lightly, under the heat map.
  FillFrustum(map, local, world, world.robot_config, kRobot);
  if (options.next_view) FillFrustum(map, local, world, *options.next_view, kNextView);
  DrawOdds(map, local, world.grid);
  // The robot, its camera's view, and the planned next view.
  DrawRobot(map, local, world, world.robot_config, kRobot, false);
  if (options.next_view) DrawRobot(map, local, world, *options.next_view, kNextView, true);
  const int dot = std::clamp(cvRound(0.018 * local.ppm), 3, 7);
  LabelPlacer placer(map.size());
  // The axes' strips along the top and left edges are kept clear of labels.
  DrawAxes(map, local);
  placer.Reserve(cv::Rect(0, 0, map.cols, 22));
  placer.Reserve(cv::Rect(0, 0, 44, map.rows));
  const auto anchors = DrawObjects(map, local, world, dot, &placer);
  DrawLabels(map, local, world, anchors, &placer);
  DrawScaleBar(map, local.ppm);
  cv::rectangle(map, cv::Point(0, 0), cv::Point(map.cols - 1, map.rows - 1), kFurnitureEdge, 1);
}

// The title bar: takes the picture, gives it the title and the subtitle.
void DrawTitle(cv::Mat& img, const BeliefPictureOptions& options) {
  Label(img, options.title.empty() ? std::string("belief") : options.title, cv::Point(10, 26), 0.7,
        kInk, false, 2);
  if (!options.subtitle.empty())
    Label(img, options.subtitle, cv::Point(10, 50), 0.5, kMuted, false);
}

// The colour bar: takes the picture and the legend's left edge and line *y, gives it the bar of
// the odds' colours with its ticks and words; *y moves below it.
void DrawColorBar(cv::Mat& img, int x0, int* y) {
  Label(img, "P(target in cell)", cv::Point(x0, *y), 0.5, kInk, false);
  *y += 10;
  const int bar_w = kLegendWidth - 40, bar_h = 16;
  for (int i = 0; i < bar_w; ++i) {
    const cv::Vec3b c = ProbabilityColor(static_cast<double>(i) / (bar_w - 1));
    cv::line(img, cv::Point(x0 + i, *y), cv::Point(x0 + i, *y + bar_h),
             cv::Scalar(c[0], c[1], c[2]));
  }
  cv::rectangle(img, cv::Point(x0, *y), cv::Point(x0 + bar_w - 1, *y + bar_h), kMuted, 1);
  for (int t = 0; t <= 4; ++t) {
    const int x = x0 + (bar_w - 1) * t / 4;
    cv::line(img, cv::Point(x, *y + bar_h), cv::Point(x, *y + bar_h + 4), kInk, 1);
    Label(img, Format("%.2g", t / 4.0), cv::Point(x - 8, *y + bar_h + 17), 0.4, kInk, false);
  }
  *y += bar_h + 34;
  Label(img, "seen, empty", cv::Point(x0, *y), 0.4, kMuted, false);
  Label(img, "not seen", cv::Point(x0 + bar_w / 2 - 28, *y), 0.4, kMuted, false);
  Label(img, "likely", cv::Point(x0 + bar_w - 44, *y), 0.4, kMuted, false);
  *y += 30;
}

// The legend's symbols: takes the picture and the legend's left edge and line *y, gives it one
// line per symbol of the map; *y moves below them.
void DrawLegendEntries(cv::Mat& img, int x0, int* y) {
  auto entry = [&](const std::string& text, auto&& symbol) {
    symbol(cv::Point(x0 + 12, *y - 5));
    Label(img, text, cv::Point(x0 + 34, *y), 0.45, kInk, false);
    *y += 24;
  };
  auto box_symbol = [&](const cv::Scalar& color) {
    return [&img, color](cv::Point c) {
      cv::rectangle(img, c - cv::Point(9, 7), c + cv::Point(9, 7), color, 2, cv::LINE_AA);
    };
  };
  entry("object: id, P(target) of its faces", box_symbol(kObject));
  entry("declared target", box_symbol(kTarget));
  entry("declared obstacle", box_symbol(kObstacle));
  entry("inside a box: not seen (hatched)", [&](cv::Point c) {
    cv::rectangle(img, c - cv::Point(9, 7), c + cv::Point(9, 7), cv::Scalar(235, 235, 235),
                  cv::FILLED);
    for (int d = -8; d <= 8; d += 6) {
      cv::line(img, c + cv::Point(d - 5, 7), c + cv::Point(d + 5, -7), kMuted, 1, cv::LINE_AA);
    }
    cv::rectangle(img, c - cv::Point(9, 7), c + cv::Point(9, 7), kObject, 1, cv::LINE_AA);
  });
  entry("removed object", [&](cv::Point c) {
    DashedPolygon(
        img,
        {c + cv::Point(-9, -7), c + cv::Point(9, -7), c + cv::Point(9, 7), c + cv::Point(-9, 7)},
        cv::Scalar(160, 160, 160), 1);
  });
  entry("face odds (outer: low, inner: high)", [&](cv::Point c) {
    const cv::Vec3b a = ProbabilityColor(0.2), b = ProbabilityColor(0.8);
    cv::circle(img, c, 7, cv::Scalar(a[0], a[1], a[2]), cv::FILLED, cv::LINE_AA);
    cv::circle(img, c, 4, cv::Scalar(b[0], b[1], b[2]), cv::FILLED, cv::LINE_AA);
    cv::circle(img, c, 7, kInk, 1, cv::LINE_AA);
  });
  entry("robot and camera view", [&](cv::Point c) {
    cv::circle(img, c, 7, kRobot, 2, cv::LINE_AA);
    cv::arrowedLine(img, c, c + cv::Point(11, 0), kRobot, 2, cv::LINE_AA, 0, 0.4);
  });
  entry("planned next view", [&](cv::Point c) {
    DashedLine(img, c + cv::Point(-10, 0), c + cv::Point(10, 0), kNextView, 2, 4.0);
  });
  entry("furniture / base regions", [&](cv::Point c) {
    cv::rectangle(img, c - cv::Point(9, 7), c + cv::Point(1, 7), kFurniture, cv::FILLED);
    DashedLine(img, c + cv::Point(4, -7), c + cv::Point(4, 7), kRegion, 1, 3.0);
  });
}

// The summary: takes the picture and the legend's left edge and line y, gives it the most
// likely place of the target, the next action (when planned) and the step and object counts.
void DrawSummary(cv::Mat& img, int x0, int y, const World& world,
                 const BeliefPictureOptions& options) {
  y += 8;
  Label(img, options.done ? "done:" : "most likely:", cv::Point(x0, y), 0.45, kMuted, false);
  y += 22;
  Label(img, options.done ? std::string("found, the target was removed") : BestGuess(world),
        cv::Point(x0, y), 0.5, kInk, false);
  y += 26;
  if (!options.next_action.empty()) {
    Label(img, "next: " + options.next_action, cv::Point(x0, y), 0.5, kNextView, false);
    y += 24;
  }
  Label(img,
        Format("step %.0f", world.steps) +
            Format(", %.0f objects known", static_cast<double>(world.objects.size()) - 1),
        cv::Point(x0, y), 0.42, kMuted, false);
}

}  // namespace

cv::Mat RenderBelief(const World& world, const BeliefPictureOptions& options) {
  const Layout l = PlanLayout(world, options);
  cv::Mat img(l.height, l.width, CV_8UC3, cv::Scalar(255, 255, 255));
  // The map panel, below the title bar; the legend to its right.
  cv::Mat map = img(cv::Rect(0, l.title_height, l.map_w, l.map_h));
  DrawMap(map, Frame{l.lo, l.hi, l.ppm, cv::Point(0, 0)}, world, options);
  DrawTitle(img, options);
  const int x0 = l.map_w + 16;
  int y = l.title_height + 22;
  DrawColorBar(img, x0, &y);
  DrawLegendEntries(img, x0, &y);
  DrawSummary(img, x0, y, world, options);
  return img;
}

}  // namespace npfkct::render
