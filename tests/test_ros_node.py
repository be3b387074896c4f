"""The ROS 1 node against a real roscore and the real server: a whole episode over topics.

The test plays the robot: it executes the node's actions with the simulated robot and publishes
the robot's pose, joints and detections, then the action's result."""

import json
import math
import os
import socket
import subprocess
import sys
import time

import pytest

from conftest import ROOT, SimRobot, scenario_path, wait_for

rospy = pytest.importorskip("rospy")
from geometry_msgs.msg import PoseStamped  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import String  # noqa: E402

NODE = os.path.join(ROOT, "clients", "ros", "npfkct_ros_node.py")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def roscore(tmp_path):
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


def test_node_drives_an_episode(roscore, server):
    node = subprocess.Popen([sys.executable, NODE, f"_server:={server.url}",
                             f"_scenario:={scenario_path('loose1')}", "_budget_ms:=250",
                             "_seed:=2", "__name:=npfkct"],
                            env=roscore, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    try:
        rospy.init_node("npfkct_test_robot", anonymous=True, disable_signals=True)
        actions, goals, statuses = [], [], []
        rospy.Subscriber("/npfkct/next_action", String, lambda m: actions.append(json.loads(m.data)))
        rospy.Subscriber("/npfkct/base_goal", PoseStamped, goals.append)
        rospy.Subscriber("/npfkct/status", String, lambda m: statuses.append(json.loads(m.data)))
        pose_pub = rospy.Publisher("/npfkct/base_pose", PoseStamped, queue_size=10, latch=True)
        joint_pub = rospy.Publisher("/npfkct/joint_states", JointState, queue_size=10, latch=True)
        det_pub = rospy.Publisher("/npfkct/detections", String, queue_size=10, latch=True)
        result_pub = rospy.Publisher("/npfkct/action_result", String, queue_size=10)
        assert wait_for(lambda: result_pub.get_num_connections() > 0 and
                        pose_pub.get_num_connections() > 0, timeout=60), node.stdout.read()

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
            det_pub.publish(String(data=json.dumps(observation["detections"])))
            pose_pub.publish(pose)

        robot = SimRobot("loose1", seed=2)
        publish_state(robot.execute({"type": "LOOK"})["observation"])
        done = False
        for step in range(40):
            assert wait_for(lambda: len(actions) > step, timeout=60), node.stdout.read()
            pending = actions[step]
            reply = robot.execute(pending["action"])
            publish_state(reply["observation"])
            time.sleep(0.3)  # let the state messages land before the result
            result_pub.publish(String(data=json.dumps(
                {"actionId": pending["actionId"], "succeeded": not reply["outcome"]["illegal"]})))
            assert wait_for(lambda: len(statuses) > step, timeout=60), node.stdout.read()
            if statuses[step]["done"]:
                done = True
                break
        robot.close()
        assert done
        assert goals, "MOVE actions were published as base goals"
        assert statuses[-1]["session"]["state"] == "DONE"
    finally:
        node.terminate()
        node.wait(timeout=30)
