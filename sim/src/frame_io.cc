#include "npfkct/sim/frame_io.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "npfkct/render/belief_picture.h"

namespace npfkct::sim {

cv::Mat FrameBgr(const Frame& frame) {
  cv::Mat rgb(frame.height, frame.width, CV_8UC3, const_cast<uint8_t*>(frame.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  return bgr;
}

cv::Mat FrameDepth(const Frame& frame) {
  return cv::Mat(frame.height, frame.width, CV_32F, const_cast<float*>(frame.depth.data())).clone();
}

pcl::PointCloud<pcl::PointXYZRGB>::Ptr FrameCloud(const Frame& frame, bool world_frame) {
  auto cloud = pcl::make_shared<pcl::PointCloud<pcl::PointXYZRGB>>();
  cloud->reserve(frame.depth.size() / 2);
  for (int v = 0; v < frame.height; ++v) {
    for (int u = 0; u < frame.width; ++u) {
      const size_t i = static_cast<size_t>(v) * frame.width + u;
      const float z = frame.depth[i];
      if (!(z > 0.0f)) continue;
      const double x = (u + 0.5 - frame.cx) / frame.fx * z;
      const double y = (v + 0.5 - frame.cy) / frame.fy * z;
      pcl::PointXYZRGB p;
      if (world_frame) {
        const Vec3 w =
            frame.pose.position + frame.pose.forward * z - frame.pose.left * x - frame.pose.up * y;
        p.x = static_cast<float>(w.x());
        p.y = static_cast<float>(w.y());
        p.z = static_cast<float>(w.z());
      } else {
        p.x = static_cast<float>(x);
        p.y = static_cast<float>(y);
        p.z = z;
      }
      p.r = frame.rgb[i * 3];
      p.g = frame.rgb[i * 3 + 1];
      p.b = frame.rgb[i * 3 + 2];
      cloud->push_back(p);
    }
  }
  cloud->width = static_cast<uint32_t>(cloud->size());
  cloud->height = 1;
  cloud->is_dense = true;
  return cloud;
}

cv::Mat RenderStep(const object_search::World& world, const Frame& view,
                   const std::string& caption) {
  render::BeliefPictureOptions options;
  options.title = caption;
  options.map_pixels = 640;
  cv::Mat left = render::RenderBelief(world, options);
  cv::Mat right = FrameBgr(view);
  const int height = std::max(left.rows, right.rows);
  auto pad = [&](const cv::Mat& m) {
    cv::Mat out(height, m.cols, CV_8UC3, cv::Scalar(255, 255, 255));
    m.copyTo(out(cv::Rect(0, 0, m.cols, m.rows)));
    return out;
  };
  cv::Mat row;
  cv::hconcat(pad(left), pad(right), row);
  return row;
}

std::vector<cv::Mat> ObjectPhotos(const SceneObject& object, int pixels) {
  std::vector<cv::Mat> photos;
  const Vec3& size = object.box.size;
  for (int face = 0; face < 4; ++face) {
    // The side as a person photographs it: from outside, upright. In the box's frame the camera
    // looks along -n, so the image's right is (-n) x z and its up is z.
    Vec3 n = Vec3::Zero();
    n[face / 2] = (face % 2) ? 1.0 : -1.0;
    const Vec3 right = (-n).cross(Vec3::UnitZ());
    const int horizontal = face / 2 == 0 ? 1 : 0;  // the box axis along the image's rows
    const double width = size[horizontal], height = size.z();
    const int w = pixels, h = std::max(8, static_cast<int>(pixels * height / width));
    // The renderer's face coordinates: u along axis a, v along axis b.
    const int a = (face / 2 + 1) % 3, b = (face / 2 + 2) % 3;
    cv::Mat img(h, w, CV_8UC3);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const Vec3 local = 0.5 * size[face / 2] * n + ((x + 0.5) / w - 0.5) * width * right +
                           (0.5 - (y + 0.5) / h) * height * Vec3::UnitZ();
        const Color c = object.texture_seed != 0
                            ? PatternColor(object.texture_seed, face, local[a] / size[a] + 0.5,
                                           local[b] / size[b] + 0.5)
                            : object.color;
        img.at<cv::Vec3b>(y, x) = cv::Vec3b(c[2], c[1], c[0]);
      }
    }
    photos.push_back(img);
  }
  return photos;
}

Status WritePng(const std::string& path, const cv::Mat& image) {
  try {
    if (!cv::imwrite(path, image)) return InternalError("cannot write PNG '" + path + "'");
  } catch (const cv::Exception& e) {
    return InternalError("cannot write PNG '" + path + "': " + e.what());
  }
  return OkStatus();
}

}  // namespace npfkct::sim
