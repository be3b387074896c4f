"""The ROS 1 node against a real roscore and the real server: whole episodes over topics.

The test plays the robot: it executes the node's actions with the simulated robot and publishes
the robot's pose, joints and either detections or the rendered camera frame (PointCloud2, Image,
CameraInfo), then the action's result."""

import base64
import json
import math
import os
import socket
import struct
import subprocess
import sys
import time
import zlib

import pytest

from conftest import ROOT, SimRobot, scenario_path, wait_for

rospy = pytest.importorskip("rospy")
from geometry_msgs.msg import PoseStamped  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image, JointState, PointCloud2, PointField  # noqa: E402
from std_msgs.msg import String  # noqa: E402

NODE = os.path.join(ROOT, "clients", "ros", "npfkct_ros_node.py")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def roscore(tmp_path_factory):
    # One master for the module: rospy binds this process to the first master it meets.
    tmp_path = tmp_path_factory.mktemp("ros")
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_HOSTNAME="127.0.0.1",
               ROS_LOG_DIR=str(tmp_path / "roslog"), ROS_HOME=str(tmp_path / "roshome"))
    proc = subprocess.Popen(["roscore", "-p", str(port)], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    os.environ.update({k: env[k] for k in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_LOG_DIR",
                                           "ROS_HOME")})
    import rosgraph
    assert wait_for(lambda: rosgraph.is_master_online(), timeout=30)
    yield env
    proc.terminate()
    proc.wait(timeout=30)


def png_to_bgr8(png):
    """(width, height, bgr bytes) of an 8-bit RGB or RGBA PNG (what OpenCV writes)."""
    pos, chunks = 8, []
    while pos < len(png):
        length, kind = struct.unpack(">I4s", png[pos:pos + 8])
        chunks.append((kind, png[pos + 8:pos + 8 + length]))
        pos += 12 + length
    header = dict(chunks)[b"IHDR"]
    width, height, depth, colour = struct.unpack(">IIBB", header[:10])
    assert depth == 8 and colour in (2, 6)
    bpp = 3 if colour == 2 else 4
    raw = zlib.decompress(b"".join(data for kind, data in chunks if kind == b"IDAT"))
    stride = width * bpp
    out, prev = bytearray(), bytearray(stride)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b = prev[i]
            c = prev[i - bpp] if i >= bpp else 0
            if kind == 1:
                line[i] = (line[i] + a) & 255
            elif kind == 2:
                line[i] = (line[i] + b) & 255
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        prev = line
        pixels = line if bpp == 3 else bytearray(b for k, b in enumerate(line) if k % 4 != 3)
        pixels[0::3], pixels[2::3] = pixels[2::3], pixels[0::3]  # RGB -> BGR
        out += pixels
    return width, height, bytes(out)


def sensor_messages(observation):
    """The rendered frame of a raw observation as PointCloud2, Image and CameraInfo."""
    stamp = rospy.Time.now()
    cloud = PointCloud2()
    cloud.header.stamp, cloud.header.frame_id = stamp, "head_camera_rgb_optical_frame"
    data = base64.b64decode(observation["pointCloud"]["data"])
    cloud.height, cloud.width = 1, len(data) // 16
    cloud.fields = [PointField(name, 4 * i, PointField.FLOAT32, 1)
                    for i, name in enumerate(("x", "y", "z", "rgb"))]
    cloud.is_bigendian, cloud.point_step, cloud.row_step = False, 16, len(data)
    cloud.data, cloud.is_dense = data, True
    width, height, bgr = png_to_bgr8(base64.b64decode(observation["image"]["data"]))
    image = Image()
    image.header = cloud.header
    image.width, image.height, image.encoding, image.step = width, height, "bgr8", 3 * width
    image.data = bgr
    info = CameraInfo()
    info.header = cloud.header
    c = observation["camera"]
    info.width, info.height = c["width"], c["height"]
    info.K = [c["fx"], 0, c["cx"], 0, c["fy"], c["cy"], 0, 0, 1]
    return cloud, image, info


