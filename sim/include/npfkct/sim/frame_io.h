// Conversions of simulator frames to OpenCV images and PCL clouds, and the per-step pictures of
// `npfkct-bench --render` (the belief picture of npfkct/render, the robot's view, the chosen
// action, like the paper's figure 5). Only executables and the perception/server layers include
// this header.
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <opencv2/core.hpp>
#include <string>

#include "npfkct/object_search/world.h"
#include "npfkct/sim/simulator.h"

namespace npfkct::sim {

/// The frame's colour image as an 8-bit BGR matrix.
cv::Mat FrameBgr(const Frame& frame);
/// The frame's depth image in metres (CV_32F, 0 where nothing was hit).
cv::Mat FrameDepth(const Frame& frame);
/// The frame as a coloured point cloud, in the camera's optical frame (x right, y down,
/// z forward) or, with `world_frame`, in the world frame.
pcl::PointCloud<pcl::PointXYZRGB>::Ptr FrameCloud(const Frame& frame, bool world_frame);

/// The picture of one step: the belief picture of npfkct/render (titled `caption`: the grid
/// world's odds with a colour bar, labelled objects and face odds, the robot and its view,
/// cropped to the workspaces) on the left, the robot's camera view on the right.
cv::Mat RenderStep(const object_search::World& world, const Frame& view,
                   const std::string& caption);

/// Photos of an object's printed sides (faces 0-3), as the robot would be given of its target:
/// each face flat, `pixels` wide, in BGR.
std::vector<cv::Mat> ObjectPhotos(const SceneObject& object, int pixels = 240);

/// Writes a PNG; the status names the path on failure.
Status WritePng(const std::string& path, const cv::Mat& image);

}  // namespace npfkct::sim
