"""SLAM maps for a session's world: ROS map_server's YAML + PGM pair as the occupancyGrid the
server takes (the fields of nav_msgs/OccupancyGrid), and the workspaces' heights from the
point-cloud map (a PCD file)."""

import base64
import os
from typing import Any, Dict, List, Tuple


def _read_pgm(data: bytes) -> Tuple[int, int, int, List[int]]:
    """Width, height, maxval and the pixels (top row first) of a binary (P5) or plain (P2) PGM."""
    tokens: List[bytes] = []
    i = 0
    magic = data[:2]
    if magic not in (b"P5", b"P2"):
        raise ValueError("not a PGM image (P5 or P2)")
    i = 2
    while len(tokens) < 3:  # width, height, maxval; comments start with '#'
        while i < len(data) and data[i:i + 1].isspace():
            i += 1
        if data[i:i + 1] == b"#":
            while i < len(data) and data[i:i + 1] != b"\n":
                i += 1
            continue
        start = i
        while i < len(data) and not data[i:i + 1].isspace():
            i += 1
        if start == i:
            raise ValueError("truncated PGM header")
        tokens.append(data[start:i])
    width, height, maxval = (int(t) for t in tokens)
    if width < 1 or height < 1 or not 1 <= maxval <= 65535:
        raise ValueError("bad PGM size or maxval")
    count = width * height
    if magic == b"P2":
        pixels = [int(t) for t in data[i:].split()[:count]]
    else:
        i += 1  # the single whitespace after maxval
        step = 1 if maxval < 256 else 2
        raw = data[i:i + count * step]
        pixels = list(raw) if step == 1 else [raw[k] << 8 | raw[k + 1] for k in range(0, len(raw), 2)]
    if len(pixels) != count:
        raise ValueError(f"PGM has {len(pixels)} pixels, {width} x {height} expected")
    return width, height, maxval, pixels


def occupancy_grid_from_map_files(yaml_path: str) -> Dict[str, Any]:
    """The world's "occupancyGrid" from map_server's YAML (image, resolution, origin, negate,
    occupied_thresh, free_thresh; mode trinary) and the PGM it names: a cell occupied (100)
    above occupied_thresh, free (0) below free_thresh, unknown (-1) between; rows flipped so
    that row 0 is the lowest y, as nav_msgs/OccupancyGrid has them. Needs PyYAML."""
    import yaml  # PyYAML (Debian: python3-yaml)

    with open(yaml_path, encoding="utf-8") as f:
        meta = yaml.safe_load(f)
    image = meta["image"]
    if not os.path.isabs(image):
        image = os.path.join(os.path.dirname(os.path.abspath(yaml_path)), image)
    with open(image, "rb") as f:
        width, height, maxval, pixels = _read_pgm(f.read())
    negate = bool(meta.get("negate", 0))
    occupied, free = float(meta.get("occupied_thresh", 0.65)), float(meta.get("free_thresh", 0.196))
    cells = bytearray(width * height)
    for row in range(height):
        top = height - 1 - row  # the PGM's first row is the map's highest y
        for col in range(width):
            v = pixels[top * width + col]
            p = v / maxval if negate else (maxval - v) / maxval
            cells[row * width + col] = 100 if p > occupied else 0 if p < free else 0xFF  # -1
    origin = [float(v) for v in meta.get("origin", [0.0, 0.0, 0.0])]
    return {"resolution": float(meta["resolution"]), "origin": origin, "width": width,
            "height": height, "data": base64.b64encode(bytes(cells)).decode()}