def drive_episode(roscore, server, raw, steps=40):
    """Runs the node on Loose1 and plays its robot; returns the statuses it published."""
    seed = 2
    robot = SimRobot("loose1", seed=seed, raw=raw)
    args = [sys.executable, NODE, f"_server:={server.url}",
            f"_scenario:={scenario_path('loose1')}", "_budget_ms:=250", f"_seed:={seed}",
            "__name:=npfkct"]
    photo_dir = os.path.join(roscore["ROS_HOME"], "photos")
    if raw:
        os.makedirs(photo_dir, exist_ok=True)
        paths = []
        for i, photo in enumerate(robot.target_photos()):
            paths.append(os.path.join(photo_dir, f"target{i}.png"))
            with open(paths[-1], "wb") as f:
                f.write(photo)
        args.append("_target_photos:=" + json.dumps(paths))
    node = subprocess.Popen(args, env=roscore, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    try:
        rospy.init_node("npfkct_test_robot", anonymous=True, disable_signals=True)
        actions, goals, statuses = [], [], []
        subs = [
            rospy.Subscriber("/npfkct/next_action", String,
                             lambda m: actions.append(json.loads(m.data))),
            rospy.Subscriber("/npfkct/base_goal", PoseStamped, goals.append),
            rospy.Subscriber("/npfkct/status", String,
                             lambda m: statuses.append(json.loads(m.data))),
        ]
        pose_pub = rospy.Publisher("/npfkct/base_pose", PoseStamped, queue_size=10, latch=True)
        joint_pub = rospy.Publisher("/npfkct/joint_states", JointState, queue_size=10, latch=True)
        det_pub = rospy.Publisher("/npfkct/detections", String, queue_size=10, latch=True)
        cloud_pub = rospy.Publisher("/npfkct/points", PointCloud2, queue_size=2)
        image_pub = rospy.Publisher("/npfkct/image", Image, queue_size=2)
        info_pub = rospy.Publisher("/npfkct/camera_info", CameraInfo, queue_size=2, latch=True)
        result_pub = rospy.Publisher("/npfkct/action_result", String, queue_size=10)
        assert wait_for(lambda: result_pub.get_num_connections() > 0 and
                        pose_pub.get_num_connections() > 0 and
                        cloud_pub.get_num_connections() > 0, timeout=60), node.stdout.read()

        def publish_state(observation):
            c = observation["robotState"]
            pose = PoseStamped()
            pose.header.frame_id = "map"
            pose.pose.position.x, pose.pose.position.y = c["x"], c["y"]
            pose.pose.orientation.z = math.sin(c["yaw"] / 2)
            pose.pose.orientation.w = math.cos(c["yaw"] / 2)
            joints = JointState()
            joints.name = ["torso_lift_joint", "head_pan_joint", "head_tilt_joint"]
            joints.position = [c["lift"], c["pan"], c["tilt"]]
            joint_pub.publish(joints)
            if "detections" in observation:
                det_pub.publish(String(data=json.dumps(observation["detections"])))
            if "pointCloud" in observation:
                cloud, image, info = sensor_messages(observation)
                info_pub.publish(info)
                image_pub.publish(image)
                cloud_pub.publish(cloud)
            pose_pub.publish(pose)

        publish_state(robot.execute({"type": "LOOK"})["observation"])
        for step in range(steps):
            assert wait_for(lambda: len(actions) > step, timeout=60), node.stdout.read()
            pending = actions[step]
            reply = robot.execute(pending["action"])
            publish_state(reply["observation"])
            time.sleep(0.5)  # let the state and sensor messages land before the result
            result_pub.publish(String(data=json.dumps(
                {"actionId": pending["actionId"], "succeeded": not reply["outcome"]["illegal"]})))
            assert wait_for(lambda: len(statuses) > step, timeout=60), node.stdout.read()
            if statuses[step]["done"]:
                break
        assert goals, "MOVE actions were published as base goals"
        for sub in subs:
            sub.unregister()
        return statuses
    finally:
        robot.close()
        node.terminate()
        node.wait(timeout=30)


def test_node_drives_an_episode(roscore, server):
    statuses = drive_episode(roscore, server, raw=False)
    assert statuses[-1]["done"]
    assert statuses[-1]["session"]["state"] == "DONE"
    assert "perceptionTracks" not in statuses[-1]["session"]


def test_node_sends_raw_frames_to_perception(roscore, server):
    statuses = drive_episode(roscore, server, raw=True, steps=30)
    # The server's perception turned the PointCloud2 + Image into objects.
    assert statuses[-1]["session"]["perceptionTracks"] >= 2
    assert statuses[-1]["session"]["objectCount"] >= 2
    assert statuses[-1]["done"], "the target was not removed within 30 steps"
