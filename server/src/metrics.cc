#include "npfkct/server/metrics.h"

#include <algorithm>
#include <cstdio>
#include <string_view>

namespace npfkct::server {
namespace {

std::vector<double> LatencyBounds() {
  return {0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60};
}

std::string Num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace

void Metrics::Histogram::Observe(double v) {
  size_t i = 0;
  while (i < bounds.size() && v > bounds[i]) ++i;
  ++counts[i];
  sum += v;
  ++count;
}

Metrics::Metrics() {
  planning_seconds_.bounds = LatencyBounds();
  planning_seconds_.counts.assign(planning_seconds_.bounds.size() + 1, 0);
  overhead_seconds_.bounds = {0.0001, 0.00025, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.025, 0.05, 0.1};
  overhead_seconds_.counts.assign(overhead_seconds_.bounds.size() + 1, 0);
}

void Metrics::ObserveRequest(const std::string& method, const std::string& route, int code,
                             double seconds) {
  // The methods of HTTP/1.1 (RFC 9110) keep their name; anything else a client sends is
  // "other", so that a label never carries client bytes nor grows a series per spelling.
  static constexpr std::string_view kMethods[] = {"GET",     "HEAD",    "POST",  "PUT",  "DELETE",
                                                  "CONNECT", "OPTIONS", "TRACE", "PATCH"};
  const bool known = method == "-" || std::find(std::begin(kMethods), std::end(kMethods), method) !=
                                          std::end(kMethods);
  std::lock_guard<std::mutex> lock(mutex_);
  ++requests_["method=\"" + (known ? method : std::string("other")) + "\",route=\"" + route +
              "\",code=\"" + std::to_string(code) + "\""];
  auto& h = request_seconds_["route=\"" + route + "\""];
  if (h.bounds.empty()) {
    h.bounds = LatencyBounds();
    h.counts.assign(h.bounds.size() + 1, 0);
  }
  h.Observe(seconds);
}

void Metrics::ObserveStore(const std::string& op, double seconds, bool failed) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string labels = "op=\"" + op + "\"";
  auto& h = store_seconds_[labels];
  if (h.bounds.empty()) {
    h.bounds = {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 1, 5};
    h.counts.assign(h.bounds.size() + 1, 0);
  }
  h.Observe(seconds);
  if (failed) ++store_errors_[labels];
}

void Metrics::ObservePlan(double planning_seconds, double overhead_seconds, int64_t simulations) {
  std::lock_guard<std::mutex> lock(mutex_);
  planning_seconds_.Observe(planning_seconds);
  overhead_seconds_.Observe(overhead_seconds);
  ++plans_;
  simulations_ += static_cast<uint64_t>(simulations);
}

void Metrics::RenderHistogram(std::string* out, const std::string& name, const std::string& labels,
                              const Histogram& h) {
  uint64_t cumulative = 0;
  const std::string sep = labels.empty() ? "" : ",";
  for (size_t i = 0; i < h.bounds.size(); ++i) {
    cumulative += h.counts[i];
    *out += name + "_bucket{" + labels + sep + "le=\"" + Num(h.bounds[i]) + "\"} " +
            std::to_string(cumulative) + "\n";
  }
  cumulative += h.counts.back();
  *out += name + "_bucket{" + labels + sep + "le=\"+Inf\"} " + std::to_string(cumulative) + "\n";
  const std::string braces = labels.empty() ? "" : "{" + labels + "}";
  *out += name + "_sum" + braces + " " + Num(h.sum) + "\n";
  *out += name + "_count" + braces + " " + std::to_string(h.count) + "\n";
}

std::string Metrics::Render(int planning, int waiting) const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::string out;
  out += "# HELP npfkct_http_requests_total HTTP requests by method, route and status code.\n";
  out += "# TYPE npfkct_http_requests_total counter\n";
  for (const auto& [labels, n] : requests_) {
    out += "npfkct_http_requests_total{" + labels + "} " + std::to_string(n) + "\n";
  }
  out += "# HELP npfkct_http_request_duration_seconds Request latency by route.\n";
  out += "# TYPE npfkct_http_request_duration_seconds histogram\n";
  for (const auto& [labels, h] : request_seconds_) {
    RenderHistogram(&out, "npfkct_http_request_duration_seconds", labels, h);
  }
  out += "# HELP npfkct_planning_seconds Time spent in the planner per :plan.\n";
  out += "# TYPE npfkct_planning_seconds histogram\n";
  RenderHistogram(&out, "npfkct_planning_seconds", "", planning_seconds_);
  out += "# HELP npfkct_plan_overhead_seconds Latency of :plan beyond the planner's own time.\n";
  out += "# TYPE npfkct_plan_overhead_seconds histogram\n";
  RenderHistogram(&out, "npfkct_plan_overhead_seconds", "", overhead_seconds_);
  out += "# HELP npfkct_plans_total Plans computed.\n# TYPE npfkct_plans_total counter\n";
  out += "npfkct_plans_total " + std::to_string(plans_) + "\n";
  out += "# HELP npfkct_simulations_total Simulations run by all planners.\n";
  out += "# TYPE npfkct_simulations_total counter\n";
  out += "npfkct_simulations_total " + std::to_string(simulations_) + "\n";
  out += "# HELP npfkct_sessions Sessions held in memory by this server.\n";
  out += "# TYPE npfkct_sessions gauge\n";
  out += "npfkct_sessions " + std::to_string(sessions_.load()) + "\n";
  out += "# HELP npfkct_sessions_expired_total Sessions deleted after their idle TTL.\n";
  out += "# TYPE npfkct_sessions_expired_total counter\n";
  out += "npfkct_sessions_expired_total " + std::to_string(expired_.load()) + "\n";
  out += "# HELP npfkct_store_operation_seconds Latency of session store calls by operation.\n";
  out += "# TYPE npfkct_store_operation_seconds histogram\n";
  for (const auto& [labels, h] : store_seconds_) {
    RenderHistogram(&out, "npfkct_store_operation_seconds", labels, h);
  }
  out += "# HELP npfkct_store_errors_total Store calls that failed (unreachable, timed out).\n";
  out += "# TYPE npfkct_store_errors_total counter\n";
  for (const auto& [labels, n] : store_errors_) {
    out += "npfkct_store_errors_total{" + labels + "} " + std::to_string(n) + "\n";
  }
  out += "# HELP npfkct_store_conflicts_total Saves refused: the session was saved meanwhile.\n";
  out += "# TYPE npfkct_store_conflicts_total counter\n";
  out += "npfkct_store_conflicts_total " + std::to_string(store_conflicts_.load()) + "\n";
  out += "# HELP npfkct_store_up Whether the session store answered its last call.\n";
  out += "# TYPE npfkct_store_up gauge\n";
  out += "npfkct_store_up " + std::string(store_up_.load() ? "1" : "0") + "\n";
  out += "# HELP npfkct_sessions_loaded_total Sessions loaded from the store (belief rebuilt).\n";
  out += "# TYPE npfkct_sessions_loaded_total counter\n";
  out += "npfkct_sessions_loaded_total " + std::to_string(loaded_.load()) + "\n";
  out += "# HELP npfkct_sessions_evicted_total Sessions dropped from memory (still stored).\n";
  out += "# TYPE npfkct_sessions_evicted_total counter\n";
  out += "npfkct_sessions_evicted_total " + std::to_string(evicted_.load()) + "\n";
  out += "# HELP npfkct_planning_slots_busy Planning slots in use.\n";
  out += "# TYPE npfkct_planning_slots_busy gauge\n";
  out += "npfkct_planning_slots_busy " + std::to_string(planning) + "\n";
  out += "# HELP npfkct_planning_queue Plans waiting for a slot.\n";
  out += "# TYPE npfkct_planning_queue gauge\n";
  out += "npfkct_planning_queue " + std::to_string(waiting) + "\n";
  return out;
}

}  // namespace npfkct::server
