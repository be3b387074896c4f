// npfkct-perception-bench: time per stage of the perception pipeline on 640x480 RGB-D frames
// rendered by the simulator, on one core (OpenCV threads off; PCL here is single-threaded).
// Prints one JSON object with the median milliseconds of each stage, and how well the target was
// told apart: the share of the target's detections scored above 0.5 (recall) and of the other
// objects' scored below (rejected), each detection matched to the scene object at its box.
// With --room SIDE every scenario's room is grown to a square of that side around its own
// centre (a house map), to measure what perception's prior map costs as the room grows: the
// CPU time of building the pipeline, of its most expensive frame, and the process's peak memory.
// With --pose-offset D each frame is reported off its true pose by D metres in x and in y and
// D / 2 radians in yaw (each sign drawn at random, seeded): registration must take the offset
// back, and the bench prints the corrected pose's error against the truth (median and 90th
// percentile of the position error, median of the heading error; with no offset, the error
// registration adds to an exact report).
#include <pcl/console/print.h>
#include <sys/resource.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/common/version.h"
#include "npfkct/object_search/geometry.h"
#include "npfkct/perception/perception.h"
#include "npfkct/sim/frame_io.h"
#include "npfkct/sim/simulator.h"
#include "npfkct/solver/planner.h"

namespace {

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[static_cast<size_t>(q * static_cast<double>(v.size() - 1))];
}

