"""The simulated robot (npfkct-sim-robot, JSON lines on stdio) behind typed ROS interfaces.

It stands for a real robot's drivers: tf (map -> base_link, the lift and head chain and a
static camera mount), sensor_msgs/JointState, Detection3DArray in the camera's optical frame,
a FollowJointTrajectory server for the lift and head (the base goal, a PoseStamped in the map
frame on `base_goal`, is executed with it as one MOVE), an ObjectCommand server, and the
simulator's true state on `sim/robot_state` for tests. Everything it publishes after an action
carries one stamp, the instant the simulator executed it.

Fault injection for tests: ~pose_delay (s) publishes the new pose and joints that long after
the detections (a lagging localisation); ~detections_frame labels the detections with another
frame id."""

import json
import math
import subprocess
import threading

import actionlib
import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, TransformStamped
from sensor_msgs.msg import JointState

from npfkct_ros.geometry import Rigid, quat_from_rpy
from npfkct_ros.msg import (Detection3D, Detection3DArray, FaceScore,
                            FollowJointTrajectoryAction, FollowJointTrajectoryResult,
                            ObjectCommandAction, ObjectCommandGoal, ObjectCommandResult,
                            RobotConfig)

COMMANDS = {ObjectCommandGoal.DECLARE_TARGET: "DECLARE_TARGET",
            ObjectCommandGoal.DECLARE_OBSTACLE: "DECLARE_OBSTACLE",
            ObjectCommandGoal.REMOVE: "REMOVE"}

# The head's kinematic chain (a Fetch-like robot): the camera mount matters only in that the
# node must undo it through tf.
HEAD_PAN_OFFSET = (0.05, 0.0, 0.75)
HEAD_TILT_OFFSET = (0.14, 0.0, 0.21)
CAMERA_OFFSET = (0.06, 0.02, 0.05)
OPTICAL = quat_from_rpy(-math.pi / 2, 0.0, -math.pi / 2)  # z forward, x right, y down


