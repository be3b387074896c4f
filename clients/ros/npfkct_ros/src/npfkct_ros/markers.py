"""RViz markers of a session's belief (GET /v1/sessions/{id}/belief as JSON) and its next view.

Plain Python: the message classes come in as arguments (visualization_msgs' Marker and
MarkerArray, geometry_msgs' Point, std_msgs' ColorRGBA), so the same function serves ROS 1 and a
ROS 2 wrapper, whose messages have the same fields. Namespaces, each redrawn whole (a DELETEALL
first):

  belief_grid   CUBE_LIST: the grid-world cells where the target may be, red by their weight
                (cells under 5% of the heaviest are left out; at most max_cells cells)
  objects       CUBE per known object, red by the chance it is the target, grey otherwise
  labels        TEXT_VIEW_FACING: each object's id and that chance
  furniture     CUBE per piece of furniture
  view          LINE_STRIP: the floor the camera covers from the robot's configuration
  next_view     LINE_STRIP and ARROW: the planned next view (while a MOVE is pending)
"""

import math

from npfkct_ros.geometry import quat_from_rpy

NAMESPACES = ("belief_grid", "objects", "labels", "furniture", "view", "next_view")


def cell_weights(workspace):
    """(x, y, z, weight) of every cell of a grid workspace: weight = sigmoid(log-odds), the
    planner's sampling weight, at the cell's centre on the surface."""
    nx, ny = int(workspace["cellsX"]), int(workspace["cellsY"])
    cx, cy = workspace["center"]
    c, s = math.cos(workspace["yaw"]), math.sin(workspace["yaw"])
    dx, dy = workspace["length"] / nx, workspace["width"] / ny
    odds = workspace["logOdds"]
    for iy in range(ny):
        for ix in range(nx):
            lx = -0.5 * workspace["length"] + (ix + 0.5) * dx
            ly = -0.5 * workspace["width"] + (iy + 0.5) * dy
            yield (cx + c * lx - s * ly, cy + s * lx + c * ly, workspace["height"],
                   1.0 / (1.0 + math.exp(-odds[iy * nx + ix])))


def belief_markers(belief, frame, stamp, msgs, max_cells=20000):
    """A MarkerArray of `belief` in `frame` (the map frame of the session's coordinates).
    `msgs` has Marker, MarkerArray, Point and ColorRGBA."""
    Marker, Point, Color = msgs.Marker, msgs.Point, msgs.ColorRGBA
    out = msgs.MarkerArray()
    clear = Marker(action=Marker.DELETEALL)
    clear.header.frame_id, clear.header.stamp = frame, stamp
    out.markers.append(clear)

    def marker(ns, index, kind, color, scale=(1.0, 1.0, 1.0)):
        m = Marker(ns=ns, id=index, type=kind, action=Marker.ADD, color=Color(*color))
        m.header.frame_id, m.header.stamp = frame, stamp
        m.pose.orientation.w = 1.0
        m.scale.x, m.scale.y, m.scale.z = scale
        out.markers.append(m)
        return m

    def place(m, center, yaw):
        m.pose.position.x, m.pose.position.y, m.pose.position.z = center
        (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
         m.pose.orientation.w) = quat_from_rpy(0.0, 0.0, yaw)

    grid = belief.get("grid", {})
    cells = [cell for w in grid.get("workspaces", []) for cell in cell_weights(w)]
    heaviest = max((cell[3] for cell in cells), default=0.0)
    if heaviest > 0.0:
        shown = sorted((cell for cell in cells if cell[3] >= 0.05 * heaviest),
                       key=lambda cell: -cell[3])[:max_cells]
        size = float(grid.get("resolution", 0.02))
        m = marker("belief_grid", 0, Marker.CUBE_LIST, (1.0, 0.0, 0.0, 1.0),
                   (size, size, 0.004))
        for x, y, z, weight in shown:
            m.points.append(Point(x, y, z + 0.003))
            share = weight / heaviest
            m.colors.append(Color(1.0, 1.0 - share, 1.0 - share, 0.3 + 0.6 * share))

    for i, obj in enumerate(belief.get("objects", [])):
        box, p = obj["box"], float(obj.get("targetProbability", 0.0))
        m = marker("objects", i, Marker.CUBE, (0.5 + 0.5 * p, 0.5 - 0.4 * p, 0.5 - 0.4 * p, 0.6),
                   tuple(box["size"]))
        place(m, box["center"], box.get("yaw", 0.0))
        label = marker("labels", i, Marker.TEXT_VIEW_FACING, (1.0, 1.0, 1.0, 1.0),
                       (0.0, 0.0, 0.05))
        label.text = f"{obj['id']} {p:.0%}"
        top = list(box["center"])
        top[2] += 0.5 * box["size"][2] + 0.05
        place(label, top, 0.0)

    for i, piece in enumerate(belief.get("furniture", [])):
        m = marker("furniture", i, Marker.CUBE, (0.55, 0.4, 0.25, 0.35), tuple(piece["size"]))
        place(m, piece["center"], piece.get("yaw", 0.0))

    def outline(ns, polygon, color):
        m = marker(ns, 0, Marker.LINE_STRIP, color, (0.02, 0.0, 0.0))
        for x, y in list(polygon) + list(polygon[:1]):
            m.points.append(Point(x, y, 0.01))

    frustum = belief.get("camera", {}).get("frustum", [])
    if len(frustum) >= 3:
        outline("view", frustum, (0.2, 0.4, 1.0, 0.9))
    following = belief.get("nextView")
    if following and len(following.get("frustum", [])) >= 3:
        outline("next_view", following["frustum"], (0.1, 0.9, 0.2, 0.9))
        c = following["configuration"]
        arrow = marker("next_view", 1, Marker.ARROW, (0.1, 0.9, 0.2, 0.9), (0.4, 0.06, 0.06))
        place(arrow, (c["x"], c["y"], 0.05), c["yaw"])
    return out
