// The closed-loop object-search benchmark of npfkct-bench --scenario.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace npfkct::bench {

/// Settings of an object-search benchmark run.
struct SearchBenchConfig {
  std::vector<std::string> scenarios;  ///< Scenario files.
  std::vector<std::string> planners;   ///< npfkct, kct, pomcp, gpomcp, pomcpow, vomcpow, advt.
  int trials = 20;
  double time_ms = 1000.0;
  int64_t sims = 0;
  uint64_t seed = 1;
  int threads = 1;
  int max_steps = 0;                 ///< 0: the scenario's (50 by default).
  std::string robot;                 ///< Overrides the scenario's robot ("fetch", "stretch").
  std::vector<std::string> options;  ///< Planner options key=value.
  std::string table_path;            ///< Markdown table output (Table 1 layout).
  std::string render_dir;            ///< Per-step PNGs (first trial of each run).
  std::string filter_model;          ///< Neural filter model (npfkct planner).
  /// Observation modes compared: "geometric" (the simulator's visibility shortcut) and/or
  /// "perception" (rendered 640x480 RGB-D frames, a noisy reported pose, and the perception
  /// pipeline: registration, segmentation, association, SIFT target detection).
  std::vector<std::string> observe = {"geometric"};
};

/// Runs every (scenario, planner) pair; prints one JSON line per pair and writes the table.
int RunObjectSearchBench(const SearchBenchConfig& config);

}  // namespace npfkct::bench
