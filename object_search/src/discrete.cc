#include "npfkct/object_search/discrete.h"

#include <algorithm>

namespace npfkct::object_search {

DiscreteObjectSearch::DiscreteObjectSearch(const ObjectSearchModel& model, DiscreteActionSet set)
    : model_(model), set_(set) {
  Refresh();
}

void DiscreteObjectSearch::Refresh() {
  const World& w = model_.world();
  poses_ = w.ManualPoses();
  lifts_ = w.ManualLifts();
  heads_ = w.ManualHeads();
  const int p = static_cast<int>(poses_.size()), l = static_cast<int>(lifts_.size());
  const int h = static_cast<int>(heads_.size());
  num_moves_ = set_ == DiscreteActionSet::kPrimitive ? p + l + h : p * l * h;
}

RobotConfig DiscreteObjectSearch::MoveTarget(int a, const RobotConfig& from) const {
  const World& w = model_.world();
  const int p = static_cast<int>(poses_.size()), l = static_cast<int>(lifts_.size());
  const int h = static_cast<int>(heads_.size());
  RobotConfig c = from;
  // The joints a primitive move keeps are the robot's as reported, within its limits: a move
  // never asks for a lift or head angle the robot cannot take.
  c.lift = std::clamp(c.lift, w.robot.lift_min, w.robot.lift_max);
  c.pan = std::clamp(c.pan, w.robot.pan_min, w.robot.pan_max);
  c.tilt = std::clamp(c.tilt, w.robot.tilt_min, w.robot.tilt_max);
  if (set_ == DiscreteActionSet::kJoint) {
    const RobotConfig& pose = poses_[a / (l * h)];
    c.x = pose.x;
    c.y = pose.y;
    c.yaw = pose.yaw;
    c.lift = lifts_[(a % (l * h)) / h];
    c.pan = heads_[a % h].first;
    c.tilt = heads_[a % h].second;
  } else if (a < p) {
    c.x = poses_[a].x;
    c.y = poses_[a].y;
    c.yaw = poses_[a].yaw;
  } else if (a < p + l) {
    c.lift = lifts_[a - p];
  } else {
    c.pan = heads_[a - p - l].first;
    c.tilt = heads_[a - p - l].second;
  }
  return c;
}

HybridAction DiscreteObjectSearch::ToHybrid(int a, const RobotConfig& from) const {
  HybridAction h;
  if (a < num_moves_) {
    h.kind = kMoveKind;
    h.x = ObjectSearchModel::VecOf(MoveTarget(a, from));
  } else {
    h.kind = a - num_moves_ + 1;
  }
  return h;
}

void DiscreteObjectSearch::LegalActions(const State& s, std::vector<int>* out) const {
  out->clear();
  for (int m = 0; m < num_moves_; ++m) out->push_back(m);
  thread_local std::vector<int> kinds;
  model_.ActionKinds(s, &kinds);
  for (int k : kinds) {
    if (k != kMoveKind) out->push_back(FromKind(k));
  }
}

}  // namespace npfkct::object_search
