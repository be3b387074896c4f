// Perception (paper appendix B): raw RGB-D frames to the object-search model's observations.
//
//   1. registration of the frame to the prior point-cloud map (PCL ICP from the reported pose;
//      RANSAC on FPFH features first when ICP alone fits badly), giving a corrected pose;
//   2. removal of map points and of points off the workspaces; objects by Euclidean cluster
//      extraction, oriented boxes by PCA;
//   3. association of clusters across frames (Mahalanobis distance of centroids and mean point
//      distance), so object ids stay stable;
//   4. target detection: each cluster reprojected into the image gives a sub-image, matched
//      against the target photos with SIFT (ratio of matched features), colour matching as a
//      fallback, an optional semantic score; the visible face grids get the detection;
//   5. moveability from size and reach.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "npfkct/common/status.h"
#include "npfkct/object_search/world.h"

namespace npfkct::perception {

using Cloud = pcl::PointCloud<pcl::PointXYZRGB>;

/// Pinhole intrinsics of the depth/colour camera (registered, same size).
struct CameraIntrinsics {
  int width = 640;
  int height = 480;
  double fx = 554.3, fy = 519.6, cx = 320.0, cy = 240.0;
  Status Validate() const;
};

/// A box in the image from the robot's own detector (a YOLO-style 2D detection of the target's
/// class), in pixels: left, top, width and height, inside the image.
struct ImageBox {
  double x = 0, y = 0, width = 0, height = 0;
  /// The probability that the box shows the target (the detector's confidence for its class).
  double score = 0.5;
};

/// One sensor frame as the robot reports it.
struct SensorFrame {
  /// Points in the camera's optical frame (x right, y down, z forward), or in the map frame.
  Cloud::ConstPtr cloud;
  bool cloud_in_map_frame = false;
  /// The colour image (BGR, intrinsics.width x intrinsics.height); may be empty.
  cv::Mat image;
  CameraIntrinsics intrinsics;
  /// The robot's configuration as its localization reports it.
  object_search::RobotConfig reported;
  /// Optional semantic score per object id from an external detector (YOLO-like), averaged with
  /// the feature-matching score.
  std::map<std::string, double> semantic_scores;
  /// The robot's detector ran on this frame and found these boxes of the target's class (none:
  /// it ran and found nothing). When present, they score the objects in place of SIFT and colour
  /// matching: an object gets the score of the box that holds most of its projected pixels (at
  /// least half of them), and an object in view that no box holds gets
  /// PerceptionOptions::unboxed_score.
  std::optional<std::vector<ImageBox>> image_boxes;
};

/// Settings of the pipeline; defaults suit the Fetch head camera at 0.5-4 m.
struct PerceptionOptions {
  double voxel = 0.01;             ///< Downsampling leaf (m).
  double icp_max_distance = 0.15;  ///< ICP correspondence distance (m).
  int icp_iterations = 80;
  double icp_good_fitness = 2.5e-4;  ///< Mean squared distance (m^2) below which ICP is trusted.
  double ransac_voxel = 0.03;        ///< Leaf for the RANSAC fallback.
  double max_correction = 0.5;       ///< Larger pose corrections are rejected (m).
  /// Registration aligns the frame with the map only where the frame lies within this distance
  /// of the camera in x-y (plus max_correction and icp_max_distance): its cost follows the view,
  /// not the room (m).
  double registration_range = 6.0;
  /// Registration runs only when the visible structure constrains the pose: the smallest
  /// eigenvalue of the point-to-plane system must exceed this fraction of the largest.
  double min_structure = 1e-5;
  double map_distance = 0.015;      ///< Points this close to the map are the map's (m).
  double workspace_margin = 0.02;   ///< Objects must stand on a workspace, within this (m).
  double max_object_height = 0.6;   ///< Points higher above a surface are ignored (m).
  double cluster_tolerance = 0.02;  ///< Euclidean clustering distance (m).
  int min_cluster_points = 40;
  int max_cluster_points = 200000;
  double association_gate = 3.0;  ///< Mahalanobis gate for matching a cluster to a track.
  double association_distance =
      0.03;                  ///< Gate on the mean distance of points to a track's box (m).
  double sift_ratio = 0.75;  ///< Lowe's ratio test.
  int min_features = 12;     ///< Fewer keypoints than this: colour matching instead.
  /// Fraction of a region's keypoints that a view of the target matches consistently; fewer
  /// than expected is evidence against the target.
  double match_threshold = 0.08;
  int min_inliers = 6;        ///< Consistent matches that mean "target".
  double gripper_max = 0.25;  ///< Largest graspable horizontal extent (m).
  /// Input bounds checked by Process() before any point reaches PCL: points per frame, and the
  /// largest |coordinate| (m) of a point in the frame it is given in (huge finite coordinates
  /// overflow PCL's voxel grids and kd-trees).
  int64_t max_points = 1'000'000;
  double max_coordinate = 1e4;
  /// Work bounds, so that no frame costs more than its size pays for. A frame with more object
  /// clusters than max_clusters is refused (the session could not know them all).
  int max_clusters = object_search::kMaxKnownObjects;
  /// A track holding more points is thinned with coarser voxels (it stays in a snapshot's bound).
  int64_t max_track_points = 200'000;
  /// All tracks together hold at most this many points (each save of the session writes them):
  /// past it the largest are thinned to a common cap that small tracks stay under.
  int64_t max_total_track_points = 400'000;
  /// ICP's source points, after downsampling, are thinned (by coarser voxels) to this many: six
  /// degrees of freedom need far fewer, and each costs a search of the map per iteration
  /// (`npfkct-perception-bench --pose-offset`: a registered pose's error median 2.6 mm).
  int64_t max_icp_points = 1'500;
  /// The RANSAC fallback's source points, after downsampling, are thinned to this many.
  int64_t max_ransac_points = 10'000;
  /// Its map points within reach of the view, after downsampling, are thinned to this many (a
  /// frame spread to the edges of registration_range reaches about 240,000).
  int64_t max_ransac_map_points = 60'000;
  /// The prior map is built lazily, in 2 m tiles around what each frame needs; the tiles kept
  /// between frames hold at most this many points together (the least recently used go first,
  /// and are built again when needed). One frame's own tiles are always kept.
  int64_t max_map_points = 2'000'000;
  /// Either cloud of RANSAC's features is thinned further (every k-th point) until a bound on
  /// its points' neighbour pairs within the features' radius (points in the 27 cells of that
  /// size around each point) is at most this: a depth camera sees surfaces (about 80 neighbours
  /// a point), while a 3-D lattice or nested shells give each about 520.
  int64_t max_ransac_pairs = 40'000'000;
  /// SIFT keypoints kept per target photo and per image region (the strongest).
  int max_features = 2'000;
  /// An image region or target photo larger than this (pixels) is scaled down before SIFT.
  int64_t max_sift_pixels = 640 * 480;
  /// Per frame, the pixels of the image regions SIFT runs on; regions beyond are scored by
  /// colour alone.
  int64_t max_sift_frame_pixels = 4 * 640 * 480;
  /// Per frame, region keypoints times photo keypoints that SIFT matches; regions beyond are
  /// scored by colour alone.
  int64_t max_sift_pairs = 20'000'000;
  /// The detector's boxes one frame may carry.
  int max_image_boxes = 256;
  /// With the robot's detector's boxes: the probability that an object in view that no box holds
  /// is the target all the same (detectors miss).
  double unboxed_score = 0.25;

