// The object-search POMDP of the paper (section 3, appendix A and J) as a generative model over a
// World: hybrid actions MOVE(config) / DECLARE(i, target|obstacle) / REMOVE(i), a guessed target
// sampled from the grid world, face-grid observations inside the camera frustum with occlusion,
// and the paper's reward table.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "npfkct/object_search/world.h"
#include "npfkct/solver/model.h"
#include "npfkct/solver/spaces.h"

namespace npfkct::object_search {

/// The per-particle part of an object's state: face odds, status, and whether this particle
/// believes the robot can remove it. The box is shared (World::objects), except object 0's
/// position, which every particle samples.
struct ObjectParticle {
  std::array<float, 8> odds{};
  int8_t status = kUpdating;
  bool moveable = true;
  friend bool operator==(const ObjectParticle&, const ObjectParticle&) = default;
};

/// A state of the belief tree: the robot's configuration, the guessed target's position and the
/// dynamic part of every object (index 0: the guessed target).
struct State {
  RobotConfig robot;
  Vec3 target = Vec3::Zero();
  std::vector<ObjectParticle> objects;
  bool terminal = false;
  friend bool operator==(const State& a, const State& b) {
    return a.robot == b.robot && a.target == b.target && a.objects == b.objects &&
           a.terminal == b.terminal;
  }
};

/// An observation as the belief tree branches on it: which objects were seen, and for each the
/// direction of its face-grid update (positive, negative, or neither).
struct Observation {
  uint64_t visible = 0;
  uint64_t positive = 0;
  uint64_t negative = 0;
  friend bool operator==(const Observation&, const Observation&) = default;
  uint64_t Hash() const;
};

/// The 20-dimensional object state of the paper: position (3), quaternion (4), sizes (3),
/// face odds (8), moveability, status.
using ObjectVector20 = std::array<double, 20>;

/// Action kinds, the one place their layout is defined: kind 0 moves to a configuration (x, y,
/// yaw, lift, pan, tilt); kind 1 + 3i + offset acts on object i, offset kDeclareTargetOffset
/// declaring it the target, kDeclareObstacleOffset an obstacle, kRemoveOffset removing it.
inline constexpr int kMoveKind = 0;
inline int ObjectKind(int object, int offset) { return 1 + 3 * object + offset; }
inline int DeclareTargetKind(int object) { return ObjectKind(object, kDeclareTargetOffset); }
inline int DeclareObstacleKind(int object) { return ObjectKind(object, kDeclareObstacleOffset); }
inline int RemoveKind(int object) { return ObjectKind(object, kRemoveOffset); }
/// The object a discrete kind refers to, and its offset.
inline int KindObject(int kind) { return (kind - 1) / 3; }
inline int KindOffset(int kind) { return (kind - 1) % 3; }

/// Rollout policies of the object-search model.
enum class SearchRollout {
  kRandom,  ///< Uniformly random legal kind and configuration (paper's Rollout_Random).
  kGreedy,  ///< Take a legal declare/remove when the odds allow it, else a random move.
  /// As kGreedy, but half of the moves look at a placement of the target drawn from the grid
  /// world that the state could show (not inside a known object still standing there), so that
  /// a simulated removal is worth what the views beneath it find. The default.
  kAimed,
  /// As kAimed, but an obstacle is declared only when the particle's target stands inside it (a
  /// cover), a declared cover is removed, and while the target stands inside a known object the
  /// moves look at that object: the rollout clears what hides the target instead of collecting
  /// R_co for every obstacle it can declare.
  kClear,
};

/// What the planning model pays for a correct obstacle declaration (the simulator and the real
/// robot always pay the world's R_co).
enum class ObstacleReward {
  kEvery,  ///< R_co for every obstacle declared: the paper's reward.
  /// R_co only for an obstacle that hides the particle's guessed target (a cover, which must be
  /// declared to be removed); any other declaration costs a step like a move. A planner then
  /// clears what hides the target instead of collecting R_co for every box it has seen.
  kCovers,
};

/// The generative object-search model over a World (held by shared pointer; the owner may
/// replace the World between planning calls, never during one).
class ObjectSearchModel {
 public:
  using State = object_search::State;
  using Action = HybridAction;
  using Observation = object_search::Observation;