class SimRobotBridge:
    """One simulated robot; its callbacks run on rospy's threads, under one lock."""

    def __init__(self):
        p = rospy.get_param
        args = [p("~robot_bin"), "--scenario", p("~scenario"), "--seed", str(p("~seed", 1))]
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     text=True)
        self.map_frame = p("~map_frame", "map")
        self.base_frame = p("~base_frame", "base_link")
        self.camera_frame = p("~camera_frame", "head_camera_rgb_optical_frame")
        self.detections_frame = p("~detections_frame", "") or self.camera_frame
        self.joints = [p("~lift_joint", "torso_lift_joint"), p("~pan_joint", "head_pan_joint"),
                       p("~tilt_joint", "head_tilt_joint")]
        self.pose_delay = float(p("~pose_delay", 0.0))
        self.lock = threading.RLock()
        self.paused = False  # a delayed pose is on its way: no periodic tf meanwhile
        self.last_stamp = rospy.Time(0)
        self.state = None
        self.base_goals = []

        self.tf = tf2_ros.TransformBroadcaster()
        self.static_tf = tf2_ros.StaticTransformBroadcaster()
        self.joint_pub = rospy.Publisher("joint_states", JointState, queue_size=50)
        # Latched: the simulator senses once per action, so a subscriber that connects after
        # the action (a node starting beside the bridge on a loaded machine) still gets it.
        self.det_pub = rospy.Publisher("detections", Detection3DArray, queue_size=10, latch=True)
        self.truth_pub = rospy.Publisher("sim/robot_state", RobotConfig, queue_size=100)
        rospy.Subscriber("base_goal", PoseStamped, self.on_base_goal, queue_size=10)
        mount = TransformStamped()
        mount.header.stamp = rospy.Time.now()
        mount.header.frame_id, mount.child_frame_id = "head_tilt_link", self.camera_frame
        Rigid(CAMERA_OFFSET, OPTICAL).to_transform(mount.transform)
        self.static_tf.sendTransform(mount)

        self.publish(self.execute({"type": "LOOK"}), truth=False)
        self.trajectory = actionlib.SimpleActionServer(
            "follow_joint_trajectory", FollowJointTrajectoryAction, self.on_trajectory, False)
        self.command = actionlib.SimpleActionServer(
            "object_command", ObjectCommandAction, self.on_command, False)
        self.trajectory.start()
        self.command.start()
        threading.Thread(target=self.periodic, daemon=True).start()
        rospy.on_shutdown(self.close)

    def close(self):
        """Ends the simulator."""
        if self.proc.poll() is None:
            self.proc.stdin.close()
            self.proc.wait(timeout=10)

    def execute(self, action):
        """One action through the simulator: its {"outcome", "observation"} reply."""
        with self.lock:
            self.proc.stdin.write(json.dumps(action) + "\n")
            self.proc.stdin.flush()
            return json.loads(self.proc.stdout.readline())

    # -- publishing --

    def next_stamp(self):
        """Now, strictly after every stamp published so far (tf drops repeated stamps)."""
        stamp = rospy.Time.now()
        if stamp <= self.last_stamp:
            stamp = self.last_stamp + rospy.Duration(0, 1000)
        self.last_stamp = stamp
        return stamp

    def chain(self, state, stamp):
        """map -> base_link -> head_pan_link -> head_tilt_link, as TransformStamped."""
        links = [
            (self.map_frame, self.base_frame,
             Rigid((state["x"], state["y"], 0.0), quat_from_rpy(0.0, 0.0, state["yaw"]))),
            (self.base_frame, "head_pan_link",
             Rigid((HEAD_PAN_OFFSET[0], HEAD_PAN_OFFSET[1], HEAD_PAN_OFFSET[2] + state["lift"]),
                   quat_from_rpy(0.0, 0.0, state["pan"]))),
            ("head_pan_link", "head_tilt_link",
             Rigid(HEAD_TILT_OFFSET, quat_from_rpy(0.0, state["tilt"], 0.0))),
        ]
        out = []
        for parent, child, rigid in links:
            t = TransformStamped()
            t.header.stamp, t.header.frame_id, t.child_frame_id = stamp, parent, child
            rigid.to_transform(t.transform)
            out.append((t, rigid))
        return out

    def publish_pose(self, state, stamp):
        """tf and joint states of `state` at `stamp`."""
        self.tf.sendTransform([t for t, _ in self.chain(state, stamp)])
        joints = JointState()
        joints.header.stamp = stamp
        joints.name = list(self.joints)
        joints.position = [state["lift"], state["pan"], state["tilt"]]
        self.joint_pub.publish(joints)

    def publish(self, reply, truth=True):
        """Publishes what the robot sensed after an action, all stamped now."""
        observation = reply["observation"]
        with self.lock:
            state = self.state = observation["robotState"]
            stamp = self.next_stamp()
            map_to_camera = Rigid()
            for _, rigid in self.chain(state, stamp):
                map_to_camera = map_to_camera * rigid
            map_to_camera = map_to_camera * Rigid(CAMERA_OFFSET, OPTICAL)
            camera_from_map = map_to_camera.inverse()
            msg = Detection3DArray()
            msg.header.stamp, msg.header.frame_id = stamp, self.detections_frame
            for d in observation.get("detections", []):
                box = d["box"]
                in_map = Rigid(box["center"], quat_from_rpy(0.0, 0.0, box.get("yaw", 0.0)))
                det = Detection3D(id=d["id"], moveability=d.get("moveability", 1.0))
                det.header = msg.header
                (camera_from_map * in_map).to_pose(det.bbox.center)
                det.bbox.size.x, det.bbox.size.y, det.bbox.size.z = box["size"]
                det.faces = [FaceScore(corner=f["corner"], score=f["score"])
                             for f in d.get("faces", [])]
                msg.detections.append(det)
            if truth:
                self.truth_pub.publish(RobotConfig(**state))
            if self.pose_delay > 0 and truth:
                self.det_pub.publish(msg)
                self.paused = True
                threading.Timer(self.pose_delay, self.delayed_pose, (state, stamp)).start()
            else:
                self.publish_pose(state, stamp)
                self.det_pub.publish(msg)

    def delayed_pose(self, state, stamp):
        """The pose of an action, late (~pose_delay)."""
        with self.lock:
            self.publish_pose(state, stamp)
            self.paused = False

    def periodic(self):
        """Republishes the pose at 10 Hz, as a robot's localisation and joint drivers do."""
        rate = rospy.Rate(10)
        while not rospy.is_shutdown():
            with self.lock:
                if not self.paused:
                    self.publish_pose(self.state, self.next_stamp())
            try:
                rate.sleep()
            except rospy.ROSInterruptException:
                return

    # -- the robot's action servers --

    def on_base_goal(self, msg):
        """Keeps the base goals until a trajectory goal with the same stamp executes them."""
        with self.lock:
            self.base_goals = (self.base_goals + [msg])[-10:]

    def base_goal_for(self, stamp, timeout=5.0):
        """The base goal stamped `stamp` (the node stamps both goals of a MOVE alike)."""
        deadline = rospy.Time.now() + rospy.Duration(timeout)
        while rospy.Time.now() < deadline and not rospy.is_shutdown():
            with self.lock:
                for goal in self.base_goals:
                    if goal.header.stamp == stamp:
                        return goal
            rospy.sleep(0.01)
        return None

    def on_trajectory(self, goal):
        """A MOVE: the trajectory's last point for the joints, the matching base goal."""
        result = FollowJointTrajectoryResult()
        names = list(goal.trajectory.joint_names)
        if not goal.trajectory.points or any(name not in names for name in self.joints):
            result.error_code = FollowJointTrajectoryResult.INVALID_JOINTS
            result.error_string = f"expected joints {self.joints}, got {names}"
            self.trajectory.set_aborted(result, result.error_string)
            return
        rospy.logdebug("sim_robot: trajectory goal stamped %.3f",
                       goal.trajectory.header.stamp.to_sec())
        base = self.base_goal_for(goal.trajectory.header.stamp)
        if base is None or base.header.frame_id != self.map_frame:
            result.error_code = FollowJointTrajectoryResult.INVALID_GOAL
            result.error_string = ("no base goal with the trajectory's stamp" if base is None
                                   else f"base goal in frame '{base.header.frame_id}', "
                                   f"expected '{self.map_frame}'")
            self.trajectory.set_aborted(result, result.error_string)
            return
        end = goal.trajectory.points[-1].positions
        o = base.pose.orientation
        config = {"x": base.pose.position.x, "y": base.pose.position.y,
                  "yaw": math.atan2(2.0 * (o.w * o.z + o.x * o.y),
                                    1.0 - 2.0 * (o.y * o.y + o.z * o.z)),
                  "lift": end[names.index(self.joints[0])],
                  "pan": end[names.index(self.joints[1])],
                  "tilt": end[names.index(self.joints[2])]}
        rospy.logdebug("sim_robot: MOVE to %s", config)
        reply = self.execute({"type": "MOVE", "configuration": config})
        self.publish(reply)
        if reply["outcome"]["illegal"]:
            result.error_code = FollowJointTrajectoryResult.GOAL_TOLERANCE_VIOLATED
            result.error_string = reply["outcome"]["detail"]
            self.trajectory.set_aborted(result, result.error_string)
        else:
            self.trajectory.set_succeeded(result)

    def on_command(self, goal):
        """DECLARE_TARGET, DECLARE_OBSTACLE or REMOVE of one object."""
        if goal.command not in COMMANDS:
            self.command.set_aborted(ObjectCommandResult(False, "unknown command"))
            return
        action = {"type": COMMANDS[goal.command], "objectId": goal.object_id}
        if goal.bbox.size.x > 0 and goal.header.frame_id == self.map_frame:
            c = Rigid.of_pose(goal.bbox.center)
            action["objectBox"] = {"center": list(c.t), "yaw": c.yaw(),
                                   "size": [goal.bbox.size.x, goal.bbox.size.y,
                                            goal.bbox.size.z]}
        reply = self.execute(action)
        self.publish(reply)
        outcome = reply["outcome"]
        self.command.set_succeeded(ObjectCommandResult(not outcome["illegal"],
                                                       outcome["detail"]))
