#include "npfkct/perception/perception.h"

#include <pcl/common/common.h>
#include <pcl/common/transforms.h>
#include <pcl/features/fpfh.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/sample_consensus_prerejective.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <numbers>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <unordered_map>

namespace npfkct::perception {
namespace {

using object_search::Box;
using object_search::Vec3;
using PointXYZ = pcl::PointXYZ;
using CloudXYZ = pcl::PointCloud<PointXYZ>;
using PointNormal = pcl::PointNormal;
using NormalCloud = pcl::PointCloud<PointNormal>;
using Clock = std::chrono::steady_clock;

double Ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

// Point-to-plane least squares whose step is the identity when the system gives no usable
// transformation (not finite, or a translation beyond any room): PCL's ICP would move the source
// by it and hand non-finite points to its k-d tree, which aborts the process (an assertion in
// the Debian build of PCL). Found by a frame with points at 9,999 m.
class FiniteStepPointToPlane final
    : public pcl::registration::TransformationEstimationPointToPlaneLLS<PointNormal, PointNormal,
                                                                        float> {
 public:
  using Base =
      pcl::registration::TransformationEstimationPointToPlaneLLS<PointNormal, PointNormal, float>;
  using Base::estimateRigidTransformation;
  void estimateRigidTransformation(const NormalCloud& source, const NormalCloud& target,
                                   const pcl::Correspondences& correspondences,
                                   Matrix4& transformation) const override {
    Base::estimateRigidTransformation(source, target, correspondences, transformation);
    constexpr float kMaxStep = 1000.0f;  // metres
    if (!transformation.allFinite() || transformation.block<3, 1>(0, 3).norm() > kMaxStep) {
      transformation.setIdentity();
    }
  }
};

// The centroid of the points in each voxel of the grid of edge `leaf` anchored at the origin.
// PCL's VoxelGrid numbers a cloud's voxels with 32-bit integers and returns a cloud that spans
// more of them (a few points 10 km away) unchanged: a dense blob then reached the k-d tree
// searches whole, and a frame of 20,000 points took 45 s instead of 0.4 s. Such a cloud is
// filtered in blocks of kBlock^3 voxels aligned with the grid, so that no voxel straddles two.
// Every field is averaged (a PointNormal's normal too, which is then no longer of unit length).
template <typename Point>
typename pcl::PointCloud<Point>::Ptr Downsample(const typename pcl::PointCloud<Point>::ConstPtr& in,
                                                double leaf) {
  using Cloud = pcl::PointCloud<Point>;
  const float f = static_cast<float>(leaf);
  auto filter = [f](const typename Cloud::ConstPtr& cloud, Cloud* out) {
    pcl::VoxelGrid<Point> grid;
    grid.setInputCloud(cloud);
    grid.setLeafSize(f, f, f);
    grid.filter(*out);
  };
  auto out = pcl::make_shared<Cloud>();
  if (in->empty()) return out;
  // PCL's own count of the voxels the cloud spans, and its limit.
  Eigen::Vector4f lo, hi;
  pcl::getMinMax3D(*in, lo, hi);
  const float inverse = 1.0f / f;
  int64_t voxels = 1;
  for (int a = 0; a < 3; ++a) voxels *= static_cast<int64_t>((hi[a] - lo[a]) * inverse) + 1;
  if (voxels <= std::numeric_limits<int32_t>::max() / 2) {
    filter(in, out.get());
    return out;
  }
  constexpr int64_t kBlock = 1000;  // 1001^3 voxels at most per block: under PCL's limit
  std::map<std::array<int64_t, 3>, typename Cloud::Ptr> blocks;
  for (const Point& p : *in) {
    std::array<int64_t, 3> key;
    for (int a = 0; a < 3; ++a) {
      // The voxel index as VoxelGrid computes it, then its block.
      const auto voxel = static_cast<int64_t>(std::floor(p.data[a] * inverse));
      key[a] = voxel >= 0 ? voxel / kBlock : -((-voxel + kBlock - 1) / kBlock);
    }
    typename Cloud::Ptr& block = blocks[key];
    if (!block) block = pcl::make_shared<Cloud>();
    block->push_back(p);
  }
  Cloud part;
  for (const auto& [key, block] : blocks) {
    filter(block, &part);
    *out += part;
  }
  return out;
}

CloudXYZ::Ptr Downsample(const CloudXYZ::ConstPtr& in, double leaf) {
  return Downsample<PointXYZ>(in, leaf);
}

// Every k-th point of `in`, k the smallest that leaves at most `max_points` (all when they fit).
template <typename Point>
typename pcl::PointCloud<Point>::Ptr Thin(const typename pcl::PointCloud<Point>::Ptr& in,
                                          int64_t max_points) {
  const auto n = static_cast<int64_t>(in->size());
  if (n <= max_points) return in;
  const int64_t stride = (n + max_points - 1) / max_points;
  auto out = pcl::make_shared<pcl::PointCloud<Point>>();
  for (int64_t i = 0; i < n; i += stride) out->push_back((*in)[i]);
  return out;
}

// A bound on the pairs of points of `cloud` closer than `radius`: for each point, the points in
// the 3 x 3 x 3 cells of edge `radius` around its own.
int64_t NeighbourPairBound(const CloudXYZ& cloud, double radius) {
  struct Key {
    int64_t x, y, z;
    bool operator==(const Key&) const = default;
  };
  struct Hash {
    size_t operator()(const Key& k) const {
      return std::hash<int64_t>()(k.x * 73856093 ^ k.y * 19349663 ^ k.z * 83492791);
    }
  };
  auto key = [radius](const PointXYZ& p) {
    return Key{static_cast<int64_t>(std::floor(p.x / radius)),
               static_cast<int64_t>(std::floor(p.y / radius)),
               static_cast<int64_t>(std::floor(p.z / radius))};
  };
  std::unordered_map<Key, int64_t, Hash> cells;
  for (const auto& p : cloud) ++cells[key(p)];
  int64_t pairs = 0;
  for (const auto& [k, count] : cells) {
    int64_t around = 0;
    for (int64_t dx = -1; dx <= 1; ++dx) {
      for (int64_t dy = -1; dy <= 1; ++dy) {
        for (int64_t dz = -1; dz <= 1; ++dz) {
          auto it = cells.find(Key{k.x + dx, k.y + dy, k.z + dz});
          if (it != cells.end()) around += it->second;
        }
      }
    }
    pairs += count * around;
  }
  return pairs;
}

// `box` widened by `by` on every side (m).
Eigen::AlignedBox2d Widened(const Eigen::AlignedBox2d& box, double by) {
  return Eigen::AlignedBox2d(box.min().array() - by, box.max().array() + by);
}

// The points of `in` inside `box` (x-y), in their order.
template <typename Point>
typename pcl::PointCloud<Point>::Ptr CropXY(const typename pcl::PointCloud<Point>::Ptr& in,
                                            const Eigen::AlignedBox2d& box) {
  auto out = pcl::make_shared<pcl::PointCloud<Point>>();
  for (const Point& p : *in) {
    if (box.contains(Eigen::Vector2d(p.x, p.y))) out->push_back(p);
  }
  return out;
}

// Points of `in` with surface normals estimated from their neighbours within `radius` in
// `surface` (in itself when null); those without a normal (too few neighbours) are left out.
NormalCloud::Ptr WithNormals(const CloudXYZ::Ptr& in, double radius,
                             const CloudXYZ::Ptr& surface = nullptr) {
  auto normals = pcl::make_shared<pcl::PointCloud<pcl::Normal>>();
  pcl::NormalEstimation<PointXYZ, pcl::Normal> ne;
  ne.setInputCloud(in);
  if (surface) ne.setSearchSurface(surface);
  ne.setRadiusSearch(radius);
  ne.compute(*normals);
  auto out = pcl::make_shared<NormalCloud>();
  for (size_t i = 0; i < in->size(); ++i) {
    const auto& n = (*normals)[i];
    if (!std::isfinite(n.normal_x)) continue;
    PointNormal p;
    p.x = (*in)[i].x;
    p.y = (*in)[i].y;
    p.z = (*in)[i].z;
    p.normal_x = n.normal_x;
    p.normal_y = n.normal_y;
    p.normal_z = n.normal_z;
    p.curvature = n.curvature;
    out->push_back(p);
  }
  return out;
}

CloudXYZ::Ptr ToXYZ(const Cloud& in) {
  auto out = pcl::make_shared<CloudXYZ>();
  out->reserve(in.size());
  for (const auto& p : in) out->push_back(PointXYZ(p.x, p.y, p.z));
  return out;
}

// The grid values lo + k step (k >= 0, up to hi) that may fall in [from, to]: the first and last
// k, a range that is empty when first > last.
void GridRange(double lo, double hi, double step, double from, double to, int64_t* first,
               int64_t* last) {
  const double top = std::min(hi, to);
  *first = static_cast<int64_t>(std::max(0.0, std::ceil((from - lo) / step - 1e-9)));
  *last = top < lo ? -1 : static_cast<int64_t>(std::floor((top - lo) / step + 1e-9));
}

// Samples the surface of an upright box (top and four sides) on a grid of `step` (the grid of
// the whole box, from its corners), keeping the points inside `region` (x-y) and visiting only
// the part of each face that can reach it, so that a wall many tiles long costs each tile its
// own share. Each point carries the outward normal of the face it lies on (the map's geometry is
// known, so its normals are not estimated).
void SampleBoxWithin(const Box& b, double step, const Eigen::AlignedBox2d& region,
                     NormalCloud* out) {
  const double c = std::cos(b.yaw), s = std::sin(b.yaw);
  // A point at (lx, ly, lz) in the box's frame, on the face of outward normal (nx, ny, nz).
  auto emit = [&](double lx, double ly, double lz, double nx, double ny, double nz) {
    const double x = b.center.x() + c * lx - s * ly, y = b.center.y() + s * lx + c * ly;
    if (region.contains(Eigen::Vector2d(x, y))) {
      PointNormal p;
      p.x = static_cast<float>(x);
      p.y = static_cast<float>(y);
      p.z = static_cast<float>(b.center.z() + lz);
      p.normal_x = static_cast<float>(c * nx - s * ny);
      p.normal_y = static_cast<float>(s * nx + c * ny);
      p.normal_z = static_cast<float>(nz);
      p.curvature = 0.0f;
      out->push_back(p);
    }
  };
  // The region in the box's frame: the box of its corners turned by -yaw (covers it).
  Eigen::AlignedBox2d local;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d corner = region.corner(static_cast<Eigen::AlignedBox2d::CornerType>(k));
    const double dx = corner.x() - b.center.x(), dy = corner.y() - b.center.y();
    local.extend(Eigen::Vector2d(c * dx + s * dy, -s * dx + c * dy));
  }
  const Vec3 h = 0.5 * b.size;
  int64_t u0, u1, v0, v1, w0, w1;
  GridRange(-h.x(), h.x(), step, local.min().x(), local.max().x(), &u0, &u1);
  GridRange(-h.y(), h.y(), step, local.min().y(), local.max().y(), &v0, &v1);
  GridRange(-h.z(), h.z(), step, -h.z(), h.z(), &w0, &w1);
  // Whether the region reaches the sides at +-h.y (+-h.x).
  auto reaches = [](double lo, double hi, double half) {
    return (lo <= -half + 1e-9 && -half - 1e-9 <= hi) || (lo <= half + 1e-9 && half - 1e-9 <= hi);
  };
  const bool near_y = reaches(local.min().y(), local.max().y(), h.y());
  const bool near_x = reaches(local.min().x(), local.max().x(), h.x());
  for (int64_t i = u0; i <= u1; ++i) {
    const double u = -h.x() + static_cast<double>(i) * step;
    for (int64_t j = v0; j <= v1; ++j)
      emit(u, -h.y() + static_cast<double>(j) * step, h.z(), 0, 0, 1);
    if (!near_y) continue;
    for (int64_t k = w0; k <= w1; ++k) {
      const double w = -h.z() + static_cast<double>(k) * step;
      emit(u, -h.y(), w, 0, -1, 0);
      emit(u, h.y(), w, 0, 1, 0);
    }
  }
  if (!near_x) return;
  for (int64_t j = v0; j <= v1; ++j) {
    const double v = -h.y() + static_cast<double>(j) * step;
    for (int64_t k = w0; k <= w1; ++k) {
      const double w = -h.z() + static_cast<double>(k) * step;
      emit(-h.x(), v, w, -1, 0, 0);
      emit(h.x(), v, w, 1, 0, 0);
    }
  }
}

// A tracked object: its points (map frame, voxelised) and their statistics.
struct Track {
  std::string id;
  CloudXYZ::Ptr points = pcl::make_shared<CloudXYZ>();
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();
  int surface = -1;  // workspace it stands on
  Box box;           // fitted to all its points so far

