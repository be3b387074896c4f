#include "npfkct/solver/clustering.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace npfkct {
namespace {

// The metric mean of `members` of `points`, found by averaging differences from a reference point
// (correct for periodic dimensions when the cluster spans less than half a period).
ActionVec MeanOf(const BoxSpace& space, const std::vector<ActionVec>& points,
                 const std::vector<int>& members) {
  const ActionVec& ref = points[members.front()];
  ActionVec sum = ActionVec::Zero(ref.size());
  for (int i : members) sum += space.Difference(points[i], ref);
  return space.WrapPeriodic(ref + sum / static_cast<double>(members.size()));
}

void Finalize(const BoxSpace& space, const std::vector<ActionVec>& points, Cluster* c) {
  c->radius = 0.0;
  c->sse = 0.0;
  for (int i : c->members) {
    const double d2 = space.SquaredDistance(points[i], c->center);
    c->sse += d2;
    c->radius = std::max(c->radius, std::sqrt(d2));
  }
}

}  // namespace

std::vector<Cluster> KMeans(const BoxSpace& space, const std::vector<ActionVec>& points, int k,
                            Rng& rng, const std::function<bool()>& stop, int max_iterations) {
  const int n = static_cast<int>(points.size());
  if (n == 0 || k < 1) return {};
  k = std::min(k, n);
  // k-means++ seeding.
  std::vector<ActionVec> centers;
  centers.push_back(points[rng.UniformInt(n)]);
  std::vector<double> d2(n, std::numeric_limits<double>::infinity());
  while (static_cast<int>(centers.size()) < k) {
    double total = 0.0;
    for (int i = 0; i < n; ++i) {
      d2[i] = std::min(d2[i], space.SquaredDistance(points[i], centers.back()));
      total += d2[i];
    }
    if (!(total > 0.0)) break;  // fewer distinct points than k
    double u = rng.Uniform() * total;
    int pick = n - 1;
    for (int i = 0; i < n; ++i) {
      u -= d2[i];
      if (u < 0.0) {
        pick = i;
        break;
      }
    }
    centers.push_back(points[pick]);
  }
  const int kk = static_cast<int>(centers.size());
  std::vector<int> assign(n, -1);
  for (int iter = 0; iter < max_iterations; ++iter) {
    bool changed = false;
    for (int i = 0; i < n; ++i) {
      int best = 0;
      double best_d = std::numeric_limits<double>::infinity();
      for (int c = 0; c < kk; ++c) {
        const double d = space.SquaredDistance(points[i], centers[c]);
        if (d < best_d) {
          best_d = d;
          best = c;
        }
      }
      if (assign[i] != best) {
        assign[i] = best;
        changed = true;
      }
    }
    if (!changed || (stop && stop())) break;
    std::vector<std::vector<int>> members(kk);
    for (int i = 0; i < n; ++i) members[assign[i]].push_back(i);
    for (int c = 0; c < kk; ++c) {
      if (!members[c].empty()) centers[c] = MeanOf(space, points, members[c]);
    }
  }
  std::vector<Cluster> clusters(kk);
  for (int i = 0; i < n; ++i) clusters[assign[i]].members.push_back(i);
  clusters.erase(std::remove_if(clusters.begin(), clusters.end(),
                                [](const Cluster& c) { return c.members.empty(); }),
                 clusters.end());
  for (Cluster& c : clusters) {
    c.center = MeanOf(space, points, c.members);
    Finalize(space, points, &c);
  }
  return clusters;
}

int ElbowK(const std::vector<double>& sse) {
  const int n = static_cast<int>(sse.size());
  if (n < 3) return 1;
  const double y0 = sse.front(), y1 = sse.back();
  const double range = y0 - y1;
  if (!(range > 0.0)) return 1;
  // Normalised points (x in [0, 1], y in [0, 1]); chord from (0, 1) to (1, 0): x + y = 1.
  int best = 0;
  double best_gap = 0.0;
  for (int i = 1; i + 1 < n; ++i) {
    const double x = static_cast<double>(i) / (n - 1);
    const double y = (sse[i] - y1) / range;
    const double gap = 1.0 - x - y;  // below the chord = convex bend
    if (gap > best_gap) {
      best_gap = gap;
      best = i;
    }
  }
  return best_gap > 1e-9 ? best + 1 : 1;
}

std::vector<Cluster> ClusterByElbow(const BoxSpace& space, const std::vector<ActionVec>& points,
                                    int k_max, Rng& rng, const std::function<bool()>& stop) {
  std::vector<std::vector<Cluster>> runs;
  std::vector<double> sse;
  for (int k = 1; k <= k_max; ++k) {
    runs.push_back(KMeans(space, points, k, rng, stop));
    double total = 0.0;
    for (const Cluster& c : runs.back()) total += c.sse;
    sse.push_back(total);
    if (static_cast<int>(runs.back().size()) < k) break;  // no more distinct points
    if (stop && stop()) break;
  }
  if (runs.empty()) return {};
  const int k = std::min(ElbowK(sse), static_cast<int>(runs.size()));
  return runs[k - 1];
}

}  // namespace npfkct
