// Prometheus text-format metrics: counters, gauges and histograms with labels.
#pragma once

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace npfkct::server {

/// The server's metrics, safe to update from any thread.
class Metrics {
 public:
  Metrics();

  /// Counts a finished request.
  void ObserveRequest(const std::string& method, const std::string& route, int code,
                      double seconds);
  /// Records a plan: the planner's own time and the request's overhead beyond it.
  void ObservePlan(double planning_seconds, double overhead_seconds, int64_t simulations);
  /// Current number of sessions held in memory.
  void SetSessions(int n) { sessions_.store(n); }
  /// Sessions deleted because they were idle past their TTL.
  void CountExpired() { ++expired_; }
  /// A call to the session store by operation ("save", "load", "refresh", ...); `failed`: it
  /// did not answer or answered with an error (not a conflict or an absent session).
  void ObserveStore(const std::string& op, double seconds, bool failed);
  /// A save refused because another request or replica saved the session first.
  void CountStoreConflict() { ++store_conflicts_; }
  /// Fleet mode: a session loaded from the store (its belief rebuilt), and one dropped from
  /// memory (still stored).
  void CountLoaded() { ++loaded_; }
  void CountEvicted() { ++evicted_; }
  /// Whether the store answered its last call.
  void SetStoreUp(bool up) { store_up_.store(up); }

  /// The exposition text, with the planning slots in use and the plans waiting for one.
  std::string Render(int planning = 0, int waiting = 0) const;

 private:
  struct Histogram {
    std::vector<double> bounds;
    std::vector<uint64_t> counts;  // per bucket (non-cumulative), +Inf last
    double sum = 0.0;
    uint64_t count = 0;
    void Observe(double v);
  };
  static void RenderHistogram(std::string* out, const std::string& name, const std::string& labels,
                              const Histogram& h);

  mutable std::mutex mutex_;
  std::map<std::string, uint64_t> requests_;          // labels -> count
  std::map<std::string, Histogram> request_seconds_;  // route labels -> histogram
  Histogram planning_seconds_;
  Histogram overhead_seconds_;
  uint64_t plans_ = 0;
  uint64_t simulations_ = 0;
  std::atomic<int> sessions_{0};
  std::atomic<uint64_t> expired_{0};
  std::map<std::string, Histogram> store_seconds_;  // op labels -> histogram
  std::map<std::string, uint64_t> store_errors_;    // op labels -> count
  std::atomic<uint64_t> store_conflicts_{0};
  std::atomic<uint64_t> loaded_{0};
  std::atomic<uint64_t> evicted_{0};
  std::atomic<bool> store_up_{true};
};

}  // namespace npfkct::server