def write_map_files(world: Dict[str, Any], directory: str, name: str = "map",
                    resolution: float = 0.05) -> str:
    """Rasterises a hand-written world (room and furniture, as a scenario file has them) into
    map_server's pair, as a SLAM map of that room would look: walls one cell thick on the
    room's border and each piece of furniture's footprint occupied (0), the floor free (254).
    Writes NAME.pgm and NAME.yaml into `directory` and returns the YAML's path."""
    import math

    lo = world.get("room", {}).get("min", [-3.0, -3.0])
    hi = world.get("room", {}).get("max", [3.0, 3.0])
    width = max(1, round((hi[0] - lo[0]) / resolution))
    height = max(1, round((hi[1] - lo[1]) / resolution))
    pixels = bytearray([254]) * (width * height)
    footprints = []
    for f in world.get("furniture", []):
        yaw = f.get("yaw", 0.0)
        footprints.append((f["center"], f["size"], math.cos(yaw), math.sin(yaw)))
    for row in range(height):  # row 0: the lowest y, written last
        y = lo[1] + (row + 0.5) * resolution
        for col in range(width):
            x = lo[0] + (col + 0.5) * resolution
            occupied = row in (0, height - 1) or col in (0, width - 1)
            for (cx, cy), size, c, s in footprints:
                u, v = c * (x - cx) + s * (y - cy), -s * (x - cx) + c * (y - cy)
                occupied = occupied or (abs(u) <= 0.5 * size[0] and abs(v) <= 0.5 * size[1])
            if occupied:
                pixels[(height - 1 - row) * width + col] = 0
    with open(os.path.join(directory, name + ".pgm"), "wb") as f:
        f.write(b"P5\n%d %d\n255\n" % (width, height) + bytes(pixels))
    path = os.path.join(directory, name + ".yaml")
    with open(path, "w", encoding="utf-8") as f:
        f.write(f"image: {name}.pgm\nresolution: {resolution}\n"
                f"origin: [{float(lo[0])}, {float(lo[1])}, 0.0]\n"
                "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return path


def traced_workspaces(world: Dict[str, Any]) -> List[Dict[str, Any]]:
    """The workspace furniture of a hand-written world as traced polygons with their heights
    (each footprint's four corners), as the world's "workspaces" takes them."""
    import math

    out = []
    for f in world.get("furniture", []):
        if not f.get("workspace"):
            continue
        (cx, cy), (sx, sy, sz) = f["center"], f["size"]
        c, s = math.cos(f.get("yaw", 0.0)), math.sin(f.get("yaw", 0.0))
        corners = [(-0.5 * sx, -0.5 * sy), (0.5 * sx, -0.5 * sy), (0.5 * sx, 0.5 * sy),
                   (-0.5 * sx, 0.5 * sy)]
        out.append({"name": f["name"], "height": sz,
                    "polygon": [[cx + c * u - s * v, cy + s * u + c * v] for u, v in corners]})
    return out


def slam_world(world: Dict[str, Any], yaml_path: str) -> Dict[str, Any]:
    """A hand-written world in the SLAM form: its robot, start and parameters, the occupancy grid
    of the map files at `yaml_path` (write_map_files makes them from the world) and its
    workspaces traced (traced_workspaces), no base regions (the server places them)."""
    out = {key: world[key] for key in ("robot", "start", "params") if key in world}
    out["occupancyGrid"] = occupancy_grid_from_map_files(yaml_path)
    out["workspaces"] = traced_workspaces(world)
    return out


# The PCD field types read_pcd decodes (struct codes by TYPE and SIZE).
_PCD_TYPES = {("F", 4): "f", ("F", 8): "d", ("I", 1): "b", ("I", 2): "h", ("I", 4): "i",
              ("I", 8): "q", ("U", 1): "B", ("U", 2): "H", ("U", 4): "I", ("U", 8): "Q"}


def read_pcd(path: str, max_points: int = 20_000_000) -> List[Tuple[float, float, float]]:
    """The x, y, z of every finite point of a PCD file (PCL's point cloud format, version 0.7:
    DATA ascii or binary; binary_compressed is refused, as a cloud of more than `max_points`).
    RTAB-Map and PCL write the point-cloud map of a SLAM session in this form."""
    import math
    import struct

    with open(path, "rb") as f:
        data = f.read()
    header: Dict[str, List[str]] = {}
    offset = 0
    while "DATA" not in header:
        end = data.find(b"\n", offset)
        if end < 0:
            raise ValueError(f"{path}: PCD header ends before DATA")
        line = data[offset:end].decode("ascii", "replace").strip()
        offset = end + 1
        if line and not line.startswith("#"):
            key, *values = line.split()
            header[key.upper()] = values
    fields = header.get("FIELDS", [])
    sizes = [int(v) for v in header.get("SIZE", [])]
    types = [v.upper() for v in header.get("TYPE", [])]
    counts = [int(v) for v in header.get("COUNT", ["1"] * len(fields))]
    if not (len(fields) == len(sizes) == len(types) == len(counts)) or not all(
            (t, s) in _PCD_TYPES for t, s in zip(types, sizes)):
        raise ValueError(f"{path}: PCD FIELDS, SIZE, TYPE and COUNT disagree")
    for axis in "xyz":
        if axis not in fields:
            raise ValueError(f"{path}: PCD has no field {axis}")
    points = int(header.get("POINTS", ["0"])[0])
    if not 0 <= points <= max_points:
        raise ValueError(f"{path}: {points} points, at most {max_points} read")
    mode = header["DATA"][0].lower()
    # Where x, y and z start among a point's values.
    starts = [sum(counts[:i]) for i in range(len(fields))]
    ix, iy, iz = (starts[fields.index(a)] for a in "xyz")
    if mode == "ascii":
        rows = (line.split() for line in data[offset:].decode("ascii").splitlines()[:points])
        values = ((float(r[ix]), float(r[iy]), float(r[iz])) for r in rows if r)
    elif mode == "binary":
        codes = "".join(_PCD_TYPES[(t, s)] * c for t, s, c in zip(types, sizes, counts))
        record = struct.Struct("<" + codes)
        if len(data) - offset < points * record.size:
            raise ValueError(f"{path}: PCD data shorter than its {points} points")
        values = ((r[ix], r[iy], r[iz]) for r in record.iter_unpack(
            data[offset:offset + points * record.size]))
    else:
        raise ValueError(f"{path}: PCD DATA {mode} is not read (save it as binary or ascii)")
    return [(x, y, z) for x, y, z in values if math.isfinite(x + y + z)]


def _inside(polygon: List[List[float]], x: float, y: float) -> bool:
    """Whether (x, y) lies inside the polygon (even-odd rule)."""
    inside = False
    for (x0, y0), (x1, y1) in zip(polygon, polygon[1:] + polygon[:1]):
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def workspace_heights(workspaces: List[Dict[str, Any]],
                      points: List[Tuple[float, float, float]], low: float = 0.2,
                      high: float = 2.0, bin_size: float = 0.01) -> List[Dict[str, Any]]:
    """The workspaces with each missing "height" measured in a point-cloud map (map frame, z
    up): the most populated height, in bins of `bin_size` between `low` and `high`, of the
    points inside the workspace's polygon (a table top is the one horizontal surface there that
    the map sees whole; its legs and what stands on it spread over many heights), refined to the
    mean height of the points in that bin and its two neighbours. A workspace with no point in
    that band is an error naming it."""
    out = []
    for w in workspaces:
        w = dict(w)
        if "height" not in w:
            xs = [p[0] for p in w["polygon"]]
            ys = [p[1] for p in w["polygon"]]
            count: Dict[int, int] = {}
            total: Dict[int, float] = {}
            for x, y, z in points:
                if (low < z < high and min(xs) <= x <= max(xs) and min(ys) <= y <= max(ys)
                        and _inside(w["polygon"], x, y)):
                    k = int(z / bin_size)
                    count[k] = count.get(k, 0) + 1
                    total[k] = total.get(k, 0.0) + z
            if not count:
                raise ValueError(f"workspace {w.get('name', '?')}: no point of the cloud on it "
                                 f"between {low} and {high} m")
            best = max(count, key=lambda k: (count[k], k))
            near = [best - 1, best, best + 1]
            w["height"] = round(sum(total.get(k, 0.0) for k in near) /
                                sum(count.get(k, 0) for k in near), 4)
        out.append(w)
    return out
