#include "npfkct/object_search/policies.h"

#include <bit>
#include <cmath>

#include "npfkct/object_search/proposals.h"

namespace npfkct::object_search {
namespace {

HybridAction OnObject(int object, int offset) {
  HybridAction a;
  a.kind = ObjectKind(object, offset);
  return a;
}

HybridAction MoveTo(const RobotConfig& c) {
  HybridAction a;
  a.kind = kMoveKind;
  a.x = ObjectSearchModel::VecOf(c);
  return a;
}

// Face grids (bit k: corner k) of object i that the camera at `view` updates in state s.
uint32_t FacesSeen(const ObjectSearchModel& model, const State& s, const RobotConfig& view, int i) {
  std::array<std::array<int, 4>, kMaxObjects> nearest{};
  if (!(model.VisibleObjects(s, view, &nearest) >> i & 1)) return 0;
  uint32_t mask = 0;
  for (int k : nearest[i]) mask |= 1u << k;
  return mask;
}

}  // namespace

const option_table::Table<NextBestViewOptions>& NextBestViewTable() {
  static const auto* table = new option_table::Table<NextBestViewOptions>{
      {"proposals", option_table::Int(&NextBestViewOptions::proposals)},
      {"particles", option_table::Int(&NextBestViewOptions::particles)},
  };
  return *table;
}

Status SetOption(NextBestViewOptions* o, std::string_view key, double value) {
  return option_table::Apply(NextBestViewTable(), o, key, value);
}

Status NextBestViewOptions::Validate() const {
  if (proposals < 1 || proposals > 100000) {
    return InvalidArgumentError("proposals must be in [1, 100000]");
  }
  if (particles < 1 || particles > 1000)
    return InvalidArgumentError("particles must be in [1, 1000]");
  return OkStatus();
}

NextBestView::NextBestView(const ObjectSearchModel& model, NextBestViewOptions options)
    : TreelessPlanner("nbv", model), options_(options) {}

OptionList NextBestView::OptionsUsed() const {
  return option_table::Values(NextBestViewTable(), options_);
}

template <class Score>
double NextBestView::BestView(const std::vector<RobotConfig>& views,
                              const TerminationCondition& stop, Score score,
                              RobotConfig* best) const {
  double best_score = -1.0;
  for (size_t v = 0; v < views.size(); ++v) {
    if (v % 64 == 63 && stop.ShouldStop(0)) break;  // the budget bounds the views scored
    const double value = score(views[v]);
    if (value > best_score) {
      best_score = value;
      *best = views[v];
    }
  }
  return best_score;
}

Decision<HybridAction> NextBestView::Plan(const TerminationCondition& stop, Rng& rng) {
  Decision<HybridAction> d;
  if (Status s = options_.Validate(); !s.ok()) {
    d.status = s;
    return d;
  }
  if (belief_.empty()) {
    d.status = FailedPreconditionError("belief is empty");
    return d;
  }
  const World& w = model_.world();
  const SearchParams& p = w.params;
  const int n = static_cast<int>(w.objects.size());
  // 1. Remove what was declared (unless the robot failed to); declare the target once its faces
  // confirm it.
  for (int i = 1; i < n; ++i) {
    const int8_t status = w.objects[i].status;
    if ((status == kDeclaredTarget || status == kDeclaredObstacle) &&
        !w.objects[i].removal_failed) {
      d.action = OnObject(i, kRemoveOffset);
      return FinishSearch(std::move(d), stop);
    }
  }
  for (int i = 1; i < n; ++i) {
    if (w.objects[i].status == kUpdating && model_.CountPast(w.objects[i].odds, true) >= p.n_odds) {
      d.action = OnObject(i, kDeclareTargetOffset);
      return FinishSearch(std::move(d), stop);
    }
  }
  // 2. The views, scored on particles of the belief.
  std::vector<State> particles;
  for (int k = 0; k < options_.particles; ++k) particles.push_back(belief_.Sample(rng));
  std::vector<RobotConfig> views;
  ProposeMoves(model_, ProposalOptions{}, options_.proposals, rng, &views, nullptr, &stop);
  if (views.empty()) views.push_back(w.robot_config);
  const int candidate = TargetCandidate(w);
  const double needed = std::max(
      1, p.n_odds - (candidate > 0 ? model_.CountPast(w.objects[candidate].odds, true) : 0));
  const uint32_t unconfirmed = candidate > 0 ? UnconfirmedFaces(w, candidate, +1) : 0;
  // The probability a view shows the guessed target, or the share of the faces still needed that
  // it confirms on the likeliest target.
  auto target_score = [&](const RobotConfig& view) {
    double sum = 0.0;
    for (const State& s : particles) {
      sum +=
          candidate == 0
              ? model_.SeesObject(s, view, 0)
              : std::min(1.0, std::popcount(FacesSeen(model_, s, view, candidate) & unconfirmed) /
                                  needed);
    }
    return sum / static_cast<double>(particles.size());
  };
  RobotConfig view = views[0];
  const double see = BestView(views, stop, target_score, &view);
  // 3. Clearing: the movable object with the most of the guessed target's mass inside it, worth
  // that mass after the views that confirm it as an obstacle, its declaration, its removal and a
  // look.
  int clear = -1;
  double clear_value = 0.0;
  for (int b = 1; b < n; ++b) {
    const ObjectKnowledge& o = w.objects[b];
    if (o.status != kUpdating || o.moveability < 0.5 || b == candidate) continue;
    const BoxFrame frame(o.box);
    int inside = 0;
    for (const State& s : particles) inside += frame.Contains(s.target);
    const int missing = std::max(0, p.n_odds - model_.CountPast(o.odds, false));
    const double steps = std::ceil(missing / 2.0) + 3.0;
    const double value =
        inside / static_cast<double>(particles.size()) * std::pow(p.discount, steps - 1.0);
    if (value > clear_value) {
      clear_value = value;
      clear = b;
    }
  }
  d.value = std::max(see, clear_value);
  if (clear < 0 || see >= clear_value) {
    d.action = MoveTo(view);
    return FinishSearch(std::move(d), stop);
  }
  if (model_.CountPast(w.objects[clear].odds, false) >= p.n_odds) {
    d.action = OnObject(clear, kDeclareObstacleOffset);
    return FinishSearch(std::move(d), stop);
  }
  const uint32_t obstacle_faces = UnconfirmedFaces(w, clear, -1);
  auto obstacle_score = [&](const RobotConfig& v) {
    double sum = 0.0;
    for (const State& s : particles) {
      sum += std::popcount(FacesSeen(model_, s, v, clear) & obstacle_faces);
    }
    return sum;
  };
  if (BestView(views, stop, obstacle_score, &view) <= 0.0) {
    (void)BestView(views, stop, target_score, &view);  // nothing shows it: look for the target
  }
  d.action = MoveTo(view);
  return FinishSearch(std::move(d), stop);
}

Decision<HybridAction> RolloutPolicy::Plan(const TerminationCondition& stop, Rng& rng) {
  Decision<HybridAction> d;
  if (belief_.empty()) {
    d.status = FailedPreconditionError("belief is empty");
    return d;
  }
  d.action = model_.RolloutAction(belief_.Sample(rng), rng);
  return FinishSearch(std::move(d), stop);
}

}  // namespace npfkct::object_search