  // Downsamples the points (coarser voxels until at most `max_points` remain) and refits the
  // statistics.
  void Refresh(double voxel, int64_t max_points) {
    points = Downsample(points, voxel);
    for (double leaf = 1.5 * voxel; static_cast<int64_t>(points->size()) > max_points;
         leaf *= 1.5) {
      points = Downsample(points, leaf);
    }
    centroid.setZero();
    for (const auto& p : *points) centroid += p.getVector3fMap().cast<double>();
    centroid /= std::max<size_t>(points->size(), 1);
    covariance.setZero();
    for (const auto& p : *points) {
      const Eigen::Vector3d d = p.getVector3fMap().cast<double>() - centroid;
      covariance += d * d.transpose();
    }
    covariance /= std::max<size_t>(points->size(), 1);
  }
};

// The extents of `points` along the horizontal axes at angle `yaw`: (min u, max u, min v, max v).
Eigen::Vector4d Extents(const CloudXYZ& points, const Eigen::Vector2d& origin, double yaw) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  Eigen::Vector4d e(1e9, -1e9, 1e9, -1e9);
  for (const auto& p : points) {
    const Eigen::Vector2d d = Eigen::Vector2d(p.x, p.y) - origin;
    const double u = c * d.x() + s * d.y(), v = -s * d.x() + c * d.y();
    e[0] = std::min(e[0], u);
    e[1] = std::max(e[1], u);
    e[2] = std::min(e[2], v);
    e[3] = std::max(e[3], v);
  }
  return e;
}

// The upright box of a set of points standing on a surface at `surface_height`. The yaw comes
// from PCA of the horizontal spread, and is replaced by the minimum-area rectangle's when that
// fits tighter (PCA is undetermined for square footprints and biased by partial views); the
// extents follow the chosen axes; the bottom is the surface.
Box FitBox(const CloudXYZ& points, double surface_height) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  double top = -1e9;
  std::vector<cv::Point2f> xy;
  xy.reserve(points.size());
  for (const auto& p : points) {
    mean += Eigen::Vector2d(p.x, p.y);
    top = std::max(top, static_cast<double>(p.z));
    xy.emplace_back(p.x, p.y);
  }
  mean /= static_cast<double>(points.size());
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (const auto& p : points) {
    const Eigen::Vector2d d = Eigen::Vector2d(p.x, p.y) - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(cov);
  const Eigen::Vector2d axis = eig.eigenvectors().col(1);  // largest eigenvalue
  double yaw = std::atan2(axis.y(), axis.x());
  Eigen::Vector4d e = Extents(points, mean, yaw);
  const cv::RotatedRect rect = cv::minAreaRect(xy);
  const double rect_yaw = rect.angle * std::numbers::pi / 180.0;
  const Eigen::Vector4d re = Extents(points, mean, rect_yaw);
  if ((re[1] - re[0]) * (re[3] - re[2]) < (e[1] - e[0]) * (e[3] - e[2])) {
    yaw = rect_yaw;
    e = re;
  }
  const double c = std::cos(yaw), s = std::sin(yaw);
  const double mu = 0.5 * (e[0] + e[1]), mv = 0.5 * (e[2] + e[3]);
  Box b;
  b.yaw = yaw;
  b.center =
      Vec3(mean.x() + c * mu - s * mv, mean.y() + s * mu + c * mv, 0.5 * (surface_height + top));
  b.size = Vec3(std::max(e[1] - e[0], 0.01), std::max(e[3] - e[2], 0.01),
                std::max(top - surface_height, 0.01));
  return b;
}

// Distance from a point to a box (0 inside).
double DistanceToBox(const Box& b, const PointXYZ& p) {
  const Vec3 l = b.ToLocal(Vec3(p.x, p.y, p.z));
  const Vec3 outside = (l.cwiseAbs() - 0.5 * b.size).cwiseMax(0.0);
  return outside.norm();
}

// The prior map is built in square tiles of this side (m), each when a frame first needs it,
// from the furniture and the floor around it (sampled this far past its edges, so that a voxel
// on its edge averages the same points, and normals, as if the whole map were sampled at once).
constexpr double kTileSide = 2.0;
constexpr double kTilePad = 0.1;

// The tile of a map coordinate (tiles are aligned with the map's origin).
int64_t TileIndex(double v) { return static_cast<int64_t>(std::floor(v / kTileSide)); }

// One tile of the prior map: the furniture surfaces and the floor inside it, voxelised; their
// normals at twice the voxel (ICP's target); and those of its points high enough for
// segmentation to compare object points with.
struct MapTile {
  CloudXYZ::Ptr points;
  NormalCloud::Ptr normals;
  CloudXYZ::Ptr upper;
  std::unique_ptr<pcl::KdTreeFLANN<PointXYZ>> upper_tree;  // null when `upper` is empty
  int64_t last_used = 0;                                   // the frame that needed it last
  // What it counts against max_map_points: its points (the upper ones twice, for their tree),
  // and at least 1,000 for the tile itself, so that the tiles kept are bounded too.
  int64_t size() const {
    return std::max<int64_t>(
        1000, static_cast<int64_t>(points->size() + normals->size() + 2 * upper->size()));
  }
};

// The part of the prior map one frame needs, gathered from the tiles.
struct LocalMap {
  // The tiles it was gathered from, by index (valid until the next frame's map is gathered).
  std::map<std::pair<int64_t, int64_t>, const MapTile*> tiles;
  NormalCloud::Ptr normals = pcl::make_shared<NormalCloud>();  // within the registration reach
  // Object points are looked for within this x-y box (the frame's workspace points near the
  // camera), whose tiles it holds.
  Eigen::AlignedBox2d segmentation_region;

  // Whether a map point high enough for segmentation lies within `distance` of p (which is
  // inside the segmentation region): asks the tiles within `distance` of it.
  bool NearMap(const PointXYZ& p, double distance) const {
    thread_local std::vector<int> nearest(1);
    thread_local std::vector<float> squared(1);
    for (int64_t ix = TileIndex(p.x - distance); ix <= TileIndex(p.x + distance); ++ix) {
      for (int64_t iy = TileIndex(p.y - distance); iy <= TileIndex(p.y + distance); ++iy) {
        const auto it = tiles.find({ix, iy});
        if (it == tiles.end() || !it->second->upper_tree) continue;
        if (it->second->upper_tree->nearestKSearch(p, 1, nearest, squared) > 0 &&
            squared[0] < distance * distance) {
          return true;
        }
      }
    }
    return false;
  }
};

// What registration (stage 1) gives the later stages.
struct Registration {
  CloudXYZ::Ptr in_map;                 // the frame's points in the map frame, at the reported pose
  std::shared_ptr<const LocalMap> map;  // the prior map around the frame
  Eigen::Matrix4d correction = Eigen::Matrix4d::Identity();     // of the reported pose
  Eigen::Matrix4d camera_to_map = Eigen::Matrix4d::Identity();  // the corrected camera pose
};

// What segmentation (stage 2) gives association and detection: the object points (map frame,
// corrected, voxelised), the workspace each stands on, and their Euclidean clusters (indices
// into the object points).
struct Segments {
  CloudXYZ::Ptr objects = pcl::make_shared<CloudXYZ>();
  std::vector<int> surface_of;
  std::vector<pcl::PointIndices> clusters;
};

}  // namespace

Status CameraIntrinsics::Validate() const {
  if (width < 8 || height < 8 || width > 8192 || height > 8192) {
    return InvalidFieldError("camera", "width and height must be in [8, 8192]");
  }
  if (!(fx > 0) || !(fy > 0) || !std::isfinite(fx) || !std::isfinite(fy) || !std::isfinite(cx) ||
      !std::isfinite(cy)) {
    return InvalidFieldError("camera", "focal lengths must be positive and finite");
  }
  return OkStatus();
}

