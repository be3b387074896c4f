// Closed-loop episode runner shared by the benchmark problems: plan, execute in the true model,
// observe, update the belief; across episodes on several threads.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/common/stats.h"
#include "npfkct/common/status.h"
#include "npfkct/solver/planner.h"

namespace npfkct::bench {

/// One episode's outcome.
struct EpisodeResult {
  double discounted_return = 0.0;
  double undiscounted_return = 0.0;
  /// The discounted reward without what obstacle declarations earned beyond a step (R_co -
  /// R_min each): what finding and removing the target earned (object search only).
  double target_return = 0.0;
  int steps = 0;
  bool success = false;
  std::vector<int64_t> sims_per_step;
  std::vector<double> ms_per_step;      ///< Wall time of each planning call.
  std::vector<double> cpu_ms_per_step;  ///< CPU time of the planning thread in each call.
  std::vector<double> extra_ms;         ///< Other per-step timings (perception per frame).
  std::string error;                    ///< Non-empty when planning failed.
};

/// Aggregates of a run. Intervals are two-sided 95% Student's t intervals of the mean.
struct RunSummary {
  int episodes = 0;
  double mean_return = 0.0;
  double stderr_return = 0.0;
  double ci95_return = 0.0;
  double mean_steps = 0.0;
  double ci95_steps = 0.0;
  std::optional<double> success_rate;
  double median_sims_per_step = 0.0;
  double median_sims_per_second = 0.0;      ///< Per second of wall time.
  double median_sims_per_cpu_second = 0.0;  ///< Per second of the planning thread's CPU time.
  double median_first_step_sims_per_second = 0.0;  ///< Over episodes, the first step only.
  double median_cpu_ms_per_step = 0.0;
  double wall_seconds = 0.0;
  int failed_episodes = 0;
  std::string first_error;
  /// Each episode's discounted return and steps, by episode index (for paired comparisons of two
  /// runs with the same seed).
  std::vector<double> returns;
  std::vector<double> steps;
};

/// Runs `jobs` jobs `run(index)` on `threads` threads (each job is one episode) and returns their
/// results by index; a progress line goes to stderr when it is a terminal.
inline std::vector<EpisodeResult> RunJobs(int jobs, int threads,
                                          const std::function<EpisodeResult(int)>& run,
                                          const std::string& label) {
  std::vector<EpisodeResult> results(jobs);
  std::atomic<int> next{0}, done{0};
  std::mutex print_mutex;
  const bool tty = isatty(STDERR_FILENO);
  const auto start = Clock::now();
  auto worker = [&] {
    for (int i = next++; i < jobs; i = next++) {
      results[i] = run(i);
      const int finished = ++done;
      if (tty) {
        std::lock_guard<std::mutex> lock(print_mutex);
        std::fprintf(stderr, "\r%s: %d/%d episodes, %.0f s   ", label.c_str(), finished, jobs,
                     MillisSince(start) / 1000.0);
        std::fflush(stderr);
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::max(1, threads); ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (tty) std::fprintf(stderr, "\n");
  return results;
}

/// Aggregates episode results.
inline RunSummary Summarize(const std::vector<EpisodeResult>& results, bool success_defined,
                            double wall_seconds) {
  RunSummary s;
  const int episodes = static_cast<int>(results.size());
  s.episodes = episodes;
  s.wall_seconds = wall_seconds;
  std::vector<double> sims, rate, cpu_rate, first_rate, cpu_ms, returns, steps;
  int successes = 0;
  for (const auto& r : results) {
    if (!r.error.empty()) {
      ++s.failed_episodes;
      if (s.first_error.empty()) s.first_error = r.error;
    }
    returns.push_back(r.discounted_return);
    steps.push_back(r.steps);
    successes += r.success;
    if (!r.sims_per_step.empty() && r.ms_per_step[0] > 0) {
      first_rate.push_back(r.sims_per_step[0] / (r.ms_per_step[0] / 1000.0));
    }
    for (size_t k = 0; k < r.sims_per_step.size(); ++k) {
      sims.push_back(static_cast<double>(r.sims_per_step[k]));
      if (r.ms_per_step[k] > 0) rate.push_back(r.sims_per_step[k] / (r.ms_per_step[k] / 1000.0));
      if (k < r.cpu_ms_per_step.size() && r.cpu_ms_per_step[k] > 0) {
        cpu_ms.push_back(r.cpu_ms_per_step[k]);
        cpu_rate.push_back(r.sims_per_step[k] / (r.cpu_ms_per_step[k] / 1000.0));
      }
    }
  }
  const MeanInterval ret = MeanWithInterval(returns);
  const MeanInterval st = MeanWithInterval(steps);
  s.mean_return = ret.mean;
  s.stderr_return = ret.StandardError();
  s.ci95_return = ret.half_width;
  s.mean_steps = st.mean;
  s.ci95_steps = st.half_width;
  if (success_defined)
    s.success_rate = episodes > 0 ? static_cast<double>(successes) / episodes : 0;
  s.median_sims_per_step = Median(sims);
  s.median_sims_per_second = Median(rate);
  s.median_sims_per_cpu_second = Median(cpu_rate);
  s.median_first_step_sims_per_second = Median(first_rate);
  s.median_cpu_ms_per_step = Median(cpu_ms);
  s.returns = std::move(returns);
  s.steps = std::move(steps);
  return s;
}

/// Runs `episodes` episodes of `run_episode(index)` on `threads` threads and summarises them.
/// Episode i is seeded from i alone, so results do not depend on the thread count.
inline RunSummary RunEpisodes(int episodes, int threads, bool success_defined,
                              const std::function<EpisodeResult(int)>& run_episode,
                              const std::string& label) {
  const auto start = Clock::now();
  const std::vector<EpisodeResult> results = RunJobs(episodes, threads, run_episode, label);
  return Summarize(results, success_defined, MillisSince(start) / 1000.0);
}

/// Minimal JSON string escaping.
inline std::string JsonEscape(const std::string& in) {
  std::string out;
  for (char c : in) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out;
}

}  // namespace npfkct::bench
