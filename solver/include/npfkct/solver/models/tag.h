// Tag (Pineau, Gordon & Thrun 2003), as DESPOT's papers and code evaluate it.
#pragma once

#include <cstdint>
#include <vector>

#include "npfkct/solver/model.h"

namespace npfkct::models {

/// Tag: a robot must tag an opponent on Pineau's 29-cell floor (a 10 x 2 corridor with a 3 x 3
/// room above its columns 5-7). Actions: move north, east, south or west (-1; a move into a wall
/// stays) or tag (+10 and the episode ends when robot and opponent share a cell, else -10). The
/// opponent moves away from the robot's cell before the robot moves: 0.4 a step away along x (0.2
/// each way when their columns match), 0.4 likewise along y, 0.2 stays; a step into a wall stays.
/// The robot observes its own cell after every step, or that it shares its cell with the opponent.
/// Robot and opponent start uniformly at random, the robot not told where; discount 0.95.
class Tag {
 public:
  struct State {
    int8_t robot = 0;     ///< Cell index of the robot.
    int8_t opponent = 0;  ///< Cell index of the opponent.
    bool tagged = false;
    friend bool operator==(const State&, const State&) = default;
  };
  /// 0 north, 1 east, 2 south, 3 west, 4 tag.
  using Action = int;
  /// The robot's cell, or same_cell() when it shares it with the opponent.
  using Observation = int;

  static constexpr int kNorth = 0;
  static constexpr int kEast = 1;
  static constexpr int kSouth = 2;
  static constexpr int kWest = 3;
  static constexpr int kTag = 4;
  static constexpr double kTagReward = 10.0;

  /// Pineau's floor.
  Tag();

  State SampleInitialState(Rng& rng) const;
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return 0.95; }
  bool IsTerminal(const State& s) const { return s.tagged; }
  int NumActions() const { return 5; }
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  /// Tag when robot and opponent share a cell (after the first step the observation says exactly
  /// that), else a uniformly random move that does not run into a wall: a policy of what the robot
  /// observes (the rollouts of POMCP and the like).
  Action RolloutAction(const State& s, Rng& rng) const;
  /// DESPOT's default policy of a node's scenarios (the authors' MODE-SP lower bound, in spirit):
  /// each scenario tags when its robot and opponent share a cell (what it observes), else steps
  /// along a shortest path towards the cell where most scenarios put the opponent (the next most
  /// common when that is the robot's own cell).
  void DefaultPolicyActions(const std::vector<State>& states, std::vector<Action>* out) const;
  /// DESPOT's shortest-path upper bound: the robot walks the shortest path to where the opponent
  /// is now and tags there, -(1 - gamma^d) / (1 - gamma) + 10 gamma^d (the authors' default, SP).
  double UpperBound(const State& s) const;
  /// A particle consistent with observation o, from `near` (a state after the step): the robot
  /// in the observed cell and `near`'s opponent (another cell drawn uniformly when that is the
  /// robot's), or both in `near`'s robot cell when o says the cells are shared.
  bool Reinvigorate(const State& near, const Action& a, const Observation& o, Rng& rng,
                    State* out) const;
  double MinReward() const { return -kTagReward; }
  double MaxReward() const { return kTagReward; }

  /// Cells of the floor (29).
  int num_cells() const { return static_cast<int>(cells_.size()); }
  /// The observation that robot and opponent share a cell.
  int same_cell() const { return num_cells(); }
  /// Column and row of cell i (rows grow southwards from the room's top row).
  int x(int i) const { return cells_[i].first; }
  int y(int i) const { return cells_[i].second; }
  /// The cell one step from cell i in direction d (0-3), or i at a wall.
  int Neighbour(int i, int d) const { return neighbour_[i * 4 + d]; }
  /// Moves on the shortest path between two cells.
  int Distance(int i, int j) const { return distance_[i * num_cells() + j]; }

 private:
  int CellAt(int x, int y) const;
  int MoveOpponent(int robot, int opponent, Rng& rng) const;

  std::vector<std::pair<int, int>> cells_;
  std::vector<int> index_;      // cell index per (y * kWidth + x), -1 at walls
  std::vector<int> neighbour_;  // 4 per cell
  std::vector<int> distance_;   // num_cells^2
};

}  // namespace npfkct::models
