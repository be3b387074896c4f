// k-means clustering of continuous actions into enclosing hyperspheres, with the elbow method.
#pragma once

#include <functional>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/solver/spaces.h"

namespace npfkct {

/// A cluster of points and the metric ball around its center that encloses them.
struct Cluster {
  ActionVec center;
  double radius = 0.0;       ///< Largest metric distance of a member to the center.
  double sse = 0.0;          ///< Sum of squared metric distances of the members to the center.
  std::vector<int> members;  ///< Indices into the clustered points.
};

/// k-means under `space`'s metric (periodic dimensions handled): k-means++ seeding, then Lloyd
/// iterations until assignments stop changing, `max_iterations`, or `stop` (if given) returns
/// true after an iteration. Returns min(k, #distinct points) non-empty clusters; an empty input
/// gives no clusters.
std::vector<Cluster> KMeans(const BoxSpace& space, const std::vector<ActionVec>& points, int k,
                            Rng& rng, const std::function<bool()>& stop = {},
                            int max_iterations = 50);

/// The elbow of a decreasing curve sse[0..n-1] (sse[i] for k = i + 1): the k whose point lies
/// farthest from the chord between the first and last points, after normalising both axes.
/// Returns 1 for curves of fewer than 3 points or without a bend.
int ElbowK(const std::vector<double>& sse);

/// Runs k-means for k = 1..k_max and returns the clustering at the elbow (Thorndike 1953). When
/// `stop` (if given) returns true, the elbow of the runs made so far (the last one cut short).
std::vector<Cluster> ClusterByElbow(const BoxSpace& space, const std::vector<ActionVec>& points,
                                    int k_max, Rng& rng, const std::function<bool()>& stop = {});

}  // namespace npfkct