Status PerceptionOptions::Validate() const {
  for (double v :
       {voxel, icp_max_distance, icp_good_fitness, ransac_voxel, max_correction, registration_range,
        map_distance, max_object_height, cluster_tolerance, association_gate, association_distance,
        sift_ratio, match_threshold, gripper_max}) {
    if (!(v > 0) || !std::isfinite(v))
      return InvalidArgumentError("perception options must be > 0");
  }
  if (icp_iterations < 1 || min_cluster_points < 1 || max_cluster_points < min_cluster_points ||
      min_features < 1 || min_inliers < 4 || max_clusters < 1 || max_track_points < 1 ||
      max_total_track_points < 1 || max_ransac_points < 1 || max_ransac_map_points < 1 ||
      max_map_points < 1 || max_ransac_pairs < 1 || max_icp_points < 1 || max_features < 1 ||
      max_sift_pixels < 16 || max_sift_frame_pixels < 0 || max_sift_pairs < 0 ||
      max_image_boxes < 0) {
    return InvalidArgumentError("perception options: bad counts");
  }
  if (!(unboxed_score >= 0.0 && unboxed_score <= 1.0)) {
    return InvalidArgumentError("perception options: unboxed_score must be in [0, 1]");
  }
  return OkStatus();
}

Eigen::Matrix4d CameraToMap(const object_search::RobotDescription& robot,
                            const object_search::RobotConfig& config) {
  const object_search::CameraPose pose = object_search::CameraPoseFor(robot, config);
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  t.block<3, 1>(0, 0) = -pose.left;    // optical x: right
  t.block<3, 1>(0, 1) = -pose.up;      // optical y: down
  t.block<3, 1>(0, 2) = pose.forward;  // optical z: forward
  t.block<3, 1>(0, 3) = pose.position;
  return t;
}

struct Perception::Impl {
  object_search::World world;
  TargetModel target;
  PerceptionOptions options;
  // The prior map's tiles built so far (by index), the points they hold together, and the
  // frames registered (the tiles' clock). Least recently used tiles past
  // options.max_map_points are dropped and built again when a frame needs them.
  std::map<std::pair<int64_t, int64_t>, MapTile> tiles;
  int64_t tile_points = 0;
  int64_t frames = 0;
  // Segmentation asks only whether a point standing on a workspace (higher than its surface by
  // 5 mm) lies within map_distance of the map: map points lower than this never answer, and the
  // floor is most of a room's map.
  double upper_min_z = 0.0;
  std::vector<Track> tracks;
  int next_id = 0;
  cv::Ptr<cv::SIFT> sift;  // keeps options.max_features keypoints
  std::vector<cv::Mat> photo_descriptors;
  std::vector<std::vector<cv::KeyPoint>> photo_keypoints;
  int64_t photo_features = 0;  // keypoints over every photo: a region's matching costs this each
  std::vector<cv::Mat> photo_histograms;

  cv::Mat Histogram(const cv::Mat& bgr, const cv::Mat& mask = cv::Mat()) const {
    cv::Mat hsv, hist;
    cv::cvtColor(bgr, hsv, cv::COLOR_BGR2HSV);
    const int channels[] = {0, 1};
    const int bins[] = {30, 32};
    const float hue[] = {0, 180}, sat[] = {0, 256};
    const float* ranges[] = {hue, sat};
    cv::calcHist(&hsv, 1, channels, mask, hist, 2, bins, ranges);
    cv::normalize(hist, hist, 0, 1, cv::NORM_MINMAX);
    return hist;
  }

  // FPFH features of `cloud` downsampled at ransac_voxel and, with `max_points` > 0, thinned to
  // at most that many points (every k-th). Points whose feature is not finite are dropped.
  void ComputeRansacFeatures(const CloudXYZ::Ptr& cloud, int64_t max_points, CloudXYZ::Ptr* down,
                             pcl::PointCloud<pcl::FPFHSignature33>::Ptr* features) const {
    *down = Downsample(cloud, options.ransac_voxel);
    if (max_points > 0) *down = Thin<PointXYZ>(*down, max_points);
    // Each feature weighs every neighbour within its radius: bounded by thinning the cloud,
    // which divides the pairs by the square of the stride.
    const double radius = 5.0 * options.ransac_voxel;
    for (int64_t pairs = NeighbourPairBound(**down, radius); pairs > options.max_ransac_pairs;
         pairs = NeighbourPairBound(**down, radius)) {
      const auto stride = static_cast<int64_t>(
          std::ceil(std::sqrt(static_cast<double>(pairs) / options.max_ransac_pairs)));
      *down = Thin<PointXYZ>(*down,
                             static_cast<int64_t>((*down)->size()) / std::max<int64_t>(2, stride));
    }
    auto normals = pcl::make_shared<pcl::PointCloud<pcl::Normal>>();
    pcl::NormalEstimation<PointXYZ, pcl::Normal> ne;
    ne.setInputCloud(*down);
    ne.setRadiusSearch(3.0 * options.ransac_voxel);
    ne.compute(*normals);
    *features = pcl::make_shared<pcl::PointCloud<pcl::FPFHSignature33>>();
    pcl::FPFHEstimation<PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh;
    fpfh.setInputCloud(*down);
    fpfh.setInputNormals(normals);
    fpfh.setRadiusSearch(radius);
    fpfh.compute(**features);
    // PCL weights a neighbour's histogram by 1 / squared distance: two points a float denormal
    // apart make that inf and the feature NaN, on which the consensus' feature k-d tree asserts
    // and aborts the process.
    auto kept = pcl::make_shared<CloudXYZ>();
    auto kept_features = pcl::make_shared<pcl::PointCloud<pcl::FPFHSignature33>>();
    for (size_t i = 0; i < (*features)->size(); ++i) {
      const auto& h = (**features)[i].histogram;
      if (std::all_of(std::begin(h), std::end(h), [](float v) { return std::isfinite(v); })) {
        kept->push_back((**down)[i]);
        kept_features->push_back((**features)[i]);
      }
    }
    *down = kept;
    *features = kept_features;
  }

  // The stages of Process, in pipeline order (defined with it, below).

  // Stage 1, registration: takes the checked frame, gives its points in the map frame, the
  // prior map around them and the corrected pose; sets `result`'s correction, fitness,
  // used_ransac and achieved pose.
  Registration Register(const SensorFrame& frame, PerceptionResult* result);
  // Takes a tile's index, gives the tile (built when missing), marked used by this frame.
  const MapTile& Tile(int64_t ix, int64_t iy);
  // Takes the registration reach and segmentation's region, gives the prior map a frame needs
  // there (building the tiles it lacks, then dropping old ones past the bound).
  std::shared_ptr<const LocalMap> MapFor(const Eigen::AlignedBox2d& reach,
                                         const Eigen::AlignedBox2d& segmentation);
  // Takes a map-frame point, gives whether it stands on a workspace (within `margin` of it in
  // x-y, below max_object_height above it) and which one in *which (when not null).
  bool OnWorkspace(const PointXYZ& p, double margin, int* which) const;
  // Takes the frame's map-frame points, gives those to register with: the static structure;
  // extends *on_workspaces by the x-y of the points that may stand on a workspace.
  CloudXYZ::Ptr StaticStructure(const CloudXYZ::Ptr& in_map,
                                Eigen::AlignedBox2d* on_workspaces) const;
  // Takes the structure and the camera position, gives the x-y box of the map to align with.
  Eigen::AlignedBox2d RegistrationReach(const CloudXYZ& structure,
                                        const Eigen::Vector3d& camera) const;
  // Takes the structure and the reach, gives ICP's correction (RANSAC-initialised when ICP from
  // the reported pose fits poorly), its fitness in *fitness, and *used_ransac when RANSAC's
  // alignment was kept.
  Eigen::Matrix4d Align(const CloudXYZ::Ptr& structure, const LocalMap& map,
                        const Eigen::AlignedBox2d& reach, double* fitness, bool* used_ransac) const;
  // Takes the structure and the reach, gives RANSAC's global alignment on FPFH features in
  // *guess; false when it has none worth refining.
  bool RansacGuess(const CloudXYZ::Ptr& structure, const LocalMap& map,
                   const Eigen::AlignedBox2d& reach, Eigen::Matrix4f* guess) const;

  // Stage 2, map-point removal: takes the frame's registration, gives the object points
  // (without clusters).
  Segments ObjectPoints(const Registration& reg) const;
  // Stage 2, segmentation: takes the object points, gives their Euclidean clusters.
  std::vector<pcl::PointIndices> EuclideanClusters(const CloudXYZ::Ptr& objects) const;

  // Stage 3, association: takes the clusters, gives the track of each (new tracks for the
  // unmatched); the tracks take the clusters' points.
  std::vector<int> Associate(const Segments& segments);
  // Takes a cluster's points and the tracks already taken this frame, gives the track it
  // continues, or -1.
  int MatchingTrack(const CloudXYZ& cluster, const std::vector<bool>& taken) const;

  // Stage 4, detection: takes the clusters and their tracks, gives one detection per cluster
  // (target score, visible faces, moveability). `perception` scores the image regions.
  // With the robot's detector's boxes, *box_objects gets the track id each box was given to.
  std::vector<object_search::ObjectDetection> Detect(const Perception& perception,
                                                     const SensorFrame& frame,
                                                     const Eigen::Matrix4d& camera_to_map,
                                                     const Segments& segments,
                                                     const std::vector<int>& track_of,
                                                     std::vector<std::string>* box_objects) const;
  // Takes one cluster, gives the probability that it is the target (the frame's SIFT budgets
  // spent from *sift_pixels and *sift_pairs).
  double ClusterScore(const Perception& perception, const SensorFrame& frame,
                      const Eigen::Matrix4d& map_to_camera, const CloudXYZ& objects,
                      const pcl::PointIndices& cluster, int64_t* sift_pixels,
                      int64_t* sift_pairs) const;
  // Takes one cluster, gives the pixels its points cover: their bounding rectangle in the image
  // (*rect) and a mask of that size; false when that is less than 4 x 4 pixels.
  bool ClusterMask(const CameraIntrinsics& in, const Eigen::Matrix4d& map_to_camera,
                   const CloudXYZ& objects, const pcl::PointIndices& cluster, cv::Rect* rect,
                   cv::Mat* mask) const;
  // Takes one cluster, gives the masked sub-image it covers in *region and *mask (scaled down
  // to options.max_sift_pixels); false when that is less than 4 x 4 pixels.
  bool ClusterRegion(const SensorFrame& frame, const Eigen::Matrix4d& map_to_camera,
                     const CloudXYZ& objects, const pcl::PointIndices& cluster, cv::Mat* region,
                     cv::Mat* mask) const;
  // Takes the clusters and the robot's detector's boxes, gives each cluster's probability of
  // being the target (0.5 when it covers too few pixels to say) and, per box, the index of the
  // cluster it was given to (-1 for none).
  std::vector<double> BoxScores(const SensorFrame& frame, const Eigen::Matrix4d& map_to_camera,
                                const Segments& segments, std::vector<int>* box_cluster) const;
  // Takes an object's box, gives its moveability.
  double Moveability(const Box& box) const;
};

