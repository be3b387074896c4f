// Weighted particle beliefs with a generic particle-filter update and reinvigoration.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "npfkct/common/rng.h"
#include "npfkct/common/status.h"
#include "npfkct/solver/model.h"

namespace npfkct {

/// How healthy a belief came out of an update.
enum class BeliefHealth {
  kHealthy,        ///< Enough particles were consistent with the observation.
  kReinvigorated,  ///< Some or all particles were replaced by reinvigoration.
  kDepleted,       ///< No particle was consistent and none could be reinvigorated; the belief
                   ///< holds the unweighted prediction (the observation was ignored).
};

/// "healthy", "reinvigorated" or "depleted".
inline const char* BeliefHealthName(BeliefHealth h) {
  switch (h) {
    case BeliefHealth::kHealthy:
      return "healthy";
    case BeliefHealth::kReinvigorated:
      return "reinvigorated";
    case BeliefHealth::kDepleted:
      return "depleted";
  }
  return "unknown";
}

/// How to update a particle belief.
struct BeliefUpdateOptions {
  enum class Method {
    kAuto,        ///< Likelihood weighting when the model has Z(o | a, s'), else rejection.
    kLikelihood,  ///< Likelihood weighting (needs ObservationLikelihood).
    kRejection,   ///< Keep simulated successors whose observation equals the real one.
  };
  Method method = Method::kAuto;
  /// Particles after the update; 0 keeps the current count.
  int num_particles = 0;
  /// Resample when the effective sample size falls below this fraction of the particles.
  double resample_threshold = 0.5;
  /// Rejection sampling gives up after this many simulations per wanted particle.
  int max_attempts_per_particle = 64;
  /// Fraction of particles replaced by model reinvigoration after every update (0 = only when
  /// particles run short). Needs the model's Reinvigorate.
  double reinvigoration_fraction = 0.0;

  /// Checks every field; the message names the offending one.
  Status Validate() const {
    if (num_particles < 0) return InvalidArgumentError("num_particles must be >= 0");
    if (!(resample_threshold >= 0.0 && resample_threshold <= 1.0)) {
      return InvalidArgumentError("resample_threshold must be in [0, 1]");
    }
    if (max_attempts_per_particle < 1) {
      return InvalidArgumentError("max_attempts_per_particle must be >= 1");
    }
    if (!(reinvigoration_fraction >= 0.0 && reinvigoration_fraction <= 1.0)) {
      return InvalidArgumentError("reinvigoration_fraction must be in [0, 1]");
    }
    return OkStatus();
  }
};

/// What a belief update did.
struct BeliefUpdateSummary {
  BeliefHealth health = BeliefHealth::kHealthy;
  int num_particles = 0;             ///< Particles after the update.
  int consistent = 0;                ///< Particles consistent with the observation.
  int reinvigorated = 0;             ///< Particles produced by reinvigoration.
  double effective_sample_size = 0;  ///< ESS right after weighting (before resampling).
  int64_t simulations = 0;           ///< Calls of the generative model.
};

/// A belief represented by weighted particles.
template <class State>
class ParticleBelief {
 public:
  /// An empty belief.
  ParticleBelief() = default;
  /// Equally weighted particles.
  explicit ParticleBelief(std::vector<State> particles)
      : particles_(std::move(particles)), weights_(particles_.size(), 1.0) {
    Recompute();
  }
  /// Weighted particles; weights must be non-negative with a positive sum.
  ParticleBelief(std::vector<State> particles, std::vector<double> weights)
      : particles_(std::move(particles)), weights_(std::move(weights)) {
    Recompute();
  }

  /// `n` particles drawn from the model's initial distribution.
  template <GenerativeModel M>
  static ParticleBelief FromInitial(const M& model, int n, Rng& rng) {
    std::vector<State> particles;
    particles.reserve(n);
    for (int i = 0; i < n; ++i) particles.push_back(model.SampleInitialState(rng));
    return ParticleBelief(std::move(particles));
  }

  int size() const { return static_cast<int>(particles_.size()); }
  bool empty() const { return particles_.empty(); }
  const State& particle(int i) const { return particles_[i]; }
  double weight(int i) const { return weights_[i]; }
  const std::vector<State>& particles() const { return particles_; }
  const std::vector<double>& weights() const { return weights_; }
  double total_weight() const { return total_; }

  /// The weighted mean of f(particle) (a number or a fixed-size Eigen vector). The belief must not
  /// be empty and its total weight must be positive.
  template <class F>
  std::invoke_result_t<F, const State&> Mean(F f) const {
    std::invoke_result_t<F, const State&> sum = f(particles_[0]) * (weights_[0] / total_);
    for (int i = 1; i < size(); ++i) sum += f(particles_[i]) * (weights_[i] / total_);
    return sum;
  }

