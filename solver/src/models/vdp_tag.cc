#include "npfkct/solver/models/vdp_tag.h"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace npfkct::models {
namespace {

constexpr double kMu = 2.0;
constexpr double kDt = 0.1;
constexpr int kSubsteps = 5;  // round(step_size / dt) with step_size 0.5
constexpr double kStepLength = 0.5;
constexpr double kTagRadius = 0.1;
constexpr double kPosStd = 0.05;
constexpr double kActiveStd = 0.1;
constexpr double kPassiveStd = 5.0;
constexpr double kLookCost = 5.0;
constexpr double kBarrierStart = 0.2;
constexpr double kBarrierLength = 2.8;
constexpr double kTwoPi = 2.0 * std::numbers::pi;

void VanDerPol(double x, double y, double* dx, double* dy) {
  *dx = kMu * (x - x * x * x / 3.0 - y);
  *dy = x / kMu;
}

double NormalPdf(double x, double mean, double sd) {
  const double z = (x - mean) / sd;
  return std::exp(-0.5 * z * z) / (sd * std::sqrt(2.0 * std::numbers::pi));
}

double Cross(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

}  // namespace

VdpTag::VdpTag(Rollout rollout)
    : rollout_(rollout), heading_(MakeActionVec({0.0}), MakeActionVec({kTwoPi})) {
  heading_.SetPeriodic(0);
}

void VdpTag::NextMlTarget(double x, double y, double* nx, double* ny) {
  for (int i = 0; i < kSubsteps; ++i) {
    double k1x, k1y, k2x, k2y, k3x, k3y, k4x, k4y;
    VanDerPol(x, y, &k1x, &k1y);
    VanDerPol(x + 0.5 * kDt * k1x, y + 0.5 * kDt * k1y, &k2x, &k2y);
    VanDerPol(x + 0.5 * kDt * k2x, y + 0.5 * kDt * k2y, &k3x, &k3y);
    VanDerPol(x + kDt * k3x, y + kDt * k3y, &k4x, &k4y);
    x += kDt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
    y += kDt / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y);
  }
  *nx = x;
  *ny = y;
}

void VdpTag::BarrierStop(double x, double y, double dx, double dy, double* nx, double* ny) {
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  static constexpr double kDirs[4][2] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}};
  double shortest = 1.0 + 2.0 * kEps;
  for (const auto& dir : kDirs) {
    // Barrier segment p + t r, t in [0, 1]; motion q + u s, u in [0, 1].
    const double px = kBarrierStart * dir[0], py = kBarrierStart * dir[1];
    const double rx = kBarrierLength * dir[0], ry = kBarrierLength * dir[1];
    const double rxs = Cross(rx, ry, dx, dy);
    if (std::abs(rxs) < 1e-12) continue;
    const double qpx = x - px, qpy = y - py;
    const double u = Cross(qpx, qpy, rx, ry) / rxs;
    const double t = Cross(qpx, qpy, dx, dy) / rxs;
    if (u >= 0.0 && u < shortest && t >= 0.0 && t <= 1.0) shortest = u;
  }
  const double scale = shortest - 2.0 * kEps;
  *nx = x + scale * dx;
  *ny = y + scale * dy;
}

int VdpTag::ActiveBeam(double dx, double dy) {
  double theta = std::atan2(dy, dx);
  while (theta <= 0.0) theta += kTwoPi;  // (0, 2 pi]
  const int beam = static_cast<int>(std::ceil(8.0 * theta / kTwoPi)) - 1;
  return std::clamp(beam, 0, 7);
}

VdpTag::State VdpTag::SampleInitialState(Rng& rng) const {
  State s;
  s.tx = rng.Uniform(-4.0, 4.0);
  s.ty = rng.Uniform(-4.0, 4.0);
  return s;
}

StepResult<VdpTag::State, VdpTag::Observation> VdpTag::Step(const State& s, const Action& a,
                                                            Rng& rng) const {
  StepResult<State, Observation> r;
  State& n = r.state;
  n = s;
  if (s.tagged) {
    r.terminal = true;
    r.observation.fill(1.0);
    return r;
  }
  double tx, ty;
  NextMlTarget(s.tx, s.ty, &tx, &ty);
  n.tx = tx + kPosStd * rng.Normal();
  n.ty = ty + kPosStd * rng.Normal();
  const double heading = a.x.size() > 0 ? a.x[0] : 0.0;
  BarrierStop(s.ax, s.ay, kStepLength * std::cos(heading), kStepLength * std::sin(heading), &n.ax,
              &n.ay);
  const double rx = n.tx - n.ax, ry = n.ty - n.ay;
  const double dist = std::sqrt(rx * rx + ry * ry);
  const bool look = a.kind == kMoveAndLook;
  n.tagged = dist < kTagRadius;
  r.terminal = n.tagged;
  r.reward = (n.tagged ? 100.0 : -1.0) - (look ? kLookCost : 0.0);
  const int beam = ActiveBeam(rx, ry);
  for (int b = 0; b < 8; ++b) {
    r.observation[b] = (b == beam) ? dist + (look ? kActiveStd : kPassiveStd) * rng.Normal()
                                   : 1.0 + kPassiveStd * rng.Normal();
  }
  return r;
}

void VdpTag::ActionKinds(const State&, std::vector<int>* out) const {
  out->assign({kMove, kMoveAndLook});
}

double VdpTag::ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const {
  const double rx = sp.tx - sp.ax, ry = sp.ty - sp.ay;
  const double dist = std::sqrt(rx * rx + ry * ry);
  const int beam = ActiveBeam(rx, ry);
  const double active_sd = a.kind == kMoveAndLook ? kActiveStd : kPassiveStd;
  double p = 1.0;
  for (int b = 0; b < 8; ++b) {
    p *= (b == beam) ? NormalPdf(o[b], dist, active_sd) : NormalPdf(o[b], 1.0, kPassiveStd);
  }
  return p;
}

VdpTag::Action VdpTag::RolloutAction(const State& s, Rng& rng) const {
  Action a;
  if (rollout_ == Rollout::kToNextMl) {
    double tx, ty;
    NextMlTarget(s.tx, s.ty, &tx, &ty);
    a.kind = kMove;
    a.x = heading_.WrapPeriodic(MakeActionVec({std::atan2(ty - s.ay, tx - s.ax)}));
    return a;
  }
  a.kind = rng.Bernoulli(0.5) ? kMoveAndLook : kMove;
  a.x = heading_.SampleUniform(rng);
  return a;
}

VdpTag::Action VdpTag::BeliefRolloutAction(const ParticleBelief<State>& belief, Rng& rng) const {
  if (rollout_ != Rollout::kToNextMl || belief.empty() || !(belief.total_weight() > 0.0)) {
    return RolloutAction(belief.empty() ? State{} : belief.Sample(rng), rng);
  }
  const Eigen::Vector4d m =
      belief.Mean([](const State& s) { return Eigen::Vector4d(s.ax, s.ay, s.tx, s.ty); });
  State mean;
  mean.ax = m[0];
  mean.ay = m[1];
  mean.tx = m[2];
  mean.ty = m[3];
  return RolloutAction(mean, rng);
}

}  // namespace npfkct::models
