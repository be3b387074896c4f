#include "npfkct/filter/train.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include "network.h"
#include "npfkct/common/stats.h"
#include "npfkct/solver/planner.h"

namespace npfkct::filter {
namespace {

// KL(N(mq, sq) || N(mp, sp)) summed over the latent dimensions: [B].
torch::Tensor Kl(const torch::Tensor& mq, const torch::Tensor& sq, const torch::Tensor& mp,
                 const torch::Tensor& sp) {
  return (torch::log(sp / sq) + (sq * sq + (mq - mp).pow(2)) / (2 * sp * sp) - 0.5).sum(1);
}

// The validation loss: the NLL per target with z at the context's latent mean.
double ValidationLoss(NpNet& net, const Dataset& val, int context) {
  torch::NoGradGuard no_grad;
  net->eval();
  double total = 0.0;
  int64_t count = 0;
  const int n = static_cast<int>(val.samples.size());
  for (int start = 0; start < n; start += 64) {
    std::vector<int> idx;
    for (int i = start; i < std::min(n, start + 64); ++i) idx.push_back(i);
    const Batch b = MakeBatch(val, idx, context, false, nullptr);
    auto [mu, sigma] = PredictBatch(net, b);
    total += GaussianNll(mu, sigma, b.yt.squeeze(2)).sum().item<double>();
    count += mu.numel();
  }
  net->train();
  return count > 0 ? total / static_cast<double>(count) : 0.0;
}

}  // namespace

Status TrainOptions::Validate() const {
  if (epochs < 1) return InvalidArgumentError("epochs must be >= 1");
  if (batch < 1) return InvalidArgumentError("batch must be >= 1");
  if (!(learning_rate > 0.0) || !std::isfinite(learning_rate)) {
    return InvalidArgumentError("learning_rate must be > 0");
  }
  if (!(weight_decay >= 0.0) || !std::isfinite(weight_decay)) {
    return InvalidArgumentError("weight_decay must be >= 0");
  }
  if (lr_decay_every < 1) return InvalidArgumentError("lr_decay_every must be >= 1");
  if (!(lr_decay > 0.0 && lr_decay <= 1.0)) {
    return InvalidArgumentError("lr_decay must be in (0, 1]");
  }
  if (patience < 1) return InvalidArgumentError("patience must be >= 1");
  if (min_context < 1 || max_context < min_context) {
    return InvalidArgumentError("min_context and max_context must satisfy 1 <= min <= max");
  }
  if (eval_context < 1) return InvalidArgumentError("eval_context must be >= 1");
  return OkStatus();
}

StatusOr<TrainReport> TrainFilter(const Dataset& train, const Dataset& val,
                                  const TrainOptions& options, const std::string& path,
                                  const std::function<void(int, int, int, double)>& step_progress,
                                  const std::function<void(const EpochReport&)>& epoch_done) {
  if (Status s = options.Validate(); !s.ok()) return s;
  if (train.samples.empty()) return InvalidArgumentError("train: no samples");
  if (val.samples.empty()) return InvalidArgumentError("val: no samples");
  if (options.max_context >= train.queries_per_sample) {
    return InvalidArgumentError("max_context must be below the training queries per sample");
  }
  if (options.eval_context >= val.queries_per_sample) {
    return InvalidArgumentError("eval_context must be below the validation queries per sample");
  }
  torch::manual_seed(options.seed);
  std::mt19937_64 gen(options.seed);
  NpNet net;
  net->train();
  torch::optim::Adam optimizer(
      net->parameters(),
      torch::optim::AdamOptions(options.learning_rate).weight_decay(options.weight_decay));
  TrainReport report;
  report.best_val_loss = std::numeric_limits<double>::infinity();
  const int n = static_cast<int>(train.samples.size());
  const int steps = (n + options.batch - 1) / options.batch;
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  for (int epoch = 1; epoch <= options.epochs; ++epoch) {
    const auto t0 = Clock::now();
    std::shuffle(order.begin(), order.end(), gen);
    double running = 0.0;
    for (int step = 0; step < steps; ++step) {
      const std::vector<int> idx(order.begin() + step * options.batch,
                                 order.begin() + std::min(n, (step + 1) * options.batch));
      const int context =
          std::uniform_int_distribution<int>(options.min_context, options.max_context)(gen);
      const Batch b = MakeBatch(train, idx, context, true, &gen);
      // ELBO: the targets' likelihood under z from the posterior (all queries), and the KL
      // divergence from the prior (context only), per target.
      const torch::Tensor scene = net->EncodeScene(b.points, b.image);
      const torch::Tensor xc = net->EncodeQuery(b.xc);
      const torch::Tensor xt = net->EncodeQuery(b.xt);
      auto [mp, sp] = net->Latent(scene, xc, b.yc);
      auto [mq, sq] = net->Latent(scene, xt, b.yt);
      const torch::Tensor z = mq + sq * torch::randn_like(sq);
      auto [mu, sigma] = net->Decode(scene, xt, net->Deterministic(scene, xc, b.yc, xt), z);
      const torch::Tensor nll = GaussianNll(mu, sigma, b.yt.squeeze(2)).mean();
      const torch::Tensor kl = Kl(mq, sq, mp, sp).mean() / static_cast<double>(xt.size(1));
      const torch::Tensor loss = nll + kl;
      optimizer.zero_grad();
      loss.backward();
      torch::nn::utils::clip_grad_norm_(net->parameters(), 5.0);
      optimizer.step();
      const double l = loss.item<double>();
      running = step == 0 ? l : 0.95 * running + 0.05 * l;
      if (step_progress) step_progress(epoch, step + 1, steps, running);
    }
    EpochReport e;
    e.epoch = epoch;
    e.train_loss = running;
    e.val_loss = ValidationLoss(net, val, options.eval_context);
    e.seconds = MillisSince(t0) / 1000.0;
    report.epochs.push_back(e);
    if (e.val_loss < report.best_val_loss) {
      report.best_val_loss = e.val_loss;
      report.best_epoch = epoch;
      if (Status s = SaveNet(net, path); !s.ok()) return s;
    }
    if (epoch_done) epoch_done(e);
    if (epoch - report.best_epoch >= options.patience) break;  // no better epoch for a while
    if (epoch % options.lr_decay_every == 0) {
      for (auto& group : optimizer.param_groups()) {
        auto& o = static_cast<torch::optim::AdamOptions&>(group.options());
        o.lr(o.lr() * options.lr_decay);
      }
    }
  }
  return report;
}

StatusOr<FilterMetrics> EvaluateFilter(const NeuralFilter& filter, const Dataset& test,
                                       const FilterOptions& options) {
  if (Status s = options.Validate(); !s.ok()) return s;
  if (options.context >= test.queries_per_sample) {
    return InvalidArgumentError("context must be below the test queries per sample");
  }
  FilterMetrics m;
  const double beta = options.Beta();
  int64_t useless = 0, zero = 0, kept = 0, dropped = 0, correct = 0, specific = 0, within = 0;
  int64_t clear = 0, clear_correct = 0;
  std::vector<int64_t> sample_correct, sample_efficient;  // per sample, for the interval
  double abs_error = 0.0;
  const size_t c = static_cast<size_t>(options.context);
  for (const Sample& s : test.samples) {
    const std::vector<float> cq(s.queries.begin(), s.queries.begin() + c * kQueryDim);
    const std::vector<float> cs(s.scores.begin(), s.scores.begin() + c);
    const std::vector<float> q(s.queries.begin() + c * kQueryDim, s.queries.end());
    const Prediction p = filter.Predict(s.scene, cq, cs, q);
    const int64_t correct_before = correct, efficient_before = m.efficient;
    for (size_t i = 0; i < p.mu.size(); ++i) {
      const double g = s.scores[c + i], mu = p.mu[i], sigma = p.sigma[i];
      ++m.queries;
      abs_error += std::abs(g - mu);
      if (std::abs(g - mu) <= 2 * sigma) ++within;
      const bool pass = mu > beta * sigma;
      if (g > kEfficientScore) {
        ++m.efficient;
        if (mu >= kEfficientScore) ++correct;
        if (pass) ++kept;
        if (g > 2 * kEfficientScore) {
          ++clear;
          if (mu >= kEfficientScore) ++clear_correct;
        }
      } else {
        ++useless;
        if (mu < kEfficientScore) ++specific;
      }
      if (g == 0.0) {
        ++zero;
        if (!pass) ++dropped;
      }
    }
    sample_correct.push_back(correct - correct_before);
    sample_efficient.push_back(m.efficient - efficient_before);
  }
  auto ratio = [](int64_t a, int64_t b) { return b > 0 ? static_cast<double>(a) / b : 0.0; };
  m.accuracy = ratio(correct, m.efficient);
  m.accuracy_ci95 = RatioHalfWidth95(sample_correct, sample_efficient);
  m.accuracy_clear = ratio(clear_correct, clear);
  m.specificity = ratio(specific, useless);
  m.kept_efficient = ratio(kept, m.efficient);
  m.dropped_useless = ratio(dropped, zero);
  m.mean_abs_error = m.queries > 0 ? abs_error / m.queries : 0.0;
  m.within_2_sigma = ratio(within, m.queries);
  return m;
}

}  // namespace npfkct::filter