  /// A particle drawn in proportion to its weight. The belief must not be empty.
  const State& Sample(Rng& rng) const {
    if (uniform_) return particles_[rng.UniformInt(size())];
    const double u = rng.Uniform() * total_;
    const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), u);
    const auto i = std::min<std::ptrdiff_t>(it - cumulative_.begin(), size() - 1);
    return particles_[i];
  }

  /// (sum w)^2 / sum w^2.
  double EffectiveSampleSize() const {
    double sq = 0.0;
    for (double w : weights_) sq += w * w;
    return sq > 0.0 ? total_ * total_ / sq : 0.0;
  }

  /// Replaces the particles by `n` equally weighted ones (systematic resampling).
  void Resample(int n, Rng& rng) {
    if (empty() || n <= 0) return;
    std::vector<State> out;
    out.reserve(n);
    const double step = total_ / n;
    double u = rng.Uniform() * step;
    int i = 0;
    double cum = weights_[0];
    for (int k = 0; k < n; ++k) {
      while (u > cum && i + 1 < size()) cum += weights_[++i];
      out.push_back(particles_[i]);
      u += step;
    }
    particles_ = std::move(out);
    weights_.assign(particles_.size(), 1.0);
    Recompute();
  }

  /// Bayes update after the real step (a, o). Rejection or likelihood weighting (see options);
  /// when particles run out, the model's Reinvigorate fills them; when that is impossible the
  /// belief keeps the unweighted prediction and reports kDepleted. Never throws.
  template <GenerativeModel M>
  BeliefUpdateSummary Update(const M& model, const typename M::Action& a,
                             const typename M::Observation& o, Rng& rng,
                             const BeliefUpdateOptions& options = {}) {
    BeliefUpdateSummary summary;
    if (empty()) {
      summary.health = BeliefHealth::kDepleted;
      return summary;
    }
    const int n = options.num_particles > 0 ? options.num_particles : size();
    using Method = BeliefUpdateOptions::Method;
    bool use_likelihood = options.method == Method::kLikelihood;
    if (options.method == Method::kAuto) use_likelihood = HasObservationLikelihood<M>;

    if constexpr (HasObservationLikelihood<M>) {
      if (use_likelihood) return UpdateByLikelihood(model, a, o, n, rng, options);
    }
    return UpdateByRejection(model, a, o, n, rng, options);
  }

 private:
  template <GenerativeModel M>
  BeliefUpdateSummary UpdateByLikelihood(const M& model, const typename M::Action& a,
                                         const typename M::Observation& o, int n, Rng& rng,
                                         const BeliefUpdateOptions& options) {
    BeliefUpdateSummary summary;
    std::vector<State> next;
    std::vector<double> w;
    next.reserve(size());
    w.reserve(size());
    // Draw the predicted particles from the current weights so that the result is an unweighted
    // sample times the likelihood: this keeps heavy particles from dominating after many steps.
    for (int i = 0; i < n; ++i) {
      const State& s = Sample(rng);
      auto step = model.Step(s, a, rng);
      ++summary.simulations;
      // Models that keep history in the state (e.g. RockSample's evidence counts) rewrite it as if
      // the real observation had been generated.
      if constexpr (requires { model.Condition(s, a, o, &step.state); }) {
        model.Condition(s, a, o, &step.state);
      }
      double z = model.ObservationLikelihood(a, step.state, o);
      if (!std::isfinite(z) || z < 0.0) z = 0.0;
      if (z > 0.0) ++summary.consistent;
      next.push_back(std::move(step.state));
      w.push_back(z);
    }
    double total = 0.0;
    for (double z : w) total += z;
    if (!(total > 0.0) || !std::isfinite(total)) {
      return Deplete(model, a, o, std::move(next), n, rng, summary);
    }
    particles_ = std::move(next);
    weights_ = std::move(w);
    Recompute();
    summary.effective_sample_size = EffectiveSampleSize();
    if (summary.effective_sample_size < options.resample_threshold * n) Resample(n, rng);
    summary.reinvigorated = ReinvigorateFraction(model, a, o, options, rng);
    summary.health =
        summary.reinvigorated > 0 ? BeliefHealth::kReinvigorated : BeliefHealth::kHealthy;
    summary.num_particles = size();
    return summary;
  }

  template <GenerativeModel M>
  BeliefUpdateSummary UpdateByRejection(const M& model, const typename M::Action& a,
                                        const typename M::Observation& o, int n, Rng& rng,
                                        const BeliefUpdateOptions& options) {
    BeliefUpdateSummary summary;
    std::vector<State> next;
    std::vector<State> predicted;  // kept in case nothing is accepted
    next.reserve(n);
    const int64_t max_attempts = static_cast<int64_t>(n) * options.max_attempts_per_particle;
    for (int64_t attempt = 0; attempt < max_attempts && static_cast<int>(next.size()) < n;
         ++attempt) {
      auto step = model.Step(Sample(rng), a, rng);
      ++summary.simulations;
      if (step.observation == o) {
        next.push_back(std::move(step.state));
      } else if (static_cast<int>(predicted.size()) < n) {
        predicted.push_back(std::move(step.state));
      }
    }
    summary.consistent = static_cast<int>(next.size());
    summary.effective_sample_size = summary.consistent;
    if (next.empty()) return Deplete(model, a, o, std::move(predicted), n, rng, summary);
    // Fill the shortfall by reinvigoration, else by duplicating accepted particles.
    while (static_cast<int>(next.size()) < n) {
      State fresh;
      const State& near = next[rng.UniformInt(summary.consistent)];
      if (TryReinvigorate(model, near, a, o, rng, &fresh)) {
        next.push_back(std::move(fresh));
        ++summary.reinvigorated;
      } else {
        next.push_back(next[rng.UniformInt(summary.consistent)]);
      }
    }
    particles_ = std::move(next);
    weights_.assign(particles_.size(), 1.0);
    Recompute();
    summary.reinvigorated += ReinvigorateFraction(model, a, o, options, rng);
    summary.health =
        summary.reinvigorated > 0 ? BeliefHealth::kReinvigorated : BeliefHealth::kHealthy;
    summary.num_particles = size();
    return summary;
  }

  template <GenerativeModel M>
  static bool TryReinvigorate(const M& model, const State& near, const typename M::Action& a,
                              const typename M::Observation& o, Rng& rng, State* out) {
    if constexpr (requires {
                    { model.Reinvigorate(near, a, o, rng, out) } -> std::same_as<bool>;
                  }) {
      return model.Reinvigorate(near, a, o, rng, out);
    } else {
      (void)model, (void)near, (void)a, (void)o, (void)rng, (void)out;
      return false;
    }
  }

  template <GenerativeModel M>
  int ReinvigorateFraction(const M& model, const typename M::Action& a,
                           const typename M::Observation& o, const BeliefUpdateOptions& options,
                           Rng& rng) {
    const int count = static_cast<int>(options.reinvigoration_fraction * size());
    if (count == 0) return 0;
    // Resample-move: moves are applied to equally weighted particles, each to the particle it
    // starts from, so that moves which preserve the posterior (Metropolis-Hastings) keep it.
    if (!uniform_) Resample(size(), rng);
    int done = 0;
    for (int k = 0; k < count; ++k) {
      State fresh;
      const int i = static_cast<int>(rng.UniformInt(size()));
      if (!TryReinvigorate(model, particles_[i], a, o, rng, &fresh)) continue;
      particles_[i] = std::move(fresh);
      ++done;
    }
    return done;
  }

  template <GenerativeModel M>
  BeliefUpdateSummary Deplete(const M& model, const typename M::Action& a,
                              const typename M::Observation& o, std::vector<State> predicted, int n,
                              Rng& rng, BeliefUpdateSummary summary) {
    std::vector<State> fresh;
    const int max_tries = n * 4;
    for (int i = 0; i < max_tries && !predicted.empty() && static_cast<int>(fresh.size()) < n;
         ++i) {
      State s;
      const State& near = predicted[rng.UniformInt(static_cast<int64_t>(predicted.size()))];
      if (TryReinvigorate(model, near, a, o, rng, &s)) fresh.push_back(std::move(s));
    }
    if (!fresh.empty()) {
      summary.health = BeliefHealth::kReinvigorated;
      summary.reinvigorated = static_cast<int>(fresh.size());
      particles_ = std::move(fresh);
    } else {
      summary.health = BeliefHealth::kDepleted;
      if (!predicted.empty()) particles_ = std::move(predicted);
    }
    weights_.assign(particles_.size(), 1.0);
    Recompute();
    summary.num_particles = size();
    return summary;
  }

  void Recompute() {
    cumulative_.resize(weights_.size());
    total_ = 0.0;
    uniform_ = true;
    for (size_t i = 0; i < weights_.size(); ++i) {
      total_ += weights_[i];
      cumulative_[i] = total_;
      if (weights_[i] != weights_[0]) uniform_ = false;
    }
  }

  std::vector<State> particles_;
  std::vector<double> weights_;
  std::vector<double> cumulative_;
  double total_ = 0.0;
  bool uniform_ = true;
};

/// RolloutFirst's action (search.rollout_first): the model's BeliefRolloutAction(belief, rng) when
/// it has one (a policy of the whole belief, such as the LQR action at its mean, as VOOTreeSearch's
/// RolloutFirst takes), else its RolloutAction at `s`, a state drawn from the belief.
template <class M, class State>
auto RolloutFirstAction(const M& model, const ParticleBelief<State>& belief, const State& s,
                        Rng& rng) {
  if constexpr (requires { model.BeliefRolloutAction(belief, rng); }) {
    return model.BeliefRolloutAction(belief, rng);
  } else {
    return model.RolloutAction(s, rng);
  }
}

}  // namespace npfkct