// Thins `tracks` to at most options.max_total_track_points together: the largest cap c with
// sum(min(size, c)) within the budget (water-filling), every track above c thinned to at most c,
// so that small tracks keep every point and large ones share what is left.
void ThinToTotal(std::vector<Track>* tracks, const PerceptionOptions& options,
                 const std::vector<object_search::Workspace>& workspaces) {
  std::vector<int64_t> sizes;
  int64_t total = 0;
  for (const Track& t : *tracks) {
    sizes.push_back(static_cast<int64_t>(t.points->size()));
    total += sizes.back();
  }
  if (total <= options.max_total_track_points) return;
  std::sort(sizes.begin(), sizes.end());
  int64_t budget = options.max_total_track_points, cap = 1;
  for (size_t i = 0; i < sizes.size(); ++i) {
    const auto left = static_cast<int64_t>(sizes.size() - i);
    if (sizes[i] * left > budget) {
      cap = std::max<int64_t>(1, budget / left);
      break;
    }
    budget -= sizes[i];
  }
  for (Track& t : *tracks) {
    if (static_cast<int64_t>(t.points->size()) <= cap) continue;
    t.Refresh(options.voxel, cap);
    t.box = FitBox(*t.points, workspaces[t.surface].height);
  }
}

Perception::Perception(const object_search::World& world, TargetModel target,
                       PerceptionOptions options)
    : impl_(std::make_unique<Impl>()) {
  Impl& im = *impl_;
  im.world = world;
  im.target = std::move(target);
  im.options = options;
  im.sift = cv::SIFT::create(options.max_features);
  // The prior map is built tile by tile as frames need it (Impl::MapFor).
  double lowest = std::numeric_limits<double>::infinity();
  for (const auto& ws : world.grid.workspaces()) lowest = std::min(lowest, ws.height);
  im.upper_min_z = lowest + 0.005 - options.map_distance - 1e-3;
  for (const cv::Mat& photo : im.target.photos) {
    if (photo.empty()) continue;
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    cv::Mat gray;
    cv::cvtColor(photo, gray, cv::COLOR_BGR2GRAY);
    // Scaled down as large image regions are: SIFT's pyramid of a 4-megapixel photo takes about
    // a gigabyte.
    const int64_t area = int64_t{gray.cols} * gray.rows;
    if (area > options.max_sift_pixels) {
      const double f = std::sqrt(static_cast<double>(options.max_sift_pixels) / area);
      cv::resize(gray, gray,
                 cv::Size(std::max(4, static_cast<int>(gray.cols * f)),
                          std::max(4, static_cast<int>(gray.rows * f))),
                 0, 0, cv::INTER_AREA);
    }
    im.sift->detectAndCompute(gray, cv::noArray(), keypoints, descriptors);
    if (!descriptors.empty()) {
      im.photo_descriptors.push_back(descriptors);
      im.photo_keypoints.push_back(keypoints);
      im.photo_features += descriptors.rows;
    }
    im.photo_histograms.push_back(im.Histogram(photo));
  }
}

Perception::~Perception() = default;

int Perception::tracks() const { return static_cast<int>(impl_->tracks.size()); }

std::vector<TrackState> Perception::SaveTracks(int* next_id) const {
  std::vector<TrackState> out;
  for (const Track& t : impl_->tracks) {
    TrackState st;
    st.id = t.id;
    st.surface = t.surface;
    for (const auto& p : *t.points) st.points.insert(st.points.end(), {p.x, p.y, p.z});
    out.push_back(std::move(st));
  }
  *next_id = impl_->next_id;
  return out;
}

Status CheckTracks(const std::vector<TrackState>& tracks, int next_id,
                   const object_search::World& world) {
  const auto& workspaces = world.grid.workspaces();
  if (next_id < 0) return InvalidArgumentError("perception tracks: negative next id");
  for (const TrackState& st : tracks) {
    if (st.id.empty() || st.points.empty() || st.points.size() % 3 != 0 || st.surface < 0 ||
        st.surface >= static_cast<int>(workspaces.size())) {
      return InvalidArgumentError("perception track '" + st.id + "' is malformed");
    }
  }
  return OkStatus();
}

Status Perception::RestoreTracks(const std::vector<TrackState>& tracks, int next_id) {
  if (Status s = CheckTracks(tracks, next_id, impl_->world); !s.ok()) return s;
  const auto& workspaces = impl_->world.grid.workspaces();
  std::vector<Track> restored;
  for (const TrackState& st : tracks) {
    Track t;
    t.id = st.id;
    t.surface = st.surface;
    for (size_t i = 0; i < st.points.size(); i += 3) {
      t.points->push_back(PointXYZ(st.points[i], st.points[i + 1], st.points[i + 2]));
    }
    t.Refresh(impl_->options.voxel, impl_->options.max_track_points);
    t.box = FitBox(*t.points, workspaces[t.surface].height);
    restored.push_back(std::move(t));
  }
  ThinToTotal(&restored, impl_->options, workspaces);
  impl_->tracks = std::move(restored);
  impl_->next_id = next_id;
  return OkStatus();
}

bool Perception::DropTrack(const std::string& id) {
  auto& tracks = impl_->tracks;
  const auto it =
      std::find_if(tracks.begin(), tracks.end(), [&](const Track& t) { return t.id == id; });
  if (it == tracks.end()) return false;
  tracks.erase(it);
  return true;
}

Cloud::ConstPtr Perception::map() const {
  auto out = pcl::make_shared<Cloud>();
  for (const auto& [index, tile] : impl_->tiles) {
    for (const auto& p : *tile.points) {
      pcl::PointXYZRGB q;
      q.x = p.x;
      q.y = p.y;
      q.z = p.z;
      out->push_back(q);
    }
  }
  return out;
}

int64_t Perception::map_tiles() const { return static_cast<int64_t>(impl_->tiles.size()); }

// ---- the prior map, by tiles ----

const MapTile& Perception::Impl::Tile(int64_t ix, int64_t iy) {
  auto [it, missing] = tiles.try_emplace({ix, iy});
  MapTile& t = it->second;
  t.last_used = frames;
  if (!missing) return t;
  const Eigen::AlignedBox2d padded =
      Widened(Eigen::AlignedBox2d(Eigen::Vector2d(ix * kTileSide, iy * kTileSide),
                                  Eigen::Vector2d((ix + 1) * kTileSide, (iy + 1) * kTileSide)),
              kTilePad);
  // The furniture's surfaces and the floor on the same grids as if the whole map were sampled
  // at once, so that a voxel (aligned with the origin, as the tiles are) gets the same points.
  auto raw = pcl::make_shared<NormalCloud>();
  for (const Box& b : world.furniture) SampleBoxWithin(b, 0.5 * options.voxel, padded, raw.get());
  const auto& occ = world.occupancy;
  const double step = 2.0 * options.voxel;
  int64_t x0, x1, y0, y1;
  GridRange(occ.min().x(), occ.max().x(), step, padded.min().x(), padded.max().x(), &x0, &x1);
  GridRange(occ.min().y(), occ.max().y(), step, padded.min().y(), padded.max().y(), &y0, &y1);
  PointNormal floor;
  floor.z = 0.0f;
  floor.normal_x = floor.normal_y = floor.curvature = 0.0f;
  floor.normal_z = 1.0f;
  for (int64_t i = x0; i <= x1; ++i) {
    for (int64_t j = y0; j <= y1; ++j) {
      floor.x = static_cast<float>(occ.min().x() + static_cast<double>(i) * step);
      floor.y = static_cast<float>(occ.min().y() + static_cast<double>(j) * step);
      raw->push_back(floor);
    }
  }
  // The voxels average the faces' normals: where faces meet (an edge, a table's top over its
  // side) the normal leans between them, as one estimated from the neighbours would; where
  // opposite faces share a voxel (a sheet thinner than it) they cancel and the point is left out.
  const NormalCloud::Ptr around = Downsample<PointNormal>(raw, options.voxel);
  const NormalCloud::Ptr coarse = Downsample<PointNormal>(around, 2.0 * options.voxel);
  auto own = [&](const auto& p) { return TileIndex(p.x) == ix && TileIndex(p.y) == iy; };
  t.points = pcl::make_shared<CloudXYZ>();
  t.upper = pcl::make_shared<CloudXYZ>();
  t.normals = pcl::make_shared<NormalCloud>();
  for (const auto& p : *around) {
    if (!own(p)) continue;
    t.points->push_back(PointXYZ(p.x, p.y, p.z));
    if (p.z > upper_min_z) t.upper->push_back(PointXYZ(p.x, p.y, p.z));
  }
  for (PointNormal p : *coarse) {
    const float length = p.getNormalVector3fMap().norm();
    if (!own(p) || !(length > 0.5f)) continue;
    p.getNormalVector3fMap() /= length;
    t.normals->push_back(p);
  }
  if (!t.upper->empty()) {
    t.upper_tree = std::make_unique<pcl::KdTreeFLANN<PointXYZ>>();
    t.upper_tree->setInputCloud(t.upper);
  }
  tile_points += t.size();
  return t;
}

