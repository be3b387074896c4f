// The documented limits of the API: every resource a request can make the server use (cells,
// points, pixels, particles, candidates, budgets, sessions) is bounded here, and checked before
// anything of that size is allocated. docs/api.md ("Limits") lists each with its error; the JSON
// Schemas in schemas/ carry the same numbers (a unit test keeps them in step).
//
//   api::Limits limits;                // the defaults, as documented
//   limits.max_plan_ms = 10000;        // an operator may lower a limit ...
//   Status s = limits.Validate();      // ... but never raise it past the hard maximum
#pragma once

#include <cstdint>
#include <string>

#include "npfkct/common/status.h"

namespace npfkct::api {

/// Longest time to live of a session (ttlSeconds, the server's --session-ttl), in seconds: the
/// schema's maximum (a fleet's store adds it to its clock).
inline constexpr double kMaxTtlSeconds = 1e9;

/// Every limit the API layer enforces. Defaults are the documented values; `Validate()` rejects
/// settings beyond the hard maxima (the schemas' numbers).
struct Limits {
  // ---- geometry of the world spec ----
  /// Largest |coordinate| of any position, box center or region corner (m).
  double max_coordinate = 1e4;
  /// Largest |angle| (yaw, pan, tilt; rad) and |lift| (m) accepted anywhere.
  double max_angle = 1e3;
  /// Cells of the occupancy map: room area / mapResolution^2, computed in 64 bits.
  int64_t max_map_cells = 1'000'000;
  /// Pieces of furniture in a world.
  int max_furniture = 100;
  /// Cells of the target's grid world over every workspace (2 cm cells), computed in 64 bits.
  int64_t max_grid_cells = 250'000;
  /// Base regions and manual base poses.
  int max_base_regions = 64;
  int max_discrete_poses = 64;
  /// Objects a session can know (object_search::kMaxKnownObjects: the model's 64 less the
  /// guessed target); detections per observation.
  int max_objects = 63;

  // ---- planner ----
  /// Particles of the root belief (planner.particles, and search.numParticles).
  int max_particles = 10'000;
  /// Option overrides per planner.
  int max_planner_options = 64;

  // ---- budgets ----
  /// Wall-clock and CPU milliseconds one :plan may ask for (budget.timeMs, budget.cpuMs).
  double max_plan_ms = 60'000;
  /// Budget of a :plan that gives none.
  double default_plan_ms = 1'000;
  /// Simulations one :plan may ask for (budget.simulations).
  int64_t max_plan_simulations = 10'000'000;
  /// Planning a session may spend over its life (wall-clock seconds of every :plan together).
  double max_session_plan_seconds = 3'600;
  /// Heap (MiB) the server's allocations may reach while a plan searches: past it the plan
  /// stops with the best action found so far (a search tree grows by up to hundreds of MiB a
  /// second, and sessions keep theirs).
  int64_t max_heap_mb = 4'096;

  // ---- sensor data and photos ----
  /// Points of one raw point cloud.
  int64_t max_points = 1'000'000;
  /// Pixels of a camera image, and of each side (camera.width, camera.height).
  int64_t max_image_pixels = 4'194'304;
  int max_image_side = 4096;
  /// Target photos, and pixels of each (checked from the image header before decoding).
  int max_photos = 8;
  int64_t max_photo_pixels = 4'194'304;
  /// Points of the prior point-cloud map (floor and furniture surfaces) one frame can make
  /// perception build around the camera (it builds the map lazily, in tiles around the views:
  /// a house costs what the camera sees); a world denser than that cannot take raw sensor data.
  int64_t max_perception_map_points = 4'000'000;
  /// Scores of an external detector per observation.
  int max_semantic_scores = 256;
  /// Boxes of the robot's own detector per observation (imageBoxes).
  int max_image_boxes = 256;

  // ---- strings and requests ----
  int max_display_name = 200;
  int max_description = 2000;
  int max_id_length = 128;
  /// JSON nesting and values per request body (checked while parsing).
  int max_json_depth = 64;
  int64_t max_json_values = 100'000;

  /// Checks every limit against the hard maxima; the message names the offending one.
  Status Validate() const;
};

/// The hard maxima: what the schemas and docs/api.md document.
const Limits& HardLimits();

}  // namespace npfkct::api
