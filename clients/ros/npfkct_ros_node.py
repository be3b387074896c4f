#!/usr/bin/env python3
"""npfkct_ros_node: bridges a ROS 1 robot to the npfkct planning server.

It keeps the robot's latest state and sensor data, asks the server for the next action and
publishes it; when the robot's executive reports the action done (~action_result), it sends the
observation (robot state, detections, raw point cloud and image) and plans the next one.

Parameters (private):
  ~server        server URL (default http://127.0.0.1:8080)
  ~api_key       bearer token (optional)
  ~scenario      scenario file whose prior map creates the session, or
  ~session_id    an existing session to drive
  ~planner       planner of a new session (default npfkct)
  ~model         neural filter model of the server for npfkct (e.g. filter.pt; default none)
  ~budget_ms     planning time per step (default 1000)
  ~lift_joint, ~pan_joint, ~tilt_joint   joint names (Fetch: torso_lift_joint, head_pan_joint,
                 head_tilt_joint)
  ~map_frame     frame id of clouds already in the map frame (default map); any other frame id
                 is taken as the camera's optical frame at the reported pose
  ~target_photos list of PNG/JPEG files of the target (new sessions), for the server's perception

Subscribes:
  ~base_pose      geometry_msgs/PoseStamped  base pose in the map frame
  ~joint_states   sensor_msgs/JointState     lift, head pan and tilt
  ~points         sensor_msgs/PointCloud2    camera cloud: sent raw for the server's perception
                                             when no ~detections arrived for the step
  ~image          sensor_msgs/Image          colour image registered with the cloud (rgb8, bgr8,
                                             mono8), sent as PNG with the cloud
  ~camera_info    sensor_msgs/CameraInfo     intrinsics of the cloud's camera
  ~detections     std_msgs/String            JSON array of detections in the API's form
  ~action_result  std_msgs/String            JSON {"actionId": ..., "succeeded": bool}
Publishes:
  ~next_action    std_msgs/String            JSON {"actionId", "action", "expectedValue"}
  ~base_goal      geometry_msgs/PoseStamped  for MOVE actions
  ~joint_goal     sensor_msgs/JointState     lift/pan/tilt targets for MOVE actions
  ~status         std_msgs/String            JSON of the session after each observation
"""

import base64
import json
import math
import os
import struct
import sys
import threading
import zlib

import rospy
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2
from std_msgs.msg import String

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from npfkct_client import ApiError, NpfkctClient  # noqa: E402
from npfkct_client.cli import world_of_scenario  # noqa: E402