std::shared_ptr<const LocalMap> Perception::Impl::MapFor(const Eigen::AlignedBox2d& reach,
                                                         const Eigen::AlignedBox2d& segmentation) {
  ++frames;
  auto local = std::make_shared<LocalMap>();
  // RANSAC's map features need the points this far past the reach (RansacGuess gathers them).
  const Eigen::AlignedBox2d features = Widened(reach, 8.0 * options.ransac_voxel);
  const Eigen::AlignedBox2d near = Widened(segmentation, options.map_distance);
  const Eigen::AlignedBox2d bounds(world.occupancy.min(), world.occupancy.max());
  const Eigen::AlignedBox2d needed = Widened(features.merged(near).intersection(bounds), 1e-6);
  if (!needed.isEmpty()) {
    for (int64_t ix = TileIndex(needed.min().x()); ix <= TileIndex(needed.max().x()); ++ix) {
      for (int64_t iy = TileIndex(needed.min().y()); iy <= TileIndex(needed.max().y()); ++iy) {
        const MapTile& t = Tile(ix, iy);
        local->tiles[{ix, iy}] = &t;
        for (const auto& p : *t.normals) {
          if (reach.contains(Eigen::Vector2d(p.x, p.y))) local->normals->push_back(p);
        }
      }
    }
  }
  local->segmentation_region = segmentation;
  // Past the bound, the tiles this frame did not need go, the least recently used first.
  while (tile_points > options.max_map_points) {
    auto oldest = tiles.end();
    for (auto it = tiles.begin(); it != tiles.end(); ++it) {
      if (it->second.last_used < frames &&
          (oldest == tiles.end() || it->second.last_used < oldest->second.last_used)) {
        oldest = it;
      }
    }
    if (oldest == tiles.end()) break;
    tile_points -= oldest->second.size();
    tiles.erase(oldest);
  }
  return local;
}

double Perception::TargetScore(const cv::Mat& region, bool* used_colour,
                               const cv::Mat& mask) const {
  int64_t unbounded = std::numeric_limits<int64_t>::max();
  return ScoreRegion(region, mask, &unbounded, used_colour);
}

double Perception::ScoreRegion(const cv::Mat& region, const cv::Mat& mask, int64_t* sift_pairs,
                               bool* used_colour) const {
  const Impl& im = *impl_;
  if (used_colour != nullptr) *used_colour = false;
  if (region.empty() || im.target.photos.empty()) return 0.5;
  // Evidence in log-odds, from two cues:
  //  - SIFT: keypoints matched to a photo (Lowe's ratio test) that agree on one planar mapping
  //    (the photo's face seen in perspective). Consistent matches are strong evidence for the
  //    target; their absence is evidence against only in proportion to the keypoints found (a
  //    small or far region has too few for SIFT to decide either way).
  //  - colour: the hue-saturation histogram against the photos'. A mismatch rules the target
  //    out; a match is weak evidence (look-alikes share colours).
  cv::Mat gray;
  cv::cvtColor(region, gray, cv::COLOR_BGR2GRAY);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  const bool masked = !mask.empty() && mask.size() == region.size() && mask.type() == CV_8U;
  if (sift_pairs != nullptr) {
    im.sift->detectAndCompute(gray, masked ? mask : cv::Mat(), keypoints, descriptors);
  }
  int n = static_cast<int>(keypoints.size());
  if (sift_pairs != nullptr && int64_t{n} * im.photo_features > *sift_pairs) n = 0;  // over budget
  if (n > 0) *sift_pairs -= int64_t{n} * im.photo_features;
  int inliers = 0;
  if (n >= im.options.min_features) {
    cv::BFMatcher matcher(cv::NORM_L2);
    for (size_t k = 0; k < im.photo_descriptors.size(); ++k) {
      std::vector<std::vector<cv::DMatch>> knn;
      matcher.knnMatch(descriptors, im.photo_descriptors[k], knn, 2);
      std::vector<cv::Point2f> from, to;
      for (const auto& m : knn) {
        if (m.size() == 2 && m[0].distance < im.options.sift_ratio * m[1].distance) {
          from.push_back(keypoints[m[0].queryIdx].pt);
          to.push_back(im.photo_keypoints[k][m[0].trainIdx].pt);
        }
      }
      if (from.size() >= 5) {
        std::vector<uchar> mask;
        const cv::Mat homography = cv::findHomography(from, to, cv::RANSAC, 4.0, mask);
        // Most matches of a true view agree; chance matches between look-alike textures give
        // a homography that only a minority supports.
        const int agreeing = homography.empty() ? 0 : cv::countNonZero(mask);
        if (2 * agreeing >= static_cast<int>(from.size())) inliers = std::max(inliers, agreeing);
      }
    }
  }
  double sift = 0.0;
  if (n >= im.options.min_features && !im.photo_descriptors.empty()) {
    const double expected = im.options.match_threshold * n;  // inliers a target view would give
    if (inliers >= im.options.min_inliers) {
      sift = 3.0 * std::min(1.0, static_cast<double>(inliers) / (2.0 * im.options.min_inliers));
    } else {
      // A few missing matches mean nothing: small regions give few even for the target.
      sift = -std::min(2.0, 0.25 * std::max(0.0, expected - 0.5 * im.options.min_inliers));
    }
  }
  const cv::Mat hist = im.Histogram(region, masked ? mask : cv::Mat());
  double colour_corr = -1.0;
  for (const cv::Mat& h : im.photo_histograms) {
    colour_corr = std::max(colour_corr, cv::compareHist(hist, h, cv::HISTCMP_CORREL));
  }
  // Below 0.15 the colours differ (-3); from 0.5 they agree (+0.5).
  const double colour = colour_corr < 0.35 ? -3.0 * std::min(1.0, (0.35 - colour_corr) / 0.2)
                                           : 0.5 * std::min(1.0, (colour_corr - 0.35) / 0.15);
  if (used_colour != nullptr) *used_colour = sift == 0.0;
  if (std::getenv("NPFKCT_DEBUG_TARGET")) {
    std::fprintf(stderr, "  region %dx%d keypoints %d inliers %d colour %.2f -> %.2f %.2f\n",
                 region.cols, region.rows, n, inliers, colour_corr, sift, colour);
  }
  return std::clamp(1.0 / (1.0 + std::exp(-(sift + colour))), 0.05, 0.95);
}

namespace {

// ---- input checks: nothing changes on error ----

// Takes the frame's cloud, gives an error unless it has points, at most options.max_points, all
// finite and within options.max_coordinate.
Status CheckCloud(const Cloud::ConstPtr& cloud, const PerceptionOptions& o) {
  if (!cloud || cloud->empty()) {
    return InvalidFieldError("pointCloud.data", "the cloud is empty");
  }
  if (static_cast<int64_t>(cloud->size()) > o.max_points) {
    return InvalidFieldError("pointCloud.data",
                             "more than " + std::to_string(o.max_points) + " points");
  }
  for (size_t i = 0; i < cloud->size(); ++i) {
    const auto& p = (*cloud)[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return InvalidFieldError(
          "pointCloud.data",
          "point " + std::to_string(i) + " is not finite (drop NaN points before sending)");
    }
    if (std::abs(p.x) > o.max_coordinate || std::abs(p.y) > o.max_coordinate ||
        std::abs(p.z) > o.max_coordinate) {
      return InvalidFieldError("pointCloud.data",
                               "point " + std::to_string(i) + " has a coordinate beyond " +
                                   std::to_string(static_cast<int64_t>(o.max_coordinate)) + " m");
    }
  }
  return OkStatus();
}

// Takes a cloud said to be in the camera's optical frame, gives an error unless it lies in
// front of the camera and inside its field of view, as a camera's cloud does.
Status CheckOpticalFrame(const Cloud& cloud, const CameraIntrinsics& in) {
  size_t behind = 0, outside = 0;
  for (const auto& p : cloud) {
    if (p.z <= 0.0f) {
      ++behind;
      continue;
    }
    const double u = in.fx * p.x / p.z + in.cx, v = in.fy * p.y / p.z + in.cy;
    outside +=
        u < -0.1 * in.width || u > 1.1 * in.width || v < -0.1 * in.height || v > 1.1 * in.height;
  }
  const size_t n = cloud.size();
  if (behind * 20 > n) {
    return InvalidFieldError(
        "pointCloud.frame",
        std::to_string(100 * behind / n) +
            "% of the points are behind the camera; is the cloud really in the camera frame?");
  }
  if (outside * 20 > n) {
    return InvalidFieldError(
        "pointCloud.frame",
        std::to_string(100 * outside / n) +
            "% of the points fall outside the camera's field of view; is the cloud really in the "
            "camera's optical frame, and are the camera intrinsics right?");
  }
  return OkStatus();
}

// A number as it was given (up to 17 significant digits): a message never rounds a box's edge
// onto the image's.
std::string Exact(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// The detector's boxes: at most max_image_boxes, each finite, of positive size, inside the image,
// with a score in [0, 1]; errors name "imageBoxes[i].field".
Status CheckImageBoxes(const std::vector<ImageBox>& boxes, const CameraIntrinsics& in,
                       const PerceptionOptions& o) {
  if (boxes.size() > static_cast<size_t>(o.max_image_boxes)) {
    return InvalidFieldError("imageBoxes", std::to_string(boxes.size()) + " boxes; at most " +
                                               std::to_string(o.max_image_boxes));
  }
  for (size_t i = 0; i < boxes.size(); ++i) {
    const ImageBox& b = boxes[i];
    const std::string at = "imageBoxes[" + std::to_string(i) + "].";
    const std::pair<const char*, double> fields[] = {
        {"x", b.x}, {"y", b.y}, {"width", b.width}, {"height", b.height}, {"score", b.score}};
    for (const auto& [name, v] : fields) {
      if (!std::isfinite(v)) return InvalidFieldError(at + name, "must be a finite number");
    }
    if (!(b.score >= 0.0 && b.score <= 1.0)) {
      return InvalidFieldError(at + "score", "must be in [0, 1]");
    }
    if (!(b.width > 0.0)) return InvalidFieldError(at + "width", "must be > 0");
    if (!(b.height > 0.0)) return InvalidFieldError(at + "height", "must be > 0");
    if (b.x < 0.0 || b.x + b.width > in.width) {
      return InvalidFieldError(at + "x", "the box spans x in [" + Exact(b.x) + ", " +
                                             Exact(b.x + b.width) + "]; the image is " +
                                             std::to_string(in.width) + " pixels wide");
    }
    if (b.y < 0.0 || b.y + b.height > in.height) {
      return InvalidFieldError(at + "y", "the box spans y in [" + Exact(b.y) + ", " +
                                             Exact(b.y + b.height) + "]; the image is " +
                                             std::to_string(in.height) + " pixels high");
    }
  }
  return OkStatus();
}

// Takes the frame, gives an error unless every check above passes and the image, when given,
// is 3-channel of the camera's size, and the detector's boxes, when given, pass theirs.
Status CheckFrame(const SensorFrame& frame, const PerceptionOptions& o) {
  if (Status s = frame.intrinsics.Validate(); !s.ok()) return s;
  if (Status s = CheckCloud(frame.cloud, o); !s.ok()) return s;
  if (!frame.cloud_in_map_frame) {
    if (Status s = CheckOpticalFrame(*frame.cloud, frame.intrinsics); !s.ok()) return s;
  }
  if (!frame.image.empty() &&
      (frame.image.cols != frame.intrinsics.width || frame.image.rows != frame.intrinsics.height ||
       frame.image.type() != CV_8UC3)) {
    return InvalidFieldError("image.data", "the image is " + std::to_string(frame.image.cols) +
                                               "x" + std::to_string(frame.image.rows) +
                                               " (3 channels expected), the camera says " +
                                               std::to_string(frame.intrinsics.width) + "x" +
                                               std::to_string(frame.intrinsics.height));
  }
  if (frame.image_boxes) return CheckImageBoxes(*frame.image_boxes, frame.intrinsics, o);
  return OkStatus();
}

// Takes ICP's source points (with normals), gives whether their surfaces constrain the pose.
// The point-to-plane step solves a 6x6 least-squares system in (rotation, translation); when the
// visible surfaces leave a direction free (only a floor and table tops, say) the system is
// singular and the step degenerates, so the reported pose is kept.
bool ConstrainsPose(const NormalCloud& source, double min_structure) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : source) mean += Eigen::Vector3d(p.x, p.y, p.z);
  mean /= std::max<size_t>(source.size(), 1);
  Eigen::Matrix<double, 6, 6> system = Eigen::Matrix<double, 6, 6>::Zero();
  for (const auto& p : source) {
    const Eigen::Vector3d n(p.normal_x, p.normal_y, p.normal_z);
    Eigen::Matrix<double, 6, 1> row;
    row << (Eigen::Vector3d(p.x, p.y, p.z) - mean).cross(n), n;
    system += row * row.transpose();
  }
  const Eigen::Matrix<double, 6, 1> directions =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(system).eigenvalues();
  return directions[0] > min_structure * directions[5];
}

