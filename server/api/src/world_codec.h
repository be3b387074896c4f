// World specs and worlds as JSON (private to the API layer).
#pragma once

#include "json_util.h"
#include "npfkct/api/limits.h"
#include "npfkct/api/types.h"

namespace npfkct::api::internal {

/// A schema-checked "world" object as a WorldSpec, with the checks the schema cannot express
/// (room extent, cells counted in 64 bits, unique names, a workspace, ordered regions, params);
/// fields are named under `path`.
StatusOr<WorldSpec> ReadWorldSpec(const json& j, const std::string& path, const Limits& limits);

/// A WorldSpec as ReadWorldSpec reads it (the create request's "world"): every field, the
/// discrete poses' x, y and yaw, and the params that differ from SearchParams' defaults (those
/// the schema has: base clearance, the grid bounds and the like are the server's own).
json WorldSpecJson(const WorldSpec& spec);

/// A robot description as the API writes it: its name, footprint, reach and joints.
json RobotDescriptionJson(const object_search::RobotDescription& r);
/// A robot as a world spec gives it: a shipped robot unchanged as its name, any other as
/// RobotDescriptionJson (a URDF's robot as the joints it became).
json RobotJson(const object_search::RobotDescription& r);

/// The complete World, for snapshots (lossless for everything the planner reads).
json WorldJson(const World& w);
/// A World from WorldJson's output; every size is checked against `limits` before allocation.
/// Errors are DATA_LOSS.
StatusOr<World> WorldFromJson(const json& j, const Limits& limits);

/// The belief the API shows; with `session`, its planned next view.
json BeliefJson(const World& w, const SessionView* session);

/// The floor the camera covers from configuration `c` (the PNG's frustum), as [[x, y], ...].
json FrustumJson(const World& w, const object_search::RobotConfig& c);

/// Cells of the grid world over `workspaces` at `resolution`, as GridWorld counts them, in 64
/// bits (and saturating), so that a limit can be checked before the grid is built.
int64_t GridCells(const std::vector<object_search::Workspace>& workspaces, double resolution);
/// Cells of an occupancy map of [lo, hi] at `resolution`, as OccupancyMap counts them
/// (saturating).
int64_t MapCells(const object_search::Vec2& lo, const object_search::Vec2& hi, double resolution);

}  // namespace npfkct::api::internal