def yaw_of(q):
    """Yaw of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


_FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32


def cloud_to_api(msg, map_frame="map"):
    """A PointCloud2 as the API's pointCloud: NaN points dropped, packed as float32 xyz or, when
    the cloud has an rgb/rgba field, xyzrgb. None when no valid point remains."""
    fields = {f.name: f for f in msg.fields}
    for name in ("x", "y", "z"):
        if name not in fields or fields[name].datatype != _FLOAT32:
            raise ValueError(f"~points: field {name} missing or not FLOAT32")
    colour = fields.get("rgb") or fields.get("rgba")
    order = "<" if not msg.is_bigendian else ">"
    layout = [("x", "f"), ("y", "f"), ("z", "f")] + ([(colour.name, "I")] if colour else [])
    fmt, offset = order, 0
    for name, code in sorted(layout, key=lambda item: fields[item[0]].offset):
        fmt += "x" * (fields[name].offset - offset) + code
        offset = fields[name].offset + 4
    fmt += "x" * (msg.point_step - offset)
    names = [name for name, _ in sorted(layout, key=lambda item: fields[item[0]].offset)]
    ix, iy, iz = names.index("x"), names.index("y"), names.index("z")
    ic = names.index(colour.name) if colour else None
    out = bytearray()
    data = bytes(msg.data)
    for row in range(msg.height):
        chunk = data[row * msg.row_step:row * msg.row_step + msg.width * msg.point_step]
        for p in struct.iter_unpack(fmt, chunk):
            x, y, z = p[ix], p[iy], p[iz]
            if x != x or y != y or z != z:
                continue
            if ic is None:
                out += struct.pack("<fff", x, y, z)
            else:
                out += struct.pack("<fffI", x, y, z, p[ic] & 0xFFFFFF)
    if not out:
        return None
    frame = "map" if msg.header.frame_id == map_frame else "camera"
    return {"frame": frame, "fields": "xyzrgb" if colour else "xyz",
            "data": base64.b64encode(bytes(out)).decode()}


def image_to_png(msg):
    """A sensor_msgs/Image (rgb8, bgr8, mono8) as PNG bytes."""
    if msg.encoding in ("rgb8", "bgr8"):
        channels, colour_type = 3, 2
    elif msg.encoding == "mono8":
        channels, colour_type = 1, 0
    else:
        raise ValueError(f"~image: encoding {msg.encoding} (rgb8, bgr8 or mono8 expected)")
    data = bytes(msg.data)
    rows = bytearray()
    for v in range(msg.height):
        line = bytearray(data[v * msg.step:v * msg.step + msg.width * channels])
        if msg.encoding == "bgr8":
            line[0::3], line[2::3] = line[2::3], line[0::3]
        rows += b"\x00" + line

    def chunk(kind, payload):
        body = kind + payload
        return struct.pack(">I", len(payload)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", msg.width, msg.height, 8, colour_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
            chunk(b"IDAT", zlib.compress(bytes(rows), 6)) + chunk(b"IEND", b""))


class NpfkctNode:
    """The bridge; its callbacks run on rospy's threads, guarded by one lock."""

    def __init__(self):
        self.client = NpfkctClient(rospy.get_param("~server", "http://127.0.0.1:8080"),
                                   api_key=rospy.get_param("~api_key", "") or None)
        self.budget_ms = float(rospy.get_param("~budget_ms", 1000.0))
        self.joints = {
            "lift": rospy.get_param("~lift_joint", "torso_lift_joint"),
            "pan": rospy.get_param("~pan_joint", "head_pan_joint"),
            "tilt": rospy.get_param("~tilt_joint", "head_tilt_joint"),
        }
        self.lock = threading.Lock()
        self.state = {k: 0.0 for k in ("x", "y", "yaw", "lift", "pan", "tilt")}
        self.have_pose = False
        self.detections = None
        self.cloud = None
        self.image = None
        self.camera = None
        self.map_frame = rospy.get_param("~map_frame", "map")
        self.pending = None
        self.done = False

        scenario = rospy.get_param("~scenario", "")
        session_id = rospy.get_param("~session_id", "")
        if session_id:
            self.session_id = session_id
        elif scenario:
            photos = []
            for path in rospy.get_param("~target_photos", []):
                with open(path, "rb") as f:
                    photos.append(f.read())
            session = self.client.create_session(
                world_of_scenario(scenario), planner=rospy.get_param("~planner", "npfkct"),
                seed=int(rospy.get_param("~seed", 1)), target_photos=photos or None,
                model=rospy.get_param("~model", "") or None)
            self.session_id = session.id
        else:
            raise RuntimeError("set ~scenario or ~session_id")
        rospy.loginfo("npfkct session %s", self.session_id)

        self.action_pub = rospy.Publisher("~next_action", String, queue_size=10, latch=True)
        self.base_pub = rospy.Publisher("~base_goal", PoseStamped, queue_size=10, latch=True)
        self.joint_pub = rospy.Publisher("~joint_goal", JointState, queue_size=10, latch=True)
        self.status_pub = rospy.Publisher("~status", String, queue_size=10, latch=True)
        rospy.Subscriber("~base_pose", PoseStamped, self.on_pose)
        rospy.Subscriber("~joint_states", JointState, self.on_joints)
        rospy.Subscriber("~points", PointCloud2, self.on_points)
        rospy.Subscriber("~image", Image, self.on_image)
        rospy.Subscriber("~camera_info", CameraInfo, self.on_camera_info)
        rospy.Subscriber("~detections", String, self.on_detections)
        rospy.Subscriber("~action_result", String, self.on_result)

    # -- sensor callbacks --

    def on_pose(self, msg):
        with self.lock:
            self.state["x"] = msg.pose.position.x
            self.state["y"] = msg.pose.position.y
            self.state["yaw"] = yaw_of(msg.pose.orientation)
            first = not self.have_pose
            self.have_pose = True
        if first:
            self.plan_next()

    def on_joints(self, msg):
        with self.lock:
            for key, name in self.joints.items():
                if name in msg.name:
                    self.state[key] = msg.position[msg.name.index(name)]

    def on_points(self, msg):
        with self.lock:
            self.cloud = msg

    def on_image(self, msg):
        with self.lock:
            self.image = msg

    def on_camera_info(self, msg):
        with self.lock:
            self.camera = {"width": msg.width, "height": msg.height, "fx": msg.K[0],
                           "fy": msg.K[4], "cx": msg.K[2], "cy": msg.K[5]}

    def on_detections(self, msg):
        try:
            detections = json.loads(msg.data)
        except ValueError:
            rospy.logwarn("~detections: not JSON")
            return
        if not isinstance(detections, list):
            rospy.logwarn("~detections: expected a JSON array")
            return
        with self.lock:
            self.detections = detections

    # -- the planning loop --

    def on_result(self, msg):
        try:
            result = json.loads(msg.data)
        except ValueError:
            rospy.logwarn("~action_result: not JSON")
            return
        with self.lock:
            if self.pending is None or result.get("actionId") != self.pending["actionId"]:
                rospy.logwarn("~action_result for an action that is not pending: %s", msg.data)
                return
            body = {"succeeded": bool(result.get("succeeded", True)),
                    "robotState": dict(self.state)}
            cloud, image, camera = self.cloud, self.image, self.camera
            detections = self.detections
            action_id = self.pending["actionId"]
            self.pending = None
            self.detections = None
            self.cloud = None
            self.image = None
        if detections is not None:
            body["detections"] = detections
        elif cloud is not None:
            try:
                points = cloud_to_api(cloud, self.map_frame)
                if points is not None:  # an all-NaN cloud: the camera saw nothing in range
                    body["pointCloud"] = points
                    if image is not None:
                        body["image"] = {"encoding": "png",
                                         "data": base64.b64encode(image_to_png(image)).decode()}
                    if camera is not None:
                        body["camera"] = camera
            except (ValueError, struct.error) as e:
                rospy.logerr("sensor data not sent: %s", e)
        try:
            observed = self.client.observe(self.session_id, action_id, body=body)
        except ApiError as e:
            rospy.logerr("observe failed: %s (field %s)", e, e.field)
            return
        self.status_pub.publish(String(data=json.dumps(
            {"done": observed.done, "reward": observed.reward, "session": observed.session.raw})))
        if observed.done:
            rospy.loginfo("target removed: session done")
            self.done = True
            return
        self.plan_next()

    def plan_next(self):
        try:
            plan = self.client.plan(self.session_id, time_ms=self.budget_ms)
        except ApiError as e:
            rospy.logerr("plan failed: %s", e)
            return
        action = plan.action.to_json()
        with self.lock:
            self.pending = {"actionId": plan.action_id, "action": action}
        if action["type"] == "MOVE":
            c = action["configuration"]
            goal = PoseStamped()
            goal.header.stamp = rospy.Time.now()
            goal.header.frame_id = "map"
            goal.pose.position.x = c["x"]
            goal.pose.position.y = c["y"]
            goal.pose.orientation.z = math.sin(c["yaw"] / 2.0)
            goal.pose.orientation.w = math.cos(c["yaw"] / 2.0)
            self.base_pub.publish(goal)
            joints = JointState()
            joints.header.stamp = goal.header.stamp
            joints.name = [self.joints["lift"], self.joints["pan"], self.joints["tilt"]]
            joints.position = [c["lift"], c["pan"], c["tilt"]]
            self.joint_pub.publish(joints)
        self.action_pub.publish(String(data=json.dumps(
            {"actionId": plan.action_id, "action": action,
             "expectedValue": plan.expected_value})))


def main():
    rospy.init_node("npfkct")
    try:
        NpfkctNode()
    except (ApiError, RuntimeError, OSError) as e:
        rospy.logfatal("npfkct node: %s", e)
        return 1
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
