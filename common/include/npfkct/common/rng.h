// The random number generator every planner, model and belief draws from.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

namespace npfkct {

/// A fast, seedable pseudo-random generator (xoshiro256++ seeded by splitmix64). It satisfies
/// std::uniform_random_bit_generator. There is no global generator: every function that draws
/// random numbers takes an `Rng&`, so that sessions planning at once never share state and a fixed
/// seed reproduces a run exactly.
class Rng {
 public:
  using result_type = uint64_t;

  /// A generator whose whole stream is determined by `seed`.
  explicit Rng(uint64_t seed = 0x9e3779b97f4a7c15ULL) { Seed(seed); }

  /// Restarts the stream from `seed`.
  void Seed(uint64_t seed) {
    for (auto& word : s_) word = SplitMix64(seed);
  }

  static constexpr result_type min() { return 0; }
  static constexpr result_type max() { return std::numeric_limits<result_type>::max(); }

  /// The next 64 random bits.
  result_type operator()() {
    const uint64_t result = Rotl(s_[0] + s_[3], 23) + s_[0];
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = Rotl(s_[3], 45);
    return result;
  }

  /// Uniform in [0, 1).
  double Uniform() { return static_cast<double>((*this)() >> 11) * 0x1.0p-53; }
  /// Uniform in [lo, hi).
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  /// Uniform integer in [0, n); n must be positive.
  int64_t UniformInt(int64_t n) {
    // Lemire's multiply-shift; the bias for n << 2^64 is negligible for planning purposes.
    return static_cast<int64_t>(
        (static_cast<unsigned __int128>((*this)()) * static_cast<unsigned __int128>(n)) >> 64);
  }
  /// True with probability p.
  bool Bernoulli(double p) { return Uniform() < p; }
  /// Standard normal sample (Marsaglia polar method, no cached state).
  double Normal() {
    double u, v, s;
    do {
      u = 2.0 * Uniform() - 1.0;
      v = 2.0 * Uniform() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    return u * std::sqrt(-2.0 * std::log(s) / s);
  }
  /// Normal sample with the given mean and standard deviation.
  double Normal(double mean, double stddev) { return mean + stddev * Normal(); }

  /// A new generator whose stream is independent of this one's continuation.
  Rng Split() { return Rng((*this)()); }

 private:
  static uint64_t Rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  static uint64_t SplitMix64(uint64_t& x) {
    uint64_t z = (x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }

  uint64_t s_[4];
};

}  // namespace npfkct