// Takes the reported base pose and the map-frame correction, gives the corrected base pose: the
// correction applied to the base's position and heading.
object_search::RobotConfig CorrectedPose(const object_search::RobotConfig& reported,
                                         const Eigen::Matrix4d& correction) {
  object_search::RobotConfig corrected = reported;
  const Eigen::Vector4d base = correction * Eigen::Vector4d(reported.x, reported.y, 0, 1);
  corrected.x = base.x();
  corrected.y = base.y();
  corrected.yaw =
      object_search::WrapAngle(reported.yaw + std::atan2(correction(1, 0), correction(0, 0)));
  return corrected;
}

// Visible faces: takes the boxes of the frame's detections, one of them (`c`) and its target
// score, gives the face grids that get the detection: of its corners, the four nearest the
// camera that project into the image and that no other object hides.
std::vector<object_search::FaceDetection> VisibleFaces(const std::vector<Box>& boxes, size_t c,
                                                       double score,
                                                       const Eigen::Matrix4d& map_to_camera,
                                                       const Vec3& camera_position,
                                                       const CameraIntrinsics& intrinsics) {
  std::vector<object_search::FaceDetection> faces;
  const Box& box = boxes[c];
  const auto corners = box.Corners();
  for (int k : object_search::NearestCorners(corners, camera_position)) {
    const Vec3 p = corners[k] + 0.05 * (box.center - corners[k]);
    const Eigen::Vector4d q = map_to_camera * Eigen::Vector4d(p.x(), p.y(), p.z(), 1);
    if (q.z() <= 0) continue;
    const double u = intrinsics.fx * q.x() / q.z() + intrinsics.cx;
    const double v = intrinsics.fy * q.y() / q.z() + intrinsics.cy;
    if (u < 0 || v < 0 || u >= intrinsics.width || v >= intrinsics.height) continue;
    bool hidden = false;
    for (size_t other = 0; other < boxes.size() && !hidden; ++other) {
      if (other != c) hidden = boxes[other].BlocksSegment(camera_position, p);
    }
    if (!hidden) faces.push_back({k, score});
  }
  return faces;
}

}  // namespace

// ---- 1. registration ----

Registration Perception::Impl::Register(const SensorFrame& frame, PerceptionResult* result) {
  const Eigen::Matrix4d reported = CameraToMap(world.robot, frame.reported);
  Registration reg;
  CloudXYZ::Ptr xyz = ToXYZ(*frame.cloud);
  reg.in_map = pcl::make_shared<CloudXYZ>();
  if (frame.cloud_in_map_frame) {
    *reg.in_map = *xyz;
  } else {
    pcl::transformPointCloud(*xyz, *reg.in_map, reported.cast<float>());
  }
  Eigen::AlignedBox2d on_workspaces;
  const CloudXYZ::Ptr structure = StaticStructure(reg.in_map, &on_workspaces);
  const Eigen::Vector3d camera = reported.block<3, 1>(0, 3);
  const Eigen::AlignedBox2d reach = RegistrationReach(*structure, camera);
  // Objects are looked for where the frame shows a workspace within registration_range of the
  // camera, give or take a correction: the map is built there and no farther.
  const Eigen::AlignedBox2d segmentation =
      Widened(on_workspaces, options.max_correction)
          .intersection(Widened(Eigen::AlignedBox2d(camera.head<2>(), camera.head<2>()),
                                options.registration_range + options.max_correction));
  reg.map = MapFor(reach, segmentation);
  double fitness = std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix4d correction = Align(structure, *reg.map, reach, &fitness, &result->used_ransac);
  if (correction.block<3, 1>(0, 3).norm() > options.max_correction || !correction.allFinite()) {
    correction.setIdentity();  // implausible: keep the reported pose
  }
  result->correction = correction;
  result->fitness = fitness;
  reg.correction = correction;
  reg.camera_to_map = frame.cloud_in_map_frame ? reported : Eigen::Matrix4d(correction * reported);
  result->observation.achieved = CorrectedPose(frame.reported, correction);
  return reg;
}

bool Perception::Impl::OnWorkspace(const PointXYZ& p, double margin, int* which) const {
  const auto& workspaces = world.grid.workspaces();
  for (size_t w = 0; w < workspaces.size(); ++w) {
    const auto& ws = workspaces[w];
    if (p.z > ws.height + 0.005 && p.z < ws.height + options.max_object_height &&
        ws.ContainsXY(object_search::Vec2(p.x, p.y), margin)) {
      if (which != nullptr) *which = static_cast<int>(w);
      return true;
    }
  }
  return false;
}

CloudXYZ::Ptr Perception::Impl::StaticStructure(const CloudXYZ::Ptr& in_map,
                                                Eigen::AlignedBox2d* on_workspaces) const {
  // Register with the static structure only: points standing on a workspace are probably the
  // unknown objects, which the map lacks and which would drag the alignment. Points outside the
  // mapped area have nothing to match and would drag it too.
  const auto& bounds = world.occupancy;
  CloudXYZ::Ptr structure = pcl::make_shared<CloudXYZ>();
  for (const auto& p : *in_map) {
    const bool on_workspace = OnWorkspace(p, 0.05, nullptr);
    if (on_workspace) on_workspaces->extend(Eigen::Vector2d(p.x, p.y));
    if (p.x < bounds.min().x() + 0.2 || p.y < bounds.min().y() + 0.2 ||
        p.x > bounds.max().x() - 0.2 || p.y > bounds.max().y() - 0.2) {
      continue;
    }
    if (!on_workspace) structure->push_back(p);
  }
  if (structure->size() < 100) structure = in_map;
  return structure;
}

Eigen::AlignedBox2d Perception::Impl::RegistrationReach(const CloudXYZ& structure,
                                                        const Eigen::Vector3d& camera) const {
  // The part of the map a correction could align the frame with: where the frame's structure
  // lies within registration_range of the camera, widened by the largest correction and ICP's
  // reach. Registration then costs what the view covers, not the size of the room (a 39 m room
  // made a frame's first registration 60 s and every later one 20 s).
  Eigen::AlignedBox2d view;  // empty (Eigen's default for a fixed size)
  for (const auto& p : structure) view.extend(Eigen::Vector2d(p.x, p.y));
  view = view.intersection(
      Widened(Eigen::AlignedBox2d(camera.head<2>(), camera.head<2>()), options.registration_range));
  return Widened(view, options.max_correction + options.icp_max_distance);
}

Eigen::Matrix4d Perception::Impl::Align(const CloudXYZ::Ptr& structure, const LocalMap& map,
                                        const Eigen::AlignedBox2d& reach, double* fitness_out,
                                        bool* used_ransac) const {
  const PerceptionOptions& o = options;
  // Point-to-plane ICP: the scene is mostly planes (floor, table tops, sides), along which
  // point-to-point ICP slides.
  // At most max_icp_points: each ICP iteration searches the map for every source point. They
  // are thinned by coarser voxels, which keep every surface's share of them (every k-th point
  // of the voxel grid's order dropped thin vertical surfaces, and the check below then took
  // views for unconstrained that are not); the normals are estimated for the points kept only,
  // from all their neighbours.
  const CloudXYZ::Ptr down = Downsample(structure, 2.0 * o.voxel);
  CloudXYZ::Ptr kept = down;
  for (double leaf = 3.0 * o.voxel; static_cast<int64_t>(kept->size()) > o.max_icp_points;
       leaf *= 1.25) {
    kept = Downsample(down, leaf);
  }
  auto source = WithNormals(kept, 3.0 * o.voxel, down);
  const NormalCloud::Ptr& target = map.normals;  // the map's within reach
  const bool constrained = ConstrainsPose(*source, o.min_structure);
  const bool observable = source->size() >= 200 && target->size() >= 3 && constrained;
  pcl::IterativeClosestPointWithNormals<PointNormal, PointNormal> icp;
  icp.setTransformationEstimation(pcl::make_shared<FiniteStepPointToPlane>());
  icp.setInputSource(source);
  icp.setInputTarget(target);
  icp.setMaxCorrespondenceDistance(o.icp_max_distance);
  icp.setMaximumIterations(o.icp_iterations);
  icp.setTransformationEpsilon(1e-9);
  NormalCloud aligned;
  Eigen::Matrix4d correction = Eigen::Matrix4d::Identity();
  double fitness = std::numeric_limits<double>::quiet_NaN();
  if (observable) {
    icp.align(aligned);
    correction = icp.getFinalTransformation().cast<double>();
    fitness = icp.hasConverged() ? icp.getFitnessScore(o.icp_max_distance) : 1e9;
  }
  // Poor fit from the reported pose: a global alignment first (RANSAC on FPFH features), which
  // ICP refines.
  Eigen::Matrix4f guess;
  if (observable && fitness > o.icp_good_fitness && RansacGuess(structure, map, reach, &guess)) {
    icp.align(aligned, guess);
    const double f2 = icp.hasConverged() ? icp.getFitnessScore(o.icp_max_distance) : 1e9;
    const Eigen::Matrix4d refined = icp.getFinalTransformation().cast<double>();
    // A refinement that moves the camera too far is not kept (the check in Register would throw
    // away ICP's own correction with it), nor reported as used.
    if (f2 < fitness && refined.allFinite() &&
        refined.block<3, 1>(0, 3).norm() <= o.max_correction) {
      fitness = f2;
      correction = refined;
      *used_ransac = true;
    }
  }
  *fitness_out = fitness;
  return correction;
}

