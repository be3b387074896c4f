#include "npfkct/object_search/discrete.h"

#include <algorithm>

namespace npfkct::object_search {

DiscreteObjectSearch::DiscreteObjectSearch(const ObjectSearchModel& model, DiscreteActionSet set)
    : model_(model), set_(set) {
  Refresh();
}

void DiscreteObjectSearch::Refresh() {
  poses_ = model_.world().ManualPoses();
  const int p = static_cast<int>(poses_.size());
  num_moves_ = set_ == DiscreteActionSet::kPrimitive ? p + 3 + 9 : p * 3 * 9;
}

RobotConfig DiscreteObjectSearch::MoveTarget(int a, const RobotConfig& from) const {
  const World& w = model_.world();
  const int p = static_cast<int>(poses_.size());
  const auto lifts = w.ManualLifts();
  const auto heads = w.ManualHeads();
  RobotConfig c = from;
  // The joints a primitive move keeps are the robot's as reported, within its limits: a move
  // never asks for a lift or head angle the robot cannot take.
  c.lift = std::clamp(c.lift, w.robot.lift_min, w.robot.lift_max);
  c.pan = std::clamp(c.pan, w.robot.pan_min, w.robot.pan_max);
  c.tilt = std::clamp(c.tilt, w.robot.tilt_min, w.robot.tilt_max);
  if (set_ == DiscreteActionSet::kJoint) {
    const RobotConfig& pose = poses_[a / 27];
    c.x = pose.x;
    c.y = pose.y;
    c.yaw = pose.yaw;
    c.lift = lifts[(a % 27) / 9];
    c.pan = heads[a % 9].first;
    c.tilt = heads[a % 9].second;
  } else if (a < p) {
    c.x = poses_[a].x;
    c.y = poses_[a].y;
    c.yaw = poses_[a].yaw;
  } else if (a < p + 3) {
    c.lift = lifts[a - p];
  } else {
    c.pan = heads[a - p - 3].first;
    c.tilt = heads[a - p - 3].second;
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