  Status Validate() const;
};

/// Time spent per stage of one frame (ms).
struct StageTimings {
  double registration = 0, segmentation = 0, association = 0, detection = 0, total = 0;
};

/// What one frame gave.
struct PerceptionResult {
  object_search::RealObservation observation;                ///< Corrected pose and detections.
  Eigen::Matrix4d correction = Eigen::Matrix4d::Identity();  ///< Map-frame pose correction.
  bool used_ransac = false;
  /// ICP mean squared distance after registration; NaN when the view did not constrain the pose
  /// and the reported one was kept.
  double fitness = 0.0;
  int clusters = 0;
  /// Per box of SensorFrame::image_boxes, the id of the object it was given to; empty for a box
  /// that holds no object's pixels (half of them at least).
  std::vector<std::string> box_objects;
  StageTimings timings;
};

/// The target as the robot knows it: photos (BGR) and, optionally, its colour.
struct TargetModel {
  std::vector<cv::Mat> photos;
};

/// The state of one object track, for snapshots: id, supporting workspace, points (map frame).
struct TrackState {
  std::string id;
  int surface = -1;
  std::vector<float> points;  ///< x, y, z per point
};

/// The pipeline of one session: holds the map cloud and the object tracks across frames.
class Perception {
 public:
  /// Builds the prior point-cloud map from the world's furniture and floor.
  Perception(const object_search::World& world, TargetModel target, PerceptionOptions options);
  ~Perception();