bool Perception::Impl::RansacGuess(const CloudXYZ::Ptr& structure, const LocalMap& map,
                                   const Eigen::AlignedBox2d& reach, Eigen::Matrix4f* guess) const {
  const PerceptionOptions& o = options;
  // The map's features within reach, each computed from all its neighbours (the crop is
  // widened by the normals' and features' radii, then cut back).
  CloudXYZ::Ptr around, map_ransac = pcl::make_shared<CloudXYZ>();
  pcl::PointCloud<pcl::FPFHSignature33>::Ptr around_features;
  auto map_features = pcl::make_shared<pcl::PointCloud<pcl::FPFHSignature33>>();
  const Eigen::AlignedBox2d features = Widened(reach, 8.0 * o.ransac_voxel);
  auto points = pcl::make_shared<CloudXYZ>();
  for (const auto& [index, t] : map.tiles) {
    for (const auto& p : *t->points) {
      if (features.contains(Eigen::Vector2d(p.x, p.y))) points->push_back(p);
    }
  }
  ComputeRansacFeatures(points, o.max_ransac_map_points, &around, &around_features);
  for (size_t i = 0; i < around->size(); ++i) {
    if (reach.contains(Eigen::Vector2d((*around)[i].x, (*around)[i].y))) {
      map_ransac->push_back((*around)[i]);
      map_features->push_back((*around_features)[i]);
    }
  }
  CloudXYZ::Ptr src_down;
  pcl::PointCloud<pcl::FPFHSignature33>::Ptr src_features;
  ComputeRansacFeatures(structure, o.max_ransac_points, &src_down, &src_features);
  const bool enough = src_down->size() >= 3 && map_ransac->size() >= 3;
  pcl::SampleConsensusPrerejective<PointXYZ, PointXYZ, pcl::FPFHSignature33> ransac;
  ransac.setInputSource(src_down);
  ransac.setSourceFeatures(src_features);
  ransac.setInputTarget(map_ransac);
  ransac.setTargetFeatures(map_features);
  ransac.setMaximumIterations(20000);
  ransac.setNumberOfSamples(3);
  ransac.setCorrespondenceRandomness(5);
  ransac.setSimilarityThreshold(0.9f);
  ransac.setMaxCorrespondenceDistance(2.0f * static_cast<float>(o.ransac_voxel));
  ransac.setInlierFraction(0.25f);
  CloudXYZ ransac_aligned;
  if (enough) ransac.align(ransac_aligned);
  // ICP refines RANSAC's transform only where the result could be kept: one that moves the
  // camera farther than max_correction (plus one correspondence distance ICP could take back)
  // is rejected anyway, and ICP from so far off searches long for every source point
  // (6.5 of the 9 s an adversarial lattice of 20,000 points cost).
  const bool plausible = ransac.getFinalTransformation().block<3, 1>(0, 3).norm() <=
                         o.max_correction + o.icp_max_distance;
  if (!(enough && ransac.hasConverged() && ransac.getFinalTransformation().allFinite() &&
        plausible)) {
    return false;
  }
  *guess = ransac.getFinalTransformation();
  return true;
}

// ---- 2. segmentation ----

Segments Perception::Impl::ObjectPoints(const Registration& reg) const {
  // The corrected frame's points that stand on a workspace (near the camera) and are not the
  // map's.
  Segments out;
  CloudXYZ::Ptr points = pcl::make_shared<CloudXYZ>();
  pcl::transformPointCloud(*reg.in_map, *points, reg.correction.cast<float>());
  points = Downsample(points, options.voxel);
  const LocalMap& map = *reg.map;
  for (const auto& p : *points) {
    int surface = -1;
    if (!OnWorkspace(p, options.workspace_margin, &surface)) continue;
    if (!map.segmentation_region.contains(Eigen::Vector2d(p.x, p.y))) continue;
    if (map.NearMap(p, options.map_distance)) continue;
    out.objects->push_back(p);
    out.surface_of.push_back(surface);
  }
  return out;
}

std::vector<pcl::PointIndices> Perception::Impl::EuclideanClusters(
    const CloudXYZ::Ptr& objects) const {
  std::vector<pcl::PointIndices> clusters;
  if (!objects->empty()) {
    auto tree = pcl::make_shared<pcl::search::KdTree<PointXYZ>>();
    tree->setInputCloud(objects);
    pcl::EuclideanClusterExtraction<PointXYZ> ec;
    ec.setClusterTolerance(options.cluster_tolerance);
    ec.setMinClusterSize(options.min_cluster_points);
    ec.setMaxClusterSize(options.max_cluster_points);
    ec.setSearchMethod(tree);
    ec.setInputCloud(objects);
    ec.extract(clusters);
  }
  return clusters;
}

// ---- 3. association ----

std::vector<int> Perception::Impl::Associate(const Segments& segments) {
  const auto& workspaces = world.grid.workspaces();
  const auto& clusters = segments.clusters;
  std::vector<int> track_of(clusters.size(), -1);
  std::vector<bool> taken(tracks.size(), false);
  for (size_t c = 0; c < clusters.size(); ++c) {
    CloudXYZ cluster;
    for (int i : clusters[c].indices) cluster.push_back((*segments.objects)[i]);
    int best = MatchingTrack(cluster, taken);
    if (best < 0) {
      Track fresh;
      fresh.id = "obj-" + std::to_string(next_id++);
      tracks.push_back(std::move(fresh));
      taken.push_back(false);
      best = static_cast<int>(tracks.size()) - 1;
    }
    taken[best] = true;
    Track& tr = tracks[best];
    *tr.points += cluster;
    tr.surface = segments.surface_of[clusters[c].indices.front()];
    tr.Refresh(options.voxel, options.max_track_points);
    tr.box = FitBox(*tr.points, workspaces[tr.surface].height);
    track_of[c] = best;
  }
  // The session's tracks together (a session's snapshot holds them all, and 63 dense tracks made
  // a 190 MB one).
  ThinToTotal(&tracks, options, workspaces);
  return track_of;
}

int Perception::Impl::MatchingTrack(const CloudXYZ& cluster, const std::vector<bool>& taken) const {
  // The nearest track by the Mahalanobis distance of the centroids, within association_gate,
  // among those whose box lies within association_distance of the cluster's points.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : cluster) centroid += p.getVector3fMap().cast<double>();
  centroid /= static_cast<double>(cluster.size());
  int best = -1;
  double best_d = options.association_gate;
  for (size_t t = 0; t < tracks.size(); ++t) {
    if (taken[t]) continue;
    const Track& tr = tracks[t];
    const Eigen::Vector3d d = centroid - tr.centroid;
    const Eigen::Matrix3d cov = tr.covariance + 4e-4 * Eigen::Matrix3d::Identity();
    const double mahalanobis = std::sqrt(d.dot(cov.ldlt().solve(d)));
    if (mahalanobis >= best_d) continue;
    // Mean distance of the cluster's points to the track's box: unlike point-to-point
    // distances, it does not grow when a new viewpoint shows other faces of the object.
    double mean = 0.0;
    for (const auto& p : cluster) mean += DistanceToBox(tr.box, p);
    mean /= static_cast<double>(cluster.size());
    if (mean > options.association_distance) continue;
    best = static_cast<int>(t);
    best_d = mahalanobis;
  }
  return best;
}

// ---- 4. detection, faces and moveability ----

std::vector<object_search::ObjectDetection> Perception::Impl::Detect(
    const Perception& perception, const SensorFrame& frame, const Eigen::Matrix4d& camera_to_map,
    const Segments& segments, const std::vector<int>& track_of,
    std::vector<std::string>* box_objects) const {
  const Eigen::Matrix4d map_to_camera = camera_to_map.inverse();
  const Vec3 camera_position = camera_to_map.block<3, 1>(0, 3);
  std::vector<Box> boxes;
  for (int t : track_of) boxes.push_back(tracks[t].box);
  // The robot's own detector's boxes score the clusters when it sent them; SIFT does otherwise.
  std::vector<double> box_scores;
  if (frame.image_boxes) {
    std::vector<int> box_cluster;
    box_scores = BoxScores(frame, map_to_camera, segments, &box_cluster);
    for (int c : box_cluster) box_objects->push_back(c < 0 ? "" : tracks[track_of[c]].id);
  }
  int64_t sift_pixels = options.max_sift_frame_pixels, sift_pairs = options.max_sift_pairs;
  std::vector<object_search::ObjectDetection> detections;
  for (size_t c = 0; c < segments.clusters.size(); ++c) {
    const Track& tr = tracks[track_of[c]];
    object_search::ObjectDetection det;
    det.key = tr.id;
    det.box = boxes[c];
    double score = 0.5;
    if (frame.image_boxes) {
      score = box_scores[c];
    } else if (!frame.image.empty()) {
      score = ClusterScore(perception, frame, map_to_camera, *segments.objects,
                           segments.clusters[c], &sift_pixels, &sift_pairs);
    }
    const auto semantic = frame.semantic_scores.find(tr.id);
    if (semantic != frame.semantic_scores.end()) {
      score = 0.5 * (score + std::clamp(semantic->second, 0.0, 1.0));
    }
    // The face grids facing the camera and not hidden by other objects get the detection.
    det.faces = VisibleFaces(boxes, c, score, map_to_camera, camera_position, frame.intrinsics);
    det.moveability = Moveability(det.box);
    detections.push_back(std::move(det));
  }
  return detections;
}

