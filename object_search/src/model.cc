#include "npfkct/object_search/model.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "npfkct/object_search/proposals.h"

namespace npfkct::object_search {

uint64_t Observation::Hash() const {
  return HashMix(visible ^ HashMix(positive + 0x9e3779b97f4a7c15ULL) ^ HashMix(negative << 1));
}

ObjectSearchModel::ObjectSearchModel(std::shared_ptr<const World> world, SearchRollout rollout)
    : rollout_(rollout) {
  SetWorld(std::move(world));
}

void ObjectSearchModel::SetWorld(std::shared_ptr<const World> world) {
  world_ = std::move(world);
  const World& w = *world_;
  tan_half_horizontal_ = w.camera.TanHalfHorizontal();
  furniture_frames_.clear();
  for (const Box& f : w.furniture) furniture_frames_.emplace_back(f);
  object_frames_.clear();
  for (const auto& object : w.objects) object_frames_.emplace_back(object.box);
  Vec2 lo = Vec2::Constant(1e9), hi = Vec2::Constant(-1e9);
  for (const BaseRegion& r : w.base_regions) {
    lo = lo.cwiseMin(r.min);
    hi = hi.cwiseMax(r.max);
  }
  if (w.base_regions.empty()) lo = hi = Vec2::Zero();
  move_space_ = BoxSpace(MakeActionVec({lo.x(), lo.y(), -std::numbers::pi, w.robot.lift_min,
                                        w.robot.pan_min, w.robot.tilt_min}),
                         MakeActionVec({hi.x(), hi.y(), std::numbers::pi, w.robot.lift_max,
                                        w.robot.pan_max, w.robot.tilt_max}));
  move_space_.SetPeriodic(2);
}

RobotConfig ObjectSearchModel::ConfigOf(const ActionVec& x) {
  RobotConfig c;
  c.x = x[0];
  c.y = x[1];
  c.yaw = WrapAngle(x[2]);
  c.lift = x[3];
  c.pan = x[4];
  c.tilt = x[5];
  return c;
}

ActionVec ObjectSearchModel::VecOf(const RobotConfig& c) {
  return MakeActionVec({c.x, c.y, c.yaw, c.lift, c.pan, c.tilt});
}

State ObjectSearchModel::SampleInitialState(Rng& rng) const {
  const World& w = *world_;
  State s;
  s.robot = w.robot_config;
  s.target = w.grid.Sample(rng, 0.5 * w.params.guess_size);
  s.objects.resize(w.objects.size());
  for (size_t i = 0; i < w.objects.size(); ++i) {
    const ObjectKnowledge& k = w.objects[i];
    ObjectParticle& p = s.objects[i];
    p.odds = k.odds;
    p.status = k.status;
    p.moveable = rng.Bernoulli(k.moveability);
  }
  // The guessed target's faces are re-initialised after every real step (appendix A).
  s.objects[0].odds.fill(static_cast<float>(w.params.guess_odds));
  s.objects[0].status = kUpdating;
  return s;
}

Box ObjectSearchModel::ObjectBox(const State& s, int i) const {
  if (i == 0) {
    Box b;
    b.center = s.target;
    b.size = Vec3::Constant(world_->params.guess_size);
    return b;
  }
  return world_->objects[i].box;
}

int ObjectSearchModel::CountPast(const std::array<float, 8>& odds, bool positive) const {
  const double t = world_->params.declare_threshold;
  int n = 0;
  for (float v : odds) n += positive ? (v > t) : (v < -t);
  return n;
}

void ObjectSearchModel::ObjectFrames(const State& s,
                                     std::array<BoxFrame, kMaxObjects>* frames) const {
  const int n = static_cast<int>(s.objects.size());
  for (int i = 0; i < n; ++i) {
    (*frames)[i] = i == 0 ? BoxFrame(ObjectBox(s, 0)) : object_frames_[i];
  }
}

bool ObjectSearchModel::Sees(const CameraPose& pose, const State& s,
                             const std::array<BoxFrame, kMaxObjects>& frames, int i) const {
  const World& w = *world_;
  const int n = static_cast<int>(s.objects.size());
  if (s.objects[i].status == kRemoved) return false;
  const Vec3& c = frames[i].center;
  if (!InFrustum(w.camera, pose, c, tan_half_horizontal_)) return false;
  // The sight line, tested against every occluder as Box::BlocksSegment would.
  constexpr double kClearance = 1e-6;
  const Vec3 sight = c - pose.position;
  const double length = sight.norm();
  const bool blockable = length > 2 * kClearance;
  const Vec3 unit = sight / length;
  for (const BoxFrame& f : furniture_frames_) {
    if (blockable && f.BlocksUnitSegment(pose.position, unit, length, kClearance)) return false;
  }
  const double volume = frames[i].half.prod();
  for (int j = 0; j < n; ++j) {
    if (j == i || s.objects[j].status == kRemoved) continue;
    // A smaller object nested inside object i (a covered target) does not hide it.
    if (frames[j].half.prod() < volume && frames[i].Contains(frames[j].center)) continue;
    // The guessed target hides inside or under a real object it overlaps (covered target).
    if (frames[j].Contains(c)) return false;
    if (blockable && frames[j].BlocksUnitSegment(pose.position, unit, length, kClearance)) {
      return false;
    }
  }
  return true;
}

bool ObjectSearchModel::SeesObject(const State& s, const RobotConfig& config, int i) const {
  const int n = static_cast<int>(s.objects.size());
  if (i < 0 || i >= n) return false;
  std::array<BoxFrame, kMaxObjects> frames;
  ObjectFrames(s, &frames);
  return Sees(CameraPoseFor(world_->robot, config), s, frames, i);
}

uint64_t ObjectSearchModel::VisibleObjects(
    const State& s, const RobotConfig& config,
    std::array<std::array<int, 4>, kMaxObjects>* nearest) const {
  const CameraPose pose = CameraPoseFor(world_->robot, config);
  const int n = static_cast<int>(s.objects.size());
  std::array<BoxFrame, kMaxObjects> frames;
  ObjectFrames(s, &frames);
  uint64_t visible = 0;
  for (int i = 0; i < n; ++i) {
    if (!Sees(pose, s, frames, i)) continue;
    visible |= (uint64_t{1} << i);
    if (nearest != nullptr) {
      (*nearest)[i] = NearestCorners(frames[i].Corners(), pose.position);
    }
  }
  return visible;
}

void ObjectSearchModel::Observe(State* s, Rng& rng, Observation* o) const {
  const SearchParams& p = world_->params;
  std::array<std::array<int, 4>, kMaxObjects> nearest;
  o->visible = VisibleObjects(*s, s->robot, &nearest);
  o->positive = o->negative = 0;
  const float limit = static_cast<float>(p.face_odds_limit);
  for (int i = 0; i < static_cast<int>(s->objects.size()); ++i) {
    if (!(o->visible >> i & 1u)) continue;
    ObjectParticle& obj = s->objects[i];
    double mean = 0.0;
    for (float v : obj.odds) mean += v;
    mean /= 8.0;
    double base = 0.0;
    if (mean > p.nu_p) {
      base = p.c_o;
      o->positive |= uint64_t{1} << i;
    } else if (mean < p.nu_n) {
      base = -p.c_o;
      o->negative |= uint64_t{1} << i;
    }
    for (int k : nearest[i]) {
      const double eta = p.eta_std > 0 ? p.eta_std * rng.Normal() : 0.0;
      obj.odds[k] = std::clamp(static_cast<float>(obj.odds[k] + base + eta), -limit, limit);
    }
  }
}

StepResult<State, Observation> ObjectSearchModel::Step(const State& s, const Action& a,
                                                       Rng& rng) const {
  const SearchParams& p = world_->params;
  StepResult<State, Observation> r;
  r.state = s;
  if (s.terminal) {
    r.terminal = true;
    return r;
  }
  State& n = r.state;
  ActionOutcome outcome = ActionOutcome::kIllegal;
  if (a.kind == kMoveKind) {
    const RobotConfig c = a.x.size() == 6 ? ConfigOf(a.x) : s.robot;
    if (a.x.size() == 6 && world_->BaseFeasible(c.x, c.y, c.yaw)) {
      n.robot = c;
      outcome = ActionOutcome::kMoved;
    }
  } else {
    const int i = KindObject(a.kind);
    if (a.kind >= 1 && i < static_cast<int>(s.objects.size())) {
      ObjectParticle& obj = n.objects[i];
      const int offset = KindOffset(a.kind);
      bool legal = false;
      switch (offset) {
        case kDeclareTargetOffset:
          legal = obj.status == kUpdating && CountPast(obj.odds, true) >= p.n_odds;
          break;
        case kDeclareObstacleOffset:
          legal = obj.status == kUpdating && CountPast(obj.odds, false) >= p.n_odds;
          break;
        default:
          legal =
              (obj.status == kDeclaredTarget || obj.status == kDeclaredObstacle) && obj.moveable;
          break;
      }
      if (legal) {
        outcome = SuccessfulOutcome(offset, obj.status);
        obj.status = StatusAfter(offset);
        n.terminal = outcome == ActionOutcome::kRemovedTarget;
      }
    }
  }
  r.reward = RewardOf(p, outcome);
  if (outcome == ActionOutcome::kDeclaredObstacle && obstacle_reward_ == ObstacleReward::kCovers &&
      !object_frames_[KindObject(a.kind)].Contains(s.target)) {
    r.reward = p.r_min;
  }
  r.terminal = n.terminal;
  if (!n.terminal) Observe(&n, rng, &r.observation);
  return r;
}

void ObjectSearchModel::ActionKinds(const State& s, std::vector<int>* out) const {
  const SearchParams& p = world_->params;
  out->clear();
  out->push_back(kMoveKind);
  for (int i = 0; i < static_cast<int>(s.objects.size()); ++i) {
    const ObjectParticle& o = s.objects[i];
    if (o.status == kUpdating) {
      if (CountPast(o.odds, true) >= p.n_odds) out->push_back(DeclareTargetKind(i));
      if (CountPast(o.odds, false) >= p.n_odds) out->push_back(DeclareObstacleKind(i));
    } else if (o.status == kDeclaredTarget || o.status == kDeclaredObstacle) {
      out->push_back(RemoveKind(i));
    }
  }
}

bool ObjectSearchModel::IsFeasible(const State& s, const Action& a) const {
  if (a.kind == kMoveKind) {
    if (a.x.size() != 6 || !a.x.allFinite()) return false;
    const RobotConfig c = ConfigOf(a.x);
    const RobotDescription& r = world_->robot;
    if (c.lift < r.lift_min || c.lift > r.lift_max || c.pan < r.pan_min || c.pan > r.pan_max ||
        c.tilt < r.tilt_min || c.tilt > r.tilt_max) {
      return false;
    }
    return world_->BaseFeasible(c.x, c.y, c.yaw);
  }
  if (a.kind < 1 || a.x.size() != 0) return false;
  const int i = KindObject(a.kind);
  if (i < 1 || i >= static_cast<int>(s.objects.size())) return false;  // not the guessed target
  const int8_t status = s.objects[i].status;
  return KindOffset(a.kind) == kRemoveOffset
             ? (status == kDeclaredTarget || status == kDeclaredObstacle)
             : status == kUpdating;
}

double ObjectSearchModel::ObservationLikelihood(const Action& a, const State& sp,
                                                const Observation& o) const {
  (void)a;
  std::array<std::array<int, 4>, kMaxObjects> unused;
  if (sp.terminal) return o == Observation{} ? 1.0 : 0.0;
  if (VisibleObjects(sp, sp.robot, &unused) != o.visible) return 0.0;
  // The update direction is a function of the odds before the update, which s' no longer holds
  // exactly; accept the recorded direction when it agrees with the odds' sign.
  for (int i = 0; i < static_cast<int>(sp.objects.size()); ++i) {
    if (!(o.visible >> i & 1u)) continue;
    double mean = 0.0;
    for (float v : sp.objects[i].odds) mean += v;
    mean /= 8.0;
    const bool pos = o.positive >> i & 1u, neg = o.negative >> i & 1u;
    if ((pos && mean < world_->params.nu_n) || (neg && mean > world_->params.nu_p)) return 0.0;
  }
  return 1.0;
}

int ObjectSearchModel::CoverOf(const State& s) const {
  for (int j = 1; j < static_cast<int>(s.objects.size()); ++j) {
    if (s.objects[j].status != kRemoved && object_frames_[j].Contains(s.target)) return j;
  }
  return -1;
}

namespace {

// The first discrete kind of `kinds` with the highest rank(object, offset) above 0, or kMoveKind
// when none ranks above 0.
template <class Rank>
int HighestRanked(const std::vector<int>& kinds, Rank rank) {
  int best = kMoveKind, best_rank = 0;
  for (int k : kinds) {
    if (k == kMoveKind) continue;
    const int r = rank(KindObject(k), KindOffset(k));
    if (r > best_rank) {
      best_rank = r;
      best = k;
    }
  }
  return best;
}

}  // namespace

HybridAction ObjectSearchModel::RolloutAction(const State& s, Rng& rng) const {
  thread_local std::vector<int> kinds;
  ActionKinds(s, &kinds);
  HybridAction a;
  if (rollout_ == SearchRollout::kClear) {
    // Remove the declared target, declare the target, remove or declare the cover; nothing else
    // is declared.
    const int cover = CoverOf(s);
    a.kind = HighestRanked(kinds, [&](int i, int offset) {
      if (offset == kRemoveOffset && s.objects[i].status == kDeclaredTarget) return 4;
      if (offset == kDeclareTargetOffset) return 3;
      if (i == cover && offset == kRemoveOffset) return 2;
      if (i == cover && offset == kDeclareObstacleOffset) return 1;
      return 0;
    });
    if (a.kind != kMoveKind) return a;
    RobotConfig c;
    if (cover >= 0 && AimAt(*world_, world_->objects[cover].box.center, rng, &c)) {
      a.x = VecOf(c);
      return a;
    }
  } else if (rollout_ != SearchRollout::kRandom) {
    a.kind = HighestRanked(kinds, [&](int i, int offset) {
      if (offset == kRemoveOffset && s.objects[i].status == kDeclaredTarget) return 3;
      if (offset == kDeclareTargetOffset) return 2;
      if (offset == kDeclareObstacleOffset) return 1;
      return 0;
    });
    if (a.kind != kMoveKind) return a;
  } else {
    a.kind = kinds[rng.UniformInt(static_cast<int64_t>(kinds.size()))];
  }
  if (a.kind != kMoveKind) return a;
  if ((rollout_ == SearchRollout::kAimed || rollout_ == SearchRollout::kClear) &&
      rng.Uniform() < 0.5) {
    // A placement the belief allows, drawn again (up to 4 times) while inside a known object
    // that still stands; a camera aimed at it (else the random configuration below).
    const int n = static_cast<int>(s.objects.size());
    for (int tries = 0; tries < 4; ++tries) {
      const Vec3 p = world_->grid.Sample(rng, 0.5 * world_->params.guess_size);
      bool hidden = false;
      for (int j = 1; j < n && !hidden; ++j) {
        hidden = s.objects[j].status != kRemoved && object_frames_[j].Contains(p);
      }
      if (hidden) continue;
      RobotConfig c;
      if (AimAt(*world_, p, rng, &c)) {
        a.x = VecOf(c);
        return a;
      }
      break;
    }
  }
  // A random configuration whose base is feasible (a few tries, else stay).
  for (int tries = 0; tries < 8; ++tries) {
    a.x = move_space_.SampleUniform(rng);
    const RobotConfig c = ConfigOf(a.x);
    if (world_->BaseFeasible(c.x, c.y, c.yaw)) return a;
  }
  a.x = VecOf(s.robot);
  return a;
}

Observation ObjectSearchModel::RealObservationKey(const std::vector<int>& detected) const {
  Observation o;
  const SearchParams& p = world_->params;
  for (int i : detected) {
    if (i < 1 || i >= static_cast<int>(world_->objects.size()) || i >= kMaxObjects) continue;
    o.visible |= uint64_t{1} << i;
    double mean = 0.0;
    for (float v : world_->objects[i].odds) mean += v;
    mean /= 8.0;
    if (mean > p.nu_p) o.positive |= uint64_t{1} << i;
    if (mean < p.nu_n) o.negative |= uint64_t{1} << i;
  }
  return o;
}

ObjectVector20 ObjectSearchModel::ObjectVector(const State& s, int i) const {
  const Box b = ObjectBox(s, i);
  ObjectVector20 v{};
  v[0] = b.center.x();
  v[1] = b.center.y();
  v[2] = b.center.z();
  // Quaternion (x, y, z, w) of the yaw.
  v[3] = 0.0;
  v[4] = 0.0;
  v[5] = std::sin(0.5 * b.yaw);
  v[6] = std::cos(0.5 * b.yaw);
  v[7] = b.size.x();
  v[8] = b.size.y();
  v[9] = b.size.z();
  for (int k = 0; k < 8; ++k) v[10 + k] = s.objects[i].odds[k];
  v[18] = world_->objects[i].moveability;
  v[19] = s.objects[i].status;
  return v;
}

}  // namespace npfkct::object_search
