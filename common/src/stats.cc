#include "npfkct/common/stats.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace npfkct {
namespace {

// The continued fraction of the incomplete beta function (modified Lentz's method), valid for
// x < (a + 1) / (a + b + 2).
double BetaContinuedFraction(double x, double a, double b) {
  constexpr double kTiny = 1e-300;
  constexpr double kEps = 1e-15;
  const double qab = a + b, qap = a + 1.0, qam = a - 1.0;
  double c = 1.0;
  double d = 1.0 - qab * x / qap;
  if (std::abs(d) < kTiny) d = kTiny;
  d = 1.0 / d;
  double h = d;
  for (int m = 1; m <= 500; ++m) {
    const double m2 = 2.0 * m;
    double aa = m * (b - m) * x / ((qam + m2) * (a + m2));
    d = 1.0 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1.0 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    h *= d * c;
    aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
    d = 1.0 + aa * d;
    if (std::abs(d) < kTiny) d = kTiny;
    c = 1.0 + aa / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < kEps) break;
  }
  return h;
}

}  // namespace

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double RegularizedIncompleteBeta(double x, double a, double b) {
  if (!(x > 0.0)) return 0.0;
  if (!(x < 1.0)) return 1.0;
  const double log_front =
      std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x);
  const double front = std::exp(log_front);
  if (x < (a + 1.0) / (a + b + 2.0)) return front * BetaContinuedFraction(x, a, b) / a;
  return 1.0 - front * BetaContinuedFraction(1.0 - x, b, a) / b;
}

double StudentTCdf(double t, double df) {
  if (std::isnan(t) || !(df > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (std::isinf(t)) return t > 0 ? 1.0 : 0.0;
  const double tail = 0.5 * RegularizedIncompleteBeta(df / (df + t * t), 0.5 * df, 0.5);
  return t >= 0.0 ? 1.0 - tail : tail;
}

double StudentTQuantile(double p, double df) {
  if (!(p > 0.0 && p < 1.0) || !(df > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  if (p == 0.5) return 0.0;
  if (p < 0.5) return -StudentTQuantile(1.0 - p, df);
  // Bracket, then bisect on the monotone CDF to double precision.
  double lo = 0.0, hi = 1.0;
  while (StudentTCdf(hi, df) < p && hi < 1e12) hi *= 2.0;
  for (int i = 0; i < 200 && hi - lo > 1e-13 * std::max(1.0, hi); ++i) {
    const double mid = 0.5 * (lo + hi);
    if (StudentTCdf(mid, df) < p) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return 0.5 * (lo + hi);
}

MeanInterval MeanWithInterval(const std::vector<double>& v, double level) {
  MeanInterval m;
  m.n = static_cast<int>(v.size());
  if (m.n == 0) return m;
  double sum = 0.0;
  for (double x : v) sum += x;
  m.mean = sum / m.n;
  if (m.n < 2) return m;
  double ss = 0.0;
  for (double x : v) ss += (x - m.mean) * (x - m.mean);
  m.stddev = std::sqrt(ss / (m.n - 1));
  m.half_width = StudentTQuantile(0.5 * (1.0 + level), m.n - 1) * m.StandardError();
  return m;
}

double RatioHalfWidth95(const std::vector<int64_t>& hits, const std::vector<int64_t>& totals) {
  const size_t n = std::min(hits.size(), totals.size());
  double sum_hits = 0.0, sum_totals = 0.0;
  for (size_t i = 0; i < n; ++i) {
    sum_hits += static_cast<double>(hits[i]);
    sum_totals += static_cast<double>(totals[i]);
  }
  if (n < 2 || !(sum_totals > 0.0)) return 0.0;
  const double ratio = sum_hits / sum_totals;
  double ss = 0.0;  // residuals of the linearised ratio
  for (size_t i = 0; i < n; ++i) {
    const double d = static_cast<double>(hits[i]) - ratio * static_cast<double>(totals[i]);
    ss += d * d;
  }
  const double var =
      static_cast<double>(n) / static_cast<double>(n - 1) * ss / (sum_totals * sum_totals);
  return 1.959964 * std::sqrt(var);
}

}  // namespace npfkct