double Perception::Impl::ClusterScore(const Perception& perception, const SensorFrame& frame,
                                      const Eigen::Matrix4d& map_to_camera, const CloudXYZ& objects,
                                      const pcl::PointIndices& cluster, int64_t* sift_pixels,
                                      int64_t* sift_pairs) const {
  cv::Mat region, mask;
  if (!ClusterRegion(frame, map_to_camera, objects, cluster, &region, &mask)) return 0.5;
  // SIFT while the frame's budgets last; colour alone beyond.
  const int64_t pixels = int64_t{region.cols} * region.rows;
  const bool sift = pixels <= *sift_pixels;
  if (sift) *sift_pixels -= pixels;
  return perception.ScoreRegion(region, mask, sift ? sift_pairs : nullptr, nullptr);
}

bool Perception::Impl::ClusterMask(const CameraIntrinsics& in, const Eigen::Matrix4d& map_to_camera,
                                   const CloudXYZ& objects, const pcl::PointIndices& cluster,
                                   cv::Rect* rect, cv::Mat* mask) const {
  // The cluster's points reprojected into the image, masked to the pixels they cover (the
  // bounding rectangle alone also holds whatever stands beside or behind).
  std::vector<cv::Point3i> pixels;  // u, v, radius
  int u0 = in.width, v0 = in.height, u1 = -1, v1 = -1;
  for (int i : cluster.indices) {
    const Eigen::Vector4d q =
        map_to_camera * Eigen::Vector4d(objects[i].x, objects[i].y, objects[i].z, 1);
    if (q.z() <= 0) continue;
    // Clamped before the cast: a point just in front of the camera projects anywhere.
    const int u = static_cast<int>(std::clamp(in.fx * q.x() / q.z() + in.cx, -1e6, 1e6));
    const int v = static_cast<int>(std::clamp(in.fy * q.y() / q.z() + in.cy, -1e6, 1e6));
    // The voxel's footprint in pixels: neighbouring points' disks overlap.
    const int r = std::clamp(static_cast<int>(std::ceil(in.fx * options.voxel / q.z())), 1, 50);
    pixels.emplace_back(u, v, r);
    u0 = std::min(u0, u - r);
    v0 = std::min(v0, v - r);
    u1 = std::max(u1, u + r);
    v1 = std::max(v1, v + r);
  }
  *rect = cv::Rect(u0, v0, u1 - u0 + 1, v1 - v0 + 1) & cv::Rect(0, 0, in.width, in.height);
  if (rect->width < 4 || rect->height < 4) return false;
  *mask = cv::Mat::zeros(rect->size(), CV_8U);
  for (const cv::Point3i& p : pixels) {
    cv::circle(*mask, cv::Point(p.x - rect->x, p.y - rect->y), p.z, cv::Scalar(255), cv::FILLED);
  }
  return true;
}

bool Perception::Impl::ClusterRegion(const SensorFrame& frame, const Eigen::Matrix4d& map_to_camera,
                                     const CloudXYZ& objects, const pcl::PointIndices& cluster,
                                     cv::Mat* region, cv::Mat* mask) const {
  cv::Rect rect;
  if (!ClusterMask(frame.intrinsics, map_to_camera, objects, cluster, &rect, mask)) return false;
  *region = frame.image(rect);
  const int64_t area = int64_t{rect.width} * rect.height;
  if (area > options.max_sift_pixels) {
    const double f = std::sqrt(static_cast<double>(options.max_sift_pixels) / area);
    const cv::Size size(std::max(4, static_cast<int>(rect.width * f)),
                        std::max(4, static_cast<int>(rect.height * f)));
    cv::Mat small_region, small_mask;  // new buffers: `region` views the caller's image
    cv::resize(*region, small_region, size, 0, 0, cv::INTER_AREA);
    cv::resize(*mask, small_mask, size, 0, 0, cv::INTER_NEAREST);
    *region = small_region;
    *mask = small_mask;
  }
  return true;
}

std::vector<double> Perception::Impl::BoxScores(const SensorFrame& frame,
                                                const Eigen::Matrix4d& map_to_camera,
                                                const Segments& segments,
                                                std::vector<int>* box_cluster) const {
  const std::vector<ImageBox>& image_boxes = *frame.image_boxes;
  const size_t n = segments.clusters.size();
  std::vector<double> scores(n, 0.5);
  std::vector<cv::Rect> boxes;
  for (const ImageBox& ib : image_boxes) {
    boxes.emplace_back(
        cv::Point(static_cast<int>(std::floor(ib.x)), static_cast<int>(std::floor(ib.y))),
        cv::Point(static_cast<int>(std::ceil(ib.x + ib.width)),
                  static_cast<int>(std::ceil(ib.y + ib.height))));
  }
  // One cluster at a time (its mask and the integral image of it, which make the pixels a box
  // holds four lookups, are dropped before the next: a frame's memory is one cluster's, however
  // many clusters span the image), each box keeping the cluster of which it holds the most
  // pixels, half of them at least.
  std::vector<double> best(boxes.size(), 0.0);
  box_cluster->assign(boxes.size(), -1);
  for (size_t c = 0; c < n; ++c) {
    cv::Rect rect;
    cv::Mat mask, sum;
    if (!ClusterMask(frame.intrinsics, map_to_camera, *segments.objects, segments.clusters[c],
                     &rect, &mask)) {
      continue;  // too few pixels to say: no evidence
    }
    cv::threshold(mask, mask, 0, 1, cv::THRESH_BINARY);
    cv::integral(mask, sum, CV_32S);
    const double area = sum.at<int>(mask.rows, mask.cols);
    if (!(area > 0)) continue;
    scores[c] = options.unboxed_score;  // in view, and no box yet
    for (size_t b = 0; b < boxes.size(); ++b) {
      const cv::Rect in = boxes[b] & rect;
      if (in.empty()) continue;
      const int x0 = in.x - rect.x, y0 = in.y - rect.y;
      const int x1 = x0 + in.width, y1 = y0 + in.height;
      const double held =
          sum.at<int>(y1, x1) - sum.at<int>(y0, x1) - sum.at<int>(y1, x0) + sum.at<int>(y0, x0);
      if (held >= 0.5 * area && held > best[b]) {
        best[b] = held;
        (*box_cluster)[b] = static_cast<int>(c);
      }
    }
  }
  std::vector<bool> boxed(n, false);
  for (size_t b = 0; b < boxes.size(); ++b) {
    if (const int c = (*box_cluster)[b]; c >= 0) {
      // Several boxes on one object: the most confident.
      scores[c] = boxed[c] ? std::max(scores[c], image_boxes[b].score) : image_boxes[b].score;
      boxed[c] = true;
    }
  }
  return scores;
}

double Perception::Impl::Moveability(const Box& box) const {
  // Graspable size, and reachable from some base region.
  const double extent = std::max(box.size.x(), box.size.y());
  double reach = 1e9;
  for (const auto& region : world.base_regions) {
    const double dx =
        std::max({region.min.x() - box.center.x(), 0.0, box.center.x() - region.max.x()});
    const double dy =
        std::max({region.min.y() - box.center.y(), 0.0, box.center.y() - region.max.y()});
    reach = std::min(reach, std::hypot(dx, dy));
  }
  const bool reachable = reach <= world.robot.reach;
  return !reachable                            ? 0.05
         : extent <= options.gripper_max       ? 0.95
         : extent <= 1.5 * options.gripper_max ? 0.5
                                               : 0.05;
}

// The pipeline: each stage takes what the ones before gave.
StatusOr<PerceptionResult> Perception::Process(const SensorFrame& frame) {
  Impl& im = *impl_;
  const auto start = Clock::now();
  if (Status s = CheckFrame(frame, im.options); !s.ok()) return s;  // nothing changes on error
  PerceptionResult result;

  // ---- 1. registration to the prior map (ICP, RANSAC-initialised when it fits poorly) ----
  auto t0 = Clock::now();
  const Registration reg = im.Register(frame, &result);
  result.timings.registration = Ms(t0);

  // ---- 2. segmentation: map-point removal, then Euclidean clusters ----
  t0 = Clock::now();
  Segments segments = im.ObjectPoints(reg);
  segments.clusters = im.EuclideanClusters(segments.objects);
  result.clusters = static_cast<int>(segments.clusters.size());
  if (result.clusters > im.options.max_clusters) {  // before any track changes
    return InvalidFieldError("pointCloud.data", std::to_string(result.clusters) +
                                                    " object clusters in one frame; at most " +
                                                    std::to_string(im.options.max_clusters));
  }
  result.timings.segmentation = Ms(t0);

  // ---- 3. association of the clusters to the tracks ----
  t0 = Clock::now();
  const std::vector<int> track_of = im.Associate(segments);
  result.timings.association = Ms(t0);

  // ---- 4. target detection (the robot's detector's boxes, or SIFT / colour), visible faces,
  // moveability ----
  t0 = Clock::now();
  result.observation.objects =
      im.Detect(*this, frame, reg.camera_to_map, segments, track_of, &result.box_objects);
  result.timings.detection = Ms(t0);
  result.timings.total = Ms(start);
  return result;
}

int64_t PriorMapPoints(const object_search::World& world, const PerceptionOptions& options) {
  // The largest x-y square a frame's map can span: the registration reach (registration_range
  // around the camera, widened by a correction, ICP's reach and RANSAC's feature margin) rounded
  // out to whole tiles with their padding; segmentation's region lies inside it.
  const double side = 2.0 * (options.registration_range + options.max_correction +
                             options.icp_max_distance + 8.0 * options.ransac_voxel) +
                      2.0 * (kTileSide + kTilePad);
  // Counts of SampleBoxWithin (step voxel / 2) and of the floor grid (step 2 voxel), in floating
  // point so that nothing overflows; a box side is counted up to the square's diagonal.
  const double step = 0.5 * options.voxel;
  auto count = [](double extent, double s) { return std::floor(std::max(0.0, extent) / s) + 1.0; };
  const double diagonal = std::sqrt(2.0) * side;
  double total = 0.0;
  for (const Box& b : world.furniture) {
    const double nu = count(std::min(b.size.x(), diagonal), step);
    const double nv = count(std::min(b.size.y(), diagonal), step);
    const double nw = count(b.size.z(), step);
    total += nu * (nv + 2.0 * nw) + 2.0 * nv * nw;
  }
  const auto& occ = world.occupancy;
  total += count(std::min(occ.max().x() - occ.min().x(), side), 2.0 * options.voxel) *
           count(std::min(occ.max().y() - occ.min().y(), side), 2.0 * options.voxel);
  return total > 9e18 ? INT64_MAX : static_cast<int64_t>(total);
}

}  // namespace npfkct::perception