  explicit ObjectSearchModel(std::shared_ptr<const World> world,
                             SearchRollout rollout = SearchRollout::kAimed);

  /// Installs a new World (after a real step).
  void SetWorld(std::shared_ptr<const World> world);
  /// Sets what a simulated obstacle declaration pays (default kEvery).
  void SetObstacleReward(ObstacleReward r) { obstacle_reward_ = r; }
  const World& world() const { return *world_; }

  State SampleInitialState(Rng& rng) const;
  StepResult<State, Observation> Step(const State& s, const Action& a, Rng& rng) const;
  double Discount() const { return world_->params.discount; }
  bool IsTerminal(const State& s) const { return s.terminal; }
  void ActionKinds(const State& s, std::vector<int>* out) const;
  const BoxSpace& KindSpace(int kind) const { return kind == kMoveKind ? move_space_ : point_; }
  /// Reasonability check: the base must stand in a base region without collision; discrete
  /// actions must refer to an existing object whose status allows them.
  bool IsFeasible(const State& s, const Action& a) const;
  /// 1 when `o` is what `sp` produces after `a` (observations are deterministic given s').
  double ObservationLikelihood(const Action& a, const State& sp, const Observation& o) const;
  Action RolloutAction(const State& s, Rng& rng) const;
  /// The known object still standing that the particle's guessed target is inside, or -1.
  int CoverOf(const State& s) const;
  double MinReward() const { return world_->params.r_ill; }
  double MaxReward() const { return world_->params.r_max; }

  /// The box of object i in state s (object 0: the guessed target cube at s.target).
  Box ObjectBox(const State& s, int i) const;
  /// Which objects the camera sees from `config` in state s (bit i: object i), and for each the
  /// 4 face grids nearest to the camera.
  uint64_t VisibleObjects(const State& s, const RobotConfig& config,
                          std::array<std::array<int, 4>, kMaxObjects>* nearest) const;
  /// Whether the camera at `config` sees object i's center unoccluded in state s (object 0: the
  /// guessed target at s.target); the rule VisibleObjects applies to every object.
  bool SeesObject(const State& s, const RobotConfig& config, int i) const;
  /// The observation key of a real step, from the objects detected (their indices in the world)
  /// and the odds before the update, by the same rule as the simulated observations.
  Observation RealObservationKey(const std::vector<int>& detected) const;
  /// Decodes the continuous part of a move action.
  static RobotConfig ConfigOf(const ActionVec& x);
  /// Encodes a configuration as the continuous part of a move action.
  static ActionVec VecOf(const RobotConfig& c);
  /// The paper's 20-dimensional vector of object i in state s.
  ObjectVector20 ObjectVector(const State& s, int i) const;
  /// Number of face grids past +threshold (positive) or -threshold (negative).
  int CountPast(const std::array<float, 8>& odds, bool positive) const;

 private:
  void Observe(State* s, Rng& rng, Observation* o) const;
  /// Frames of the boxes of the objects of s (object 0's from s.target).
  void ObjectFrames(const State& s, std::array<BoxFrame, kMaxObjects>* frames) const;
  bool Sees(const CameraPose& pose, const State& s, const std::array<BoxFrame, kMaxObjects>& frames,
            int i) const;

  std::shared_ptr<const World> world_;
  std::vector<BoxFrame> furniture_frames_;  ///< Of world_->furniture, computed by SetWorld.
  std::vector<BoxFrame> object_frames_;     ///< Of world_->objects' boxes, likewise.
  double tan_half_horizontal_ = 0.0;        ///< Of world_->camera, likewise.
  SearchRollout rollout_;
  ObstacleReward obstacle_reward_ = ObstacleReward::kEvery;
  BoxSpace move_space_;
  BoxSpace point_;
};

}  // namespace npfkct::object_search
