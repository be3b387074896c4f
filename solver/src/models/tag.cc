#include "npfkct/solver/models/tag.h"

#include <cmath>
#include <deque>
#include <utility>

namespace npfkct::models {
namespace {

constexpr int kWidth = 10;
constexpr int kHeight = 5;
// Pineau's floor: the room (rows 0-2, columns 5-7) above the corridor (rows 3-4).
constexpr const char* kFloor[kHeight] = {
    "#####...##", "#####...##", "#####...##", "..........", "..........",
};
// x and y steps of north, east, south, west.
constexpr int kDx[4] = {0, 1, 0, -1};
constexpr int kDy[4] = {-1, 0, 1, 0};

int Sign(int v) { return (v > 0) - (v < 0); }

}  // namespace

Tag::Tag() : index_(kWidth * kHeight, -1) {
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      if (kFloor[y][x] == '.') {
        index_[y * kWidth + x] = num_cells();
        cells_.emplace_back(x, y);
      }
    }
  }
  const int n = num_cells();
  neighbour_.resize(4 * n);
  for (int i = 0; i < n; ++i) {
    for (int d = 0; d < 4; ++d) {
      const int j = CellAt(x(i) + kDx[d], y(i) + kDy[d]);
      neighbour_[i * 4 + d] = j >= 0 ? j : i;
    }
  }
  // Breadth-first search from every cell.
  distance_.assign(n * n, -1);
  for (int from = 0; from < n; ++from) {
    std::deque<int> queue{from};
    distance_[from * n + from] = 0;
    while (!queue.empty()) {
      const int i = queue.front();
      queue.pop_front();
      for (int d = 0; d < 4; ++d) {
        const int j = Neighbour(i, d);
        if (distance_[from * n + j] < 0) {
          distance_[from * n + j] = distance_[from * n + i] + 1;
          queue.push_back(j);
        }
      }
    }
  }
}

int Tag::CellAt(int cx, int cy) const {
  if (cx < 0 || cx >= kWidth || cy < 0 || cy >= kHeight) return -1;
  return index_[cy * kWidth + cx];
}

Tag::State Tag::SampleInitialState(Rng& rng) const {
  State s;
  s.robot = static_cast<int8_t>(rng.UniformInt(num_cells()));
  s.opponent = static_cast<int8_t>(rng.UniformInt(num_cells()));
  return s;
}

int Tag::MoveOpponent(int robot, int opponent, Rng& rng) const {
  const double u = rng.Uniform();
  const int ox = x(opponent), oy = y(opponent);
  auto to = [&](int tx, int ty) {
    const int j = CellAt(tx, ty);
    return j >= 0 ? j : opponent;
  };
  if (u < 0.4) {  // along x: away from the robot, either way when their columns match
    const int dx = Sign(ox - x(robot));
    if (dx != 0) return to(ox + dx, oy);
    return to(u < 0.2 ? ox + 1 : ox - 1, oy);
  }
  if (u < 0.8) {  // along y, likewise
    const int dy = Sign(oy - y(robot));
    if (dy != 0) return to(ox, oy + dy);
    return to(ox, u < 0.6 ? oy + 1 : oy - 1);
  }
  return opponent;
}

StepResult<Tag::State, Tag::Observation> Tag::Step(const State& s, const Action& a,
                                                   Rng& rng) const {
  StepResult<State, Observation> r;
  r.state = s;
  if (s.tagged || (a == kTag && s.robot == s.opponent)) {
    r.reward = s.tagged ? 0.0 : kTagReward;
    r.state.tagged = true;
    r.terminal = true;
    r.observation = same_cell();
    return r;
  }
  r.state.opponent = static_cast<int8_t>(MoveOpponent(s.robot, s.opponent, rng));
  if (a == kTag) {
    r.reward = -kTagReward;
  } else {
    r.reward = -1.0;
    if (a >= 0 && a < 4) r.state.robot = static_cast<int8_t>(Neighbour(s.robot, a));
  }
  r.observation = r.state.robot == r.state.opponent ? same_cell() : r.state.robot;
  return r;
}

double Tag::ObservationLikelihood(const Action&, const State& sp, const Observation& o) const {
  const int expected = (sp.tagged || sp.robot == sp.opponent) ? same_cell() : sp.robot;
  return o == expected ? 1.0 : 0.0;
}

Tag::Action Tag::RolloutAction(const State& s, Rng& rng) const {
  if (s.robot == s.opponent) return kTag;
  int open[4];
  int count = 0;
  for (int d = 0; d < 4; ++d) {
    if (Neighbour(s.robot, d) != s.robot) open[count++] = d;
  }
  return count == 0 ? kTag : open[rng.UniformInt(count)];
}

void Tag::DefaultPolicyActions(const std::vector<State>& states, std::vector<Action>* out) const {
  // The two most common opponent cells among the scenarios not sharing the robot's cell.
  static_assert(kWidth * kHeight <= 64, "one counter per cell");
  int count[64] = {};
  for (const State& s : states) {
    if (s.robot != s.opponent) ++count[s.opponent];
  }
  int first = -1, second = -1;
  for (int i = 0; i < num_cells(); ++i) {
    if (first < 0 || count[i] > count[first]) {
      second = first;
      first = i;
    } else if (second < 0 || count[i] > count[second]) {
      second = i;
    }
  }
  out->resize(states.size());
  for (size_t k = 0; k < states.size(); ++k) {
    const State& s = states[k];
    if (s.robot == s.opponent) {
      (*out)[k] = kTag;
      continue;
    }
    const int goal = first != s.robot ? first : second;
    Action a = kTag;
    for (int d = 0; d < 4; ++d) {
      if (Distance(Neighbour(s.robot, d), goal) < Distance(s.robot, goal)) {
        a = d;
        break;
      }
    }
    (*out)[k] = a;
  }
}

double Tag::UpperBound(const State& s) const {
  if (s.tagged) return 0.0;
  const double gamma_d = std::pow(Discount(), Distance(s.robot, s.opponent));
  return -(1.0 - gamma_d) / (1.0 - Discount()) + kTagReward * gamma_d;
}

bool Tag::Reinvigorate(const State& near, const Action&, const Observation& o, Rng& rng,
                       State* out) const {
  if (near.tagged || o < 0 || o > same_cell()) return false;
  *out = near;
  if (o == same_cell()) {
    out->opponent = out->robot;
    return true;
  }
  out->robot = static_cast<int8_t>(o);
  if (out->opponent == out->robot) {
    // Another cell, uniformly.
    const int j = static_cast<int>(rng.UniformInt(num_cells() - 1));
    out->opponent = static_cast<int8_t>(j >= o ? j + 1 : j);
  }
  return true;
}

}  // namespace npfkct::models
