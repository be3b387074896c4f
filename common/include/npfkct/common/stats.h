// Summary statistics for benchmark reports: medians, Student's t quantiles and t confidence
// intervals of a mean.
//
//   const MeanInterval m = MeanWithInterval(rewards);           // 95% by default
//   std::printf("%.1f ± %.1f (n = %d)", m.mean, m.half_width, m.n);
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

namespace npfkct {

/// The median of `v` (the mean of the two middle values for an even count; 0 when empty).
double Median(std::vector<double> v);

/// The regularized incomplete beta function I_x(a, b) for a, b > 0 and x in [0, 1].
double RegularizedIncompleteBeta(double x, double a, double b);

/// The CDF of Student's t distribution with `df` > 0 degrees of freedom.
double StudentTCdf(double t, double df);

/// The p-quantile of Student's t distribution with `df` > 0 degrees of freedom (p in (0, 1)),
/// e.g. StudentTQuantile(0.975, 19) = 2.093.
double StudentTQuantile(double p, double df);

/// A sample mean with the half-width of its two-sided confidence interval by Student's t.
struct MeanInterval {
  int n = 0;
  double mean = 0.0;
  double stddev = 0.0;      ///< Sample standard deviation (n - 1 in the denominator).
  double half_width = 0.0;  ///< t_{(1 + level) / 2, n - 1} stddev / sqrt(n); 0 when n < 2.
  /// The standard error of the mean, stddev / sqrt(n); 0 when n < 2.
  double StandardError() const { return n > 0 ? stddev / std::sqrt(static_cast<double>(n)) : 0.0; }
};

/// The mean of `v` and its `level` (default 95%) Student's t confidence interval.
MeanInterval MeanWithInterval(const std::vector<double>& v, double level = 0.95);

/// Half-width of the normal 95% interval of the ratio sum(hits) / sum(totals) over independent
/// units (unit i: hits[i] of totals[i]), by the delta method; 0 with fewer than 2 units or no
/// totals. Sizes must agree.
double RatioHalfWidth95(const std::vector<int64_t>& hits, const std::vector<int64_t>& totals);

}  // namespace npfkct