double Max(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

// The process's peak resident memory (getrusage's ru_maxrss, in KiB on Linux), in MB.
double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> scenarios = {"loose1", "hidden1", "complex1"};
  int repeats = 1;
  double room = 0.0;
  double pose_offset = 0.0;
  CLI::App app{"npfkct-perception-bench: per-stage time of the perception pipeline"};
  app.set_version_flag("--version", std::string("npfkct-perception-bench ") + npfkct::kVersion);
  app.add_option("--scenario", scenarios, "scenario names in scenarios")->delimiter(',');
  app.add_option("--repeats", repeats, "passes over the frames");
  app.add_option("--room", room,
                 "grow each scenario's room to a square of this side (m) around its centre")
      ->check(CLI::Range(0.0, 100.0));
  app.add_option("--pose-offset", pose_offset,
                 "report each frame this far (m in x and y; half as many rad in yaw) off its pose")
      ->check(CLI::Range(0.0, 0.5));
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(1);
  pcl::console::setVerbosityLevel(pcl::console::L_ERROR);
  std::vector<double> reg, seg, assoc, det, total, setup_cpu, frame_cpu, position_error,
      heading_error, registered_error;
  npfkct::Rng offsets(11);
  int registered = 0;  // frames whose view constrained the pose (ICP ran)
  int frames = 0;
  int target_views = 0, target_hits = 0, other_views = 0, other_hits = 0;
  for (const std::string& name : scenarios) {
    auto scenario =
        npfkct::sim::LoadScenario(std::string(NPFKCT_SCENARIO_DIR) + "/" + name + ".json");
    if (!scenario.ok()) {
      std::fprintf(stderr, "%s\n", scenario.status().ToString().c_str());
      return 2;
    }
    if (room > 0.0) {
      const npfkct::object_search::Vec2 centre = 0.5 * (scenario->room_min + scenario->room_max);
      const npfkct::object_search::Vec2 half(0.5 * room, 0.5 * room);
      scenario->room_min = scenario->room_min.cwiseMin(centre - half);
      scenario->room_max = scenario->room_max.cwiseMax(centre + half);
    }
    npfkct::sim::Simulator sim(*scenario, 1);
    const auto world = sim.InitialWorld().value();
    npfkct::Rng rng(3);
    // The views of the baselines' manual action set: every base pose, lift and head angle.
    std::vector<npfkct::sim::Frame> views;
    std::vector<npfkct::object_search::RobotConfig> poses;
    for (const auto& pose : world.ManualConfigurations()) {
      if (sim.ExecuteMove(pose, world.params, rng).illegal) continue;
      views.push_back(sim.Render(640, 480));
      poses.push_back(sim.robot());
    }
    for (int r = 0; r < repeats; ++r) {
      const double setup_start = npfkct::ThreadCpuMillis();
      npfkct::perception::Perception p(
          world, {npfkct::sim::ObjectPhotos(sim.objects()[sim.target_index()])}, {});
      setup_cpu.push_back(npfkct::ThreadCpuMillis() - setup_start);
      for (size_t v = 0; v < views.size(); ++v) {
        const auto& f = views[v];
        npfkct::perception::SensorFrame frame;
        frame.cloud = npfkct::sim::FrameCloud(f, false);
        frame.image = npfkct::sim::FrameBgr(f);
        frame.intrinsics = {f.width, f.height, f.fx, f.fy, f.cx, f.cy};
        // The pose of the rendered frame, as the robot reports it (off by the offset).
        frame.reported = poses[v];
        auto sign = [&offsets] { return offsets.Uniform() < 0.5 ? -1.0 : 1.0; };
        frame.reported.x += sign() * pose_offset;
        frame.reported.y += sign() * pose_offset;
        frame.reported.yaw += sign() * 0.5 * pose_offset;
        const double frame_start = npfkct::ThreadCpuMillis();
        auto result = p.Process(frame);
        frame_cpu.push_back(npfkct::ThreadCpuMillis() - frame_start);
        if (!result.ok()) {
          std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
          return 1;
        }
        // Detection quality: each detection against the scene object at its box.
        for (const auto& d : result->observation.objects) {
          const int i = sim.FindObject(d.key, &d.box);
          if (i < 0 || d.faces.empty()) continue;
          const bool said_target = d.faces.front().score > 0.5;
          if (sim.objects()[i].target) {
            ++target_views;
            target_hits += said_target;
          } else {
            ++other_views;
            other_hits += !said_target;
          }
        }
        registered += std::isfinite(result->fitness);
        const auto& achieved = result->observation.achieved;
        position_error.push_back(std::hypot(achieved.x - poses[v].x, achieved.y - poses[v].y));
        if (std::isfinite(result->fitness)) registered_error.push_back(position_error.back());
        heading_error.push_back(
            std::abs(npfkct::object_search::WrapAngle(achieved.yaw - poses[v].yaw)));
        reg.push_back(result->timings.registration);
        seg.push_back(result->timings.segmentation);
        assoc.push_back(result->timings.association);
        det.push_back(result->timings.detection);
        total.push_back(result->timings.total);
        ++frames;
      }
    }
  }
  std::printf(
      "{\"frames\": %d, \"resolution\": \"640x480\", \"threads\": 1, "
      "\"median_ms\": {\"registration\": %.2f, \"segmentation\": %.2f, \"association\": %.2f, "
      "\"detection\": %.2f, \"total\": %.2f}, "
      "\"target_detections\": %d, \"target_recall\": %.3f, \"other_detections\": %d, "
      "\"other_rejected\": %.3f, \"room_side_m\": %g, \"median_setup_cpu_ms\": %.1f, "
      "\"max_setup_cpu_ms\": %.1f, \"median_frame_cpu_ms\": %.1f, \"max_frame_cpu_ms\": %.1f, "
      "\"peak_rss_mb\": %.1f, \"pose_offset\": %g, \"position_error_median_m\": %.4f, "
      "\"position_error_p90_m\": %.4f, \"heading_error_median_rad\": %.4f, \"registered\": %d, "
      "\"registered_position_error_median_m\": %.4f, \"registered_position_error_p90_m\": %.4f}\n",
      frames, Median(reg), Median(seg), Median(assoc), Median(det), Median(total), target_views,
      target_views ? static_cast<double>(target_hits) / target_views : 0.0, other_views,
      other_views ? static_cast<double>(other_hits) / other_views : 0.0, room, Median(setup_cpu),
      Max(setup_cpu), Median(frame_cpu), Max(frame_cpu), PeakRssMb(), pose_offset,
      Median(position_error), Percentile(position_error, 0.9), Median(heading_error), registered,
      Median(registered_error), Percentile(registered_error, 0.9));
  return 0;
}
