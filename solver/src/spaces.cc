#include "npfkct/solver/spaces.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace npfkct {

BoxSpace::BoxSpace(ActionVec lower, ActionVec upper)
    : lower_(std::move(lower)), upper_(std::move(upper)), scale_(ActionVec::Ones(lower_.size())) {}

BoxSpace::BoxSpace(ActionVec lower, ActionVec upper, ActionVec scale)
    : lower_(std::move(lower)), upper_(std::move(upper)), scale_(std::move(scale)) {}

Status BoxSpace::Validate() const {
  if (lower_.size() != upper_.size() || lower_.size() != scale_.size()) {
    return InvalidArgumentError("box: lower, upper and scale must have the same dimension");
  }
  if (lower_.size() > kMaxActionDim) {
    return InvalidArgumentError("box: dimension " + std::to_string(lower_.size()) +
                                " exceeds the limit " + std::to_string(kMaxActionDim));
  }
  for (int i = 0; i < lower_.size(); ++i) {
    if (!std::isfinite(lower_[i]) || !std::isfinite(upper_[i])) {
      return InvalidArgumentError("box: bound " + std::to_string(i) + " is not finite");
    }
    if (lower_[i] > upper_[i]) {
      return InvalidArgumentError("box: lower[" + std::to_string(i) + "] > upper[" +
                                  std::to_string(i) + "]");
    }
    if (!(scale_[i] > 0.0) || !std::isfinite(scale_[i])) {
      return InvalidArgumentError("box: scale[" + std::to_string(i) + "] must be positive");
    }
  }
  return OkStatus();
}

BoxSpace& BoxSpace::SetPeriodic(int i) {
  if (i >= 0 && i < 32) periodic_mask_ |= (1u << i);
  return *this;
}

ActionVec BoxSpace::Difference(const ActionVec& a, const ActionVec& b) const {
  ActionVec d = a - b;
  if (periodic_mask_ != 0) {
    for (int i = 0; i < d.size(); ++i) {
      if (!periodic(i)) continue;
      const double period = upper_[i] - lower_[i];
      if (period <= 0.0) continue;
      d[i] = std::remainder(d[i], period);  // in [-period/2, period/2]
    }
  }
  return d;
}

double BoxSpace::SquaredDistance(const ActionVec& a, const ActionVec& b) const {
  return (Difference(a, b).array() / scale_.array()).square().sum();
}

double BoxSpace::Distance(const ActionVec& a, const ActionVec& b) const {
  return std::sqrt(SquaredDistance(a, b));
}

double BoxSpace::Diameter() const {
  double sum = 0.0;
  for (int i = 0; i < dim(); ++i) {
    const double width = (upper_[i] - lower_[i]) * (periodic(i) ? 0.5 : 1.0);
    sum += (width / scale_[i]) * (width / scale_[i]);
  }
  return std::sqrt(sum);
}

bool BoxSpace::Contains(const ActionVec& a) const {
  if (a.size() != lower_.size()) return false;
  for (int i = 0; i < a.size(); ++i) {
    if (!(a[i] >= lower_[i] && a[i] <= upper_[i])) return false;
  }
  return true;
}

ActionVec BoxSpace::Clamp(const ActionVec& a) const {
  ActionVec c = WrapPeriodic(a);
  for (int i = 0; i < c.size(); ++i) c[i] = std::clamp(c[i], lower_[i], upper_[i]);
  return c;
}

ActionVec BoxSpace::SampleUniform(Rng& rng) const {
  ActionVec x = ActionVec::Zero(lower_.size());
  for (int i = 0; i < x.size(); ++i) x[i] = rng.Uniform(lower_[i], upper_[i]);
  return x;
}

ActionVec BoxSpace::SampleInBall(const ActionVec& center, double radius, Rng& rng,
                                 int max_tries) const {
  const int d = dim();
  if (d == 0) return center;
  // A dimension of zero width (a robot without a lift) holds its one value: the ball is drawn in
  // the others, as in a space without it.
  int free_dims = 0;
  for (int i = 0; i < d; ++i) free_dims += !fixed(i);
  if (free_dims == 0) return Clamp(center);
  ActionVec x = ActionVec::Zero(d);
  for (int attempt = 0; attempt < max_tries; ++attempt) {
    // Uniform direction from a Gaussian, radius ~ r U^(1/d): uniform in the ball.
    ActionVec dir = ActionVec::Zero(d);
    double norm2 = 0.0;
    do {
      for (int i = 0; i < d; ++i) dir[i] = fixed(i) ? 0.0 : rng.Normal();
      norm2 = dir.squaredNorm();
    } while (norm2 == 0.0);
    const double r = radius * std::pow(rng.Uniform(), 1.0 / free_dims);
    x = center + (dir.array() * (r / std::sqrt(norm2)) * scale_.array()).matrix();
    for (int i = 0; i < d; ++i) {
      if (fixed(i)) x[i] = lower_[i];
    }
    if (periodic_mask_ != 0) x = WrapPeriodic(x);
    if (Contains(x)) return x;
  }
  return Clamp(x);
}

ActionVec BoxSpace::WrapPeriodic(const ActionVec& a) const {
  ActionVec c = a;
  for (int i = 0; i < c.size(); ++i) {
    if (!periodic(i) || !(upper_[i] > lower_[i])) continue;
    const double period = upper_[i] - lower_[i];
    c[i] = lower_[i] + std::fmod(std::fmod(c[i] - lower_[i], period) + period, period);
    if (c[i] >= upper_[i]) c[i] = lower_[i];
  }
  return c;
}

ActionVec BoxSpace::SampleGaussian(const ActionVec& center, double stddev, Rng& rng) const {
  ActionVec x = ActionVec::Zero(dim());
  for (int i = 0; i < x.size(); ++i) x[i] = center[i] + stddev * scale_[i] * rng.Normal();
  return Clamp(x);
}

std::string HybridAction::ToString() const {
  std::ostringstream out;
  out << kind << "[";
  for (int i = 0; i < x.size(); ++i) out << (i ? ", " : "") << x[i];
  out << "]";
  return out.str();
}

ActionVec MakeActionVec(std::initializer_list<double> values) {
  ActionVec v(static_cast<Eigen::Index>(values.size()));
  int i = 0;
  for (double value : values) v[i++] = value;
  return v;
}

}  // namespace npfkct
