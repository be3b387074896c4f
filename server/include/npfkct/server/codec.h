// JSON encodings of the object-search types used by the API and by session snapshots.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "npfkct/object_search/world.h"
#include "npfkct/solver/spaces.h"
#include "npfkct/solver/status.h"

namespace npfkct::server {

using nlohmann::json;

/// {"x", "y", "yaw", "lift", "pan", "tilt"}.
json ConfigToJson(const object_search::RobotConfig& c);
/// {"center": [x, y, z], "yaw", "size": [x, y, z]}.
json BoxToJson(const object_search::Box& b);
/// Parses a box; errors name `path` (e.g. "detections[2].box").
Status BoxFromJson(const json& j, const std::string& path, object_search::Box* b);

/// "UPDATING", "DECLARED_OBSTACLE", "DECLARED_TARGET" or "REMOVED".
std::string StatusName(int8_t status);

/// The complete World, for snapshots (lossless for everything the planner reads).
json WorldToJson(const object_search::World& w);
/// Restores a World from WorldToJson's output.
StatusOr<object_search::World> WorldFromJson(const json& j);

/// The belief the API shows: robot, grid-world log-odds per workspace, objects with face odds.
json BeliefToJson(const object_search::World& w);

/// The API form of a hybrid action: {"type": "MOVE", "configuration": {...}} or
/// {"type": "DECLARE_TARGET" | "DECLARE_OBSTACLE" | "REMOVE", "objectId": "..."}.
json ActionToJson(const HybridAction& a, const object_search::World& w);
/// Parses an action in API form against the world's objects.
StatusOr<HybridAction> ActionFromJson(const json& j, const std::string& path,
                                      const object_search::World& w);

/// Parses the "robotState" and "detections" of an observation. `robot_state_required` is set
/// for MOVE actions (the robot must say where it ended).
StatusOr<object_search::RealObservation> ObservationFromJson(const json& body,
                                                             const object_search::World& w,
                                                             bool robot_state_required);

/// lowerCamelCase to snake_case per dot-separated segment ("search.maxDepth" ->
/// "search.max_depth").
std::string SnakeCase(const std::string& camel);

}  // namespace npfkct::server
