// Continuous and hybrid action spaces: bounded boxes with a metric, and actions that combine a
// discrete kind with a continuous part.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/common/status.h"

namespace npfkct {

/// Largest dimension of a continuous action part. Vectors up to this size live inline (no heap).
inline constexpr int kMaxActionDim = 12;

/// A continuous action vector, stored inline.
using ActionVec = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxActionDim, 1>;

/// A bounded box [lower, upper] of R^d with the weighted Euclidean metric
/// d(a, b) = sqrt(sum_i (delta_i / scale_i)^2), where delta_i = a_i - b_i, or for a periodic
/// dimension (an angle) the shorter way round the circle of period upper_i - lower_i.
/// A box of dimension 0 is a single point.
class BoxSpace {
 public:
  /// The 0-dimensional space.
  BoxSpace() = default;
  /// A box with unit metric scales.
  BoxSpace(ActionVec lower, ActionVec upper);
  /// A box with the given metric scales (all positive).
  BoxSpace(ActionVec lower, ActionVec upper, ActionVec scale);

  /// Marks dimension `i` as periodic with period upper_i - lower_i (e.g. a yaw in [-pi, pi)).
  BoxSpace& SetPeriodic(int i);
  /// Whether dimension `i` is periodic.
  bool periodic(int i) const { return periodic_mask_ & (1u << i); }
  /// Whether dimension `i` has zero width (one value: e.g. the lift of a robot without one).
  /// Samplers move only in the other dimensions.
  bool fixed(int i) const { return !(upper_[i] > lower_[i]); }

  /// Checks bounds (finite, lower <= upper), scales (> 0) and the dimension limit.
  Status Validate() const;

  int dim() const { return static_cast<int>(lower_.size()); }
  const ActionVec& lower() const { return lower_; }
  const ActionVec& upper() const { return upper_; }
  const ActionVec& scale() const { return scale_; }

  /// Metric distance between two points of this space.
  double Distance(const ActionVec& a, const ActionVec& b) const;
  /// Squared metric distance.
  double SquaredDistance(const ActionVec& a, const ActionVec& b) const;
  /// Distance between opposite corners: the largest distance in the box.
  double Diameter() const;
  /// Whether `a` lies inside the box (bounds inclusive).
  bool Contains(const ActionVec& a) const;
  /// The nearest point of the box (periodic dimensions are wrapped into [lower, upper)).
  ActionVec Clamp(const ActionVec& a) const;
  /// The coordinate-wise difference a - b, the shorter way round for periodic dimensions.
  ActionVec Difference(const ActionVec& a, const ActionVec& b) const;
  /// Wraps periodic dimensions into [lower, upper); other dimensions are left as they are.
  ActionVec WrapPeriodic(const ActionVec& a) const;
  /// A point drawn uniformly from the box.
  ActionVec SampleUniform(Rng& rng) const;
  /// A point drawn uniformly from the metric ball of `radius` around `center`, intersected with
  /// the box (rejection sampling; after `max_tries` misses the last draw is clamped into the box).
  ActionVec SampleInBall(const ActionVec& center, double radius, Rng& rng,
                         int max_tries = 32) const;
  /// A point drawn from the isotropic Gaussian (in metric units) of standard deviation `stddev`
  /// around `center`, clamped into the box.
  ActionVec SampleGaussian(const ActionVec& center, double stddev, Rng& rng) const;

 private:
  ActionVec lower_ = ActionVec(0);
  ActionVec upper_ = ActionVec(0);
  ActionVec scale_ = ActionVec(0);
  uint32_t periodic_mask_ = 0;
};

/// An action of a hybrid space: a discrete `kind` and, when the kind has a continuous part, a
/// point `x` of that kind's box. Purely discrete kinds have x.size() == 0.
struct HybridAction {
  int kind = 0;
  ActionVec x = ActionVec(0);

  friend bool operator==(const HybridAction& a, const HybridAction& b) {
    return a.kind == b.kind && a.x.size() == b.x.size() && (a.x.array() == b.x.array()).all();
  }
  /// "kind[x0, x1, ...]" for logs and tests.
  std::string ToString() const;
};

/// Makes an ActionVec from a list of values.
ActionVec MakeActionVec(std::initializer_list<double> values);

}  // namespace npfkct
