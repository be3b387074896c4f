#include "npfkct/api/limits.h"

#include "npfkct/object_search/world.h"

namespace npfkct::api {

static_assert(Limits{}.max_objects == object_search::kMaxKnownObjects,
              "a session knows at most the objects a world can hold");

const Limits& HardLimits() {
  static const Limits* hard = [] {
    auto* l = new Limits();
    // Budgets may be configured up to these; the defaults above are lower.
    l->max_plan_ms = 600'000;
    l->max_plan_simulations = 100'000'000;
    l->max_session_plan_seconds = 1e9;
    l->max_heap_mb = int64_t{1} << 30;
    return l;
  }();
  return *hard;
}

Status Limits::Validate() const {
  const Limits& hard = HardLimits();
  auto in = [](double v, double lo, double hi) { return v >= lo && v <= hi; };
  if (!in(max_plan_ms, 1.0, hard.max_plan_ms)) {
    return InvalidFieldError("max_plan_ms",
                             "must be in [1, " + std::to_string(int64_t(hard.max_plan_ms)) + "]");
  }
  if (!in(default_plan_ms, 1.0, max_plan_ms)) {
    return InvalidFieldError("default_plan_ms", "must be in [1, max_plan_ms]");
  }
  if (!in(static_cast<double>(max_plan_simulations), 1.0,
          static_cast<double>(hard.max_plan_simulations))) {
    return InvalidFieldError("max_plan_simulations", "must be in [1, 1e8]");
  }
  if (!in(max_session_plan_seconds, 1.0, hard.max_session_plan_seconds)) {
    return InvalidFieldError("max_session_plan_seconds", "must be >= 1");
  }
  if (!in(static_cast<double>(max_heap_mb), 64.0, static_cast<double>(hard.max_heap_mb))) {
    return InvalidFieldError("max_heap_mb", "must be >= 64");
  }
  if (!in(max_particles, 1, hard.max_particles)) {
    return InvalidFieldError("max_particles",
                             "must be in [1, " + std::to_string(hard.max_particles) + "]");
  }
  // The rest are fixed: the schemas document them.
  const bool fixed =
      max_coordinate == hard.max_coordinate && max_angle == hard.max_angle &&
      max_map_cells == hard.max_map_cells && max_furniture == hard.max_furniture &&
      max_grid_cells == hard.max_grid_cells && max_base_regions == hard.max_base_regions &&
      max_discrete_poses == hard.max_discrete_poses && max_objects == hard.max_objects &&
      max_planner_options == hard.max_planner_options && max_points == hard.max_points &&
      max_image_pixels == hard.max_image_pixels && max_image_side == hard.max_image_side &&
      max_photos == hard.max_photos && max_photo_pixels == hard.max_photo_pixels &&
      max_perception_map_points == hard.max_perception_map_points &&
      max_semantic_scores == hard.max_semantic_scores && max_image_boxes == hard.max_image_boxes &&
      max_display_name == hard.max_display_name && max_description == hard.max_description &&
      max_id_length == hard.max_id_length && max_json_depth == hard.max_json_depth &&
      max_json_values == hard.max_json_values;
  if (!fixed) {
    return InvalidArgumentError(
        "limits: only the budgets, max_heap_mb and max_particles can be configured; the others "
        "are the documented ones");
  }
  return OkStatus();
}

}  // namespace npfkct::api
