// The closed-loop object-search benchmark of npfkct-bench --scenario.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "npfkct/object_search/planner_registry.h"

namespace npfkct::bench {

/// Settings of an object-search benchmark run.
struct SearchBenchConfig {
  std::vector<std::string> scenarios;  ///< Scenario files.
  /// Names of `registry`'s planners (the oracles included) or "all".
  std::vector<std::string> planners;
  /// The planners it knows (null: object_search::PlannerRegistry::BuiltIn()); the simulator's
  /// oracles are given their factory (sim::AddOracleFactories).
  const object_search::PlannerRegistry* registry = nullptr;
  int trials = 20;
  double time_ms = 0.0;  ///< Wall-clock budget per step (0: none).
  double cpu_ms = 0.0;   ///< CPU-time budget of the planning thread per step (0: none).
  int64_t sims = 0;      ///< Simulation budget per step (0: none).
  uint64_t seed = 1;
  int threads = 1;
  int max_steps = 0;                 ///< 0: the scenario's (50 by default).
  std::string robot;                 ///< Overrides the scenario's robot ("fetch", "stretch").
  std::vector<std::string> options;  ///< Planner options key=value; filter.* go to Net_sam.
  std::string table_path;            ///< Markdown table output (Table 1 layout).
  std::string render_dir;            ///< Per-step PNGs (first trial of each run).
  bool trace = false;                ///< Each step of the first trial on stderr.
  /// Neural filter model of the npfkct planner (default: the shipped one; "none": uniform).
  std::string filter_model;
  /// Observation modes compared: "geometric" (the simulator's visibility shortcut) and/or
  /// "perception" (rendered 640x480 RGB-D frames, a noisy reported pose, and the perception
  /// pipeline: registration, segmentation, association, SIFT target detection) and/or "boxes"
  /// (the same frames' depth with a simulated YOLO-style detector's 2D boxes of the target
  /// through the same pipeline, in place of the image and SIFT).
  std::vector<std::string> observe = {"geometric"};
  /// The model's rollout policy for every planner: "aimed" (the default), "greedy" or "random"
  /// (object_search::SearchRollout).
  std::string rollout = "aimed";
  /// R_co of the planners' model, when it differs from the scenario's (the simulator still pays
  /// the scenario's): what a planner that does not chase obstacle declarations does.
  std::optional<double> plan_r_co;
  /// What the planners' model pays for an obstacle declaration: "every" (the paper's R_co for
  /// each) or "covers" (only for an obstacle hiding the particle's target; object_search::
  /// ObstacleReward). The simulator always pays the scenario's reward.
  std::string obstacle_reward = "every";
  /// How the robot's grid world weighs its cells when the target is placed: "probability"
  /// (sigmoid of the log-odds) or "odds" (the paper's; object_search::GridSampling).
  std::string grid_sampling = "probability";
  /// The name the cells' records and the table give the planner, when one planner runs with
  /// options that make it a preset of its own (e.g. "npfkct-paper": npfkct with the paper's
  /// choices); empty: the planner's name. The records keep the planner run in "base_planner".
  std::string label;
};

/// Runs every (scenario, planner) pair; prints one JSON line per pair (with every trial's reward,
/// steps and success) and writes the table.
int RunObjectSearchBench(const SearchBenchConfig& config);

}  // namespace npfkct::bench