  /// Processes one frame. Input errors (empty cloud, NaN points, more than options.max_points
  /// points, coordinates beyond options.max_coordinate, wrong frame, image of the wrong size) are
  /// INVALID_ARGUMENT naming the field; the tracks are unchanged on error.
  StatusOr<PerceptionResult> Process(const SensorFrame& frame);

  /// Number of object tracks so far.
  int tracks() const;
  /// The tracks and the next id number, for snapshots.
  std::vector<TrackState> SaveTracks(int* next_id) const;
  /// Replaces the tracks (from SaveTracks); INVALID_ARGUMENT on malformed states.
  Status RestoreTracks(const std::vector<TrackState>& tracks, int next_id);
  /// Forgets the track `id` (the robot removed that object); false when there is none.
  bool DropTrack(const std::string& id);
  /// The prior map built so far (for tests and visualisation): the tiles around what frames
  /// have needed, not the whole room.
  Cloud::ConstPtr map() const;
  /// The prior map's tiles held now.
  int64_t map_tiles() const;

  /// Probability in [0.05, 0.95] that an image region (BGR; `mask`, 8-bit of the same size,
  /// selects the object's pixels) shows the target: SIFT matches against the photos that agree
  /// on one homography, with the colour histogram as the second cue. `used_colour` tells whether
  /// SIFT had too few keypoints to contribute. Exposed for tests.
  double TargetScore(const cv::Mat& region, bool* used_colour = nullptr,
                     const cv::Mat& mask = cv::Mat()) const;

 private:
  // TargetScore with SIFT skipped (sift_pairs null) or bounded: the region's keypoints times the
  // photos' are taken from *sift_pairs, and SIFT gives no evidence when they exceed it.
  double ScoreRegion(const cv::Mat& region, const cv::Mat& mask, int64_t* sift_pairs,
                     bool* used_colour) const;

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The camera-to-map transform for a robot configuration (optical frame: x right, y down,
/// z forward).
Eigen::Matrix4d CameraToMap(const object_search::RobotDescription& robot,
                            const object_search::RobotConfig& config);

/// A bound on the points of the prior point-cloud map one frame can make Perception build for
/// `world` (floor and furniture surfaces sampled at the options' voxel size, within the largest
/// region registration and segmentation may need around the camera), computed without building
/// it, so that a caller can refuse a world too dense to map. It grows with the room only up to
/// that region: a house costs what the camera sees.
int64_t PriorMapPoints(const object_search::World& world, const PerceptionOptions& options);

/// Checks saved tracks (Perception::SaveTracks) against `world` without building a perception:
/// INVALID_ARGUMENT, naming the track, when one could not be restored.
Status CheckTracks(const std::vector<TrackState>& tracks, int next_id,
                   const object_search::World& world);

}  // namespace npfkct::perception
