// The belief picture a person reads: a top view of what a session knows, cropped to the
// workspaces, with a title, a colour bar of the grid-world odds, a scale bar, labelled objects and
// their face odds, the robot with its camera frustum and the planned next view, and a legend.
// One renderer for the server's `GET .../belief?format=png` (the API layer encodes it) and the
// bench's `--render` frames (scenarios/src/frame_io.cc).
//
//   render::BeliefPictureOptions options;
//   options.title = "session 0123abcd - step 4";
//   options.next_view = planned_configuration;
//   cv::Mat bgr = render::RenderBelief(world, options);
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "npfkct/object_search/world.h"

namespace npfkct::render {

/// What a picture shows besides the world's own knowledge.
struct BeliefPictureOptions {
  /// First line of the title bar (e.g. "session 0123... - step 4").
  std::string title;
  /// Second line of the title bar (planner, model, target); empty: none.
  std::string subtitle;
  /// The planned next MOVE: drawn as a dashed robot with its frustum.
  std::optional<object_search::RobotConfig> next_view;
  /// A planned declare/remove, described for the legend (e.g. "REMOVE t3"); empty: none.
  std::string next_action;
  /// The episode is over (the target was removed): the summary says so instead of a guess.
  bool done = false;
  /// Largest picture, in pixels (the map's scale shrinks to stay within it).
  int64_t max_pixels = 4'000'000;
  /// Longest side of the map panel in pixels (before the max_pixels cap).
  int map_pixels = 900;
  /// Margin around the cropped content, in metres.
  double margin = 0.35;
};

/// The colour (BGR) of a probability in [0, 1] on the picture's colour map: pale blue-grey at 0
/// (looked at, empty), yellow, orange-red at 0.5 (not yet seen), dark red at 1. The web console
/// (server/console/console.js, COLOR_STOPS) uses the same stops.
cv::Vec3b ProbabilityColor(double p);

/// The colour map's stops: (probability, R, G, B).
struct ColorStop {
  double p;
  int r, g, b;
};
const std::vector<ColorStop>& ColorStops();

/// The floor area the camera frustum of `config` covers, seen from above: the convex hull of the
/// frustum's eight corners projected on the floor, counter-clockwise (x, y) points.
std::vector<object_search::Vec2> FrustumFootprint(const object_search::World& world,
                                                  const object_search::RobotConfig& config);

/// The rectangle [min, max] of the floor the picture shows: the workspaces, the known objects,
/// the robot (and the next view) with `margin`, within the room.
std::pair<object_search::Vec2, object_search::Vec2> CropBounds(
    const object_search::World& world, const std::optional<object_search::RobotConfig>& next_view,
    double margin);

/// The picture, 8-bit BGR.
cv::Mat RenderBelief(const object_search::World& world, const BeliefPictureOptions& options);

}  // namespace npfkct::render
