"""The FindObject action server: one npfkct session per goal, driven step by step (the session
and the step loop are episode.py's, plain Python; this module is the ROS 1 robot around it).

Each step: plan on the server; send the action to the robot (MOVE: a PoseStamped base goal in
the map frame on `base_goal` and a FollowJointTrajectory goal for the lift and head joints;
DECLARE_* / REMOVE: an ObjectCommand goal); wait for the first Detection3DArray stamped after
the action was sent; pair it with the robot's state at the detections' stamp (tf map -> base,
joint_states), refusing a pose or joints older than the detections by more than
~stale_tolerance; move the detections into the map frame through tf; observe; publish feedback.
A cancelled (preempted) goal deletes its session, and so does shutting the node down. After each
plan and each observation the belief and the next view go out as RViz markers on
`belief_markers` (visualization_msgs/MarkerArray, while someone subscribes; markers.py)."""

import threading
import types
from collections import deque

import actionlib
import rospy
import tf2_ros
from actionlib_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, PoseStamped
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from npfkct_client import ApiError, NpfkctClient, World
from npfkct_ros import retry
from npfkct_ros.episode import Episode, GoalError, Preempted, Robot
from npfkct_ros.geometry import Rigid, quat_from_rpy
from npfkct_ros.maps import occupancy_grid_json, world_from_map
from npfkct_ros.markers import belief_markers
from npfkct_ros.msg import (Detection3DArray, FindObjectAction, FindObjectFeedback,
                            FindObjectResult, FollowJointTrajectoryAction,
                            FollowJointTrajectoryGoal, ObjectCommandAction, ObjectCommandGoal,
                            RobotConfig)

MARKER_MSGS = types.SimpleNamespace(Marker=Marker, MarkerArray=MarkerArray, Point=Point,
                                    ColorRGBA=ColorRGBA)
OBJECT_COMMANDS = {"DECLARE_TARGET": ObjectCommandGoal.DECLARE_TARGET,
                   "DECLARE_OBSTACLE": ObjectCommandGoal.DECLARE_OBSTACLE,
                   "REMOVE": ObjectCommandGoal.REMOVE}


class FindObjectServer(Robot):
    """The node: parameters, tf, the robot's action clients and the find_object server; the
    Robot of its goals' episodes."""

    def __init__(self):
        p = rospy.get_param
        self.client = NpfkctClient(p("~server", "http://127.0.0.1:8080"),
                                   api_key=str(p("~api_key", "")) or None,
                                   timeout=float(p("~http_timeout", 60.0)))
        self.policy = retry.RetryPolicy(int(p("~retries", 5)), float(p("~retry_base_s", 0.2)),
                                        float(p("~retry_max_s", 5.0)))
        self.map_frame = p("~map_frame", "map")
        self.base_frame = p("~base_frame", "base_link")
        self.camera_frame = p("~camera_frame", "head_camera_rgb_optical_frame")
        self.joints = [p("~lift_joint", "torso_lift_joint"), p("~pan_joint", "head_pan_joint"),
                       p("~tilt_joint", "head_tilt_joint")]
        self.defaults = {
            "scenario": p("~scenario", ""), "planner": p("~planner", "npfkct"),
            "model": p("~model", ""), "seed": int(p("~seed", 1)),
            "max_steps": int(p("~max_steps", 50)), "budget_ms": float(p("~budget_ms", 1000.0)),
            "target_description": p("~target_description", ""),
            "target_photos": list(p("~target_photos", [])),
        }
        # A SLAM map (nav_msgs/OccupancyGrid, latched) and the workspaces traced in it: the
        # session's world instead of the scenario's room and furniture.
        self.map_topic = str(p("~map_topic", ""))
        self.workspaces = list(p("~workspaces", []))
        self.map = None
        self.stale_tolerance = float(p("~stale_tolerance", 0.0))
        self.pose_timeout = float(p("~pose_timeout", 5.0))
        self.action_timeout = float(p("~action_timeout", 60.0))
        self.tf_timeout = float(p("~tf_timeout", 10.0))
        self.base_tolerance = float(p("~base_tolerance", 0.05))
        self.yaw_tolerance = float(p("~yaw_tolerance", 0.05))

        self.tf = tf2_ros.Buffer(cache_time=rospy.Duration(60.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf)
        self.cond = threading.Condition()
        self.joint_history = deque(maxlen=500)  # (stamp, {name: position}), by arrival
        self.detections = None  # the newest Detection3DArray
        self.episode = None  # the running goal's
        self.session_lock = threading.Lock()

        self.base_pub = rospy.Publisher("base_goal", PoseStamped, queue_size=1, latch=True)
        self.markers_pub = rospy.Publisher("belief_markers", MarkerArray, queue_size=1,
                                           latch=True)
        self.trajectory = actionlib.SimpleActionClient("follow_joint_trajectory",
                                                       FollowJointTrajectoryAction)
        self.object_command = actionlib.SimpleActionClient("object_command", ObjectCommandAction)
        rospy.Subscriber("joint_states", JointState, self.on_joints, queue_size=50)
        rospy.Subscriber("detections", Detection3DArray, self.on_detections, queue_size=10)
        if self.map_topic:
            rospy.Subscriber(self.map_topic, OccupancyGrid, self.on_map, queue_size=1)
        self.server = actionlib.SimpleActionServer("find_object", FindObjectAction,
                                                   execute_cb=self.on_goal, auto_start=False)
        rospy.on_shutdown(self.on_shutdown)
        self.server.start()
        rospy.loginfo("npfkct: find_object ready (server %s)", self.client.base_url)

    # -- subscriptions --

    def on_joints(self, msg):
        """Keeps the joint states, stamped, for pairing with detections."""
        positions = dict(zip(msg.name, msg.position))
        with self.cond:
            self.joint_history.append((msg.header.stamp, positions))
            self.cond.notify_all()

    def on_map(self, msg):
        """Keeps the newest map."""
        with self.cond:
            self.map = msg
            self.cond.notify_all()

    def session_world(self, scenario):
        """The session's world: the scenario's prior map, or with ~map_topic the newest map
        (waited for up to ~pose_timeout) and ~workspaces, the scenario giving the robot, start
        and parameters."""
        base = World.from_scenario(scenario) if scenario else {}
        if not self.map_topic:
            return base
        with self.cond:
            self.cond.wait_for(lambda: self.map is not None, timeout=self.pose_timeout)
            grid = self.map
        if grid is None:
            raise GoalError(f"no map on {self.map_topic} within {self.pose_timeout} s")
        return world_from_map(base, occupancy_grid_json(grid), self.workspaces)

    def on_detections(self, msg):
        """Keeps the newest detections."""
        with self.cond:
            self.detections = msg
            self.cond.notify_all()

    # -- the goal --

    def on_goal(self, goal):
        """SimpleActionServer's callback: runs one episode; ends the goal."""
        result = FindObjectResult()
        try:
            self.run_episode(goal, result)
        except Preempted:
            self.delete_session("goal cancelled")
            result.message = "cancelled: session deleted"
            self.server.set_preempted(result, result.message)
            return
        except (GoalError, ApiError, OSError, ValueError, tf2_ros.TransformException) as e:
            result.message = str(e)
            rospy.logerr("npfkct: goal aborted: %s", e)
            with self.session_lock:
                self.episode = None  # the session is kept for inspection (its TTL ends it)
            self.server.set_aborted(result, result.message)
            return
        with self.session_lock:
            self.episode = None
        if result.success:
            self.server.set_succeeded(result, result.message)
        else:
            self.server.set_aborted(result, result.message)

    def run_episode(self, goal, result):
        """Creates the session and loops plan -> execute -> observe; fills `result`."""
        d = self.defaults
        scenario = goal.scenario or d["scenario"]
        if not scenario and not self.map_topic:
            raise GoalError("no scenario: set the goal's scenario, the ~scenario parameter or "
                            "~map_topic")
        max_steps = goal.max_steps or d["max_steps"]
        budget_ms = goal.budget_ms or d["budget_ms"]
        self.check_frames()
        photos = []
        for path in list(goal.target_photos) or d["target_photos"]:
            with open(path, "rb") as f:
                photos.append(f.read())
        world = self.session_world(scenario)
        episode = Episode(self.client, self.policy, self)
        with self.session_lock:
            self.episode = episode
        session = episode.create(
            world, planner=goal.planner or d["planner"], seed=goal.seed or d["seed"],
            model=d["model"] or None,
            target_description=goal.target_description or d["target_description"] or None,
            target_photos=photos or None)
        result.session_id = session.id
        rospy.loginfo("npfkct: session %s", session.id)

        def on_step(step, action_id, action, value, succeeded, body, reward, done, session):
            result.steps = session.step
            result.reward += reward
            feedback = FindObjectFeedback(
                step=step, session_id=session.id, action_id=action_id,
                action_type=action["type"], object_id=action.get("objectId", ""),
                expected_value=value, succeeded=succeeded,
                observed=RobotConfig(**body["robotState"]), detections=len(body["detections"]),
                reward=reward, done=done)
            if action["type"] == "MOVE":
                feedback.configuration = RobotConfig(**action["configuration"])
            self.server.publish_feedback(feedback)
            rospy.loginfo("npfkct: step %d %s succeeded=%s reward=%g", step, action["type"],
                          succeeded, reward)

        result.success, result.steps, _, result.message = episode.run(
            budget_ms, max_steps, on_step, self.publish_markers)

    # -- Robot: what an episode needs of this node --

    def now(self):
        return rospy.Time.now()

    def execute(self, action, sent):
        return self.send_to_robot(action, sent)

    def observe(self, sent):
        detections = self.wait_detections(sent)
        state, _ = self.robot_state_at(detections.header.stamp)
        return state, self.detections_in_map(detections)

    def preempted(self):
        return self.server.is_preempt_requested() or rospy.is_shutdown()

    def log(self, level, message):
        {"info": rospy.loginfo, "warn": rospy.logwarn}.get(level, rospy.logerr)(
            "npfkct: %s", message)

    def sleep(self, seconds):
        """rospy.sleep that ends early when the node shuts down."""
        try:
            rospy.sleep(seconds)
        except rospy.ROSInterruptException:
            pass

    def publish_markers(self, session_id):
        """The session's belief and next view as RViz markers, when someone listens (one GET of
        the belief; a failure is logged, never the goal's end)."""
        if self.markers_pub.get_num_connections() == 0:
            return
        try:
            belief = self.client.belief(session_id)
            self.markers_pub.publish(
                belief_markers(belief, self.map_frame, rospy.Time.now(), MARKER_MSGS))
        except (ApiError, OSError, KeyError, TypeError, ValueError) as e:
            rospy.logwarn("npfkct: belief markers not published: %s", e)

    def delete_session(self, why):
        """Deletes the running goal's session (one try each way: shutdown cannot wait long)."""
        with self.session_lock:
            episode, self.episode = self.episode, None
        if episode is not None:
            episode.delete(why)

    def on_shutdown(self):
        """rospy's shutdown hook."""
        self.delete_session("shutdown")

    def check_preempt(self):
        """Raises Preempted when the goal was cancelled or the node is going down."""
        if self.preempted():
            raise Preempted()

    # -- tf --

    def check_frames(self):
        """The map -> base and base -> camera transforms exist (else the goal is refused)."""
        for target, source, what in ((self.map_frame, self.base_frame, "the robot's pose"),
                                     (self.base_frame, self.camera_frame,
                                      "the camera's extrinsics")):
            try:
                self.tf.lookup_transform(target, source, rospy.Time(0),
                                         rospy.Duration(self.tf_timeout))
            except tf2_ros.TransformException as e:
                raise GoalError(f"no tf {target} -> {source} ({what}) within "
                                f"{self.tf_timeout:g} s: {e}") from None

    def transform_at(self, target, source, stamp):
        """The transform target <- source at `stamp`: exact when tf has data at or after it;
        tf's newest one when that is at most ~stale_tolerance older than `stamp`; else waits up
        to ~pose_timeout for tf to catch up, and refuses (GoalError) an older pose."""
        try:
            return self.tf.lookup_transform(target, source, stamp)
        except tf2_ros.ExtrapolationException:
            pass
        except tf2_ros.TransformException as e:
            raise GoalError(f"no tf {target} -> {source}: {e}") from None
        latest = self.tf.lookup_transform(target, source, rospy.Time(0))
        if (stamp - latest.header.stamp).to_sec() <= self.stale_tolerance:
            return latest
        deadline = rospy.Time.now() + rospy.Duration(self.pose_timeout)
        while rospy.Time.now() < deadline:
            self.check_preempt()
            try:
                return self.tf.lookup_transform(target, source, stamp, rospy.Duration(0.1))
            except tf2_ros.TransformException:
                pass
        latest = self.tf.lookup_transform(target, source, rospy.Time(0))
        raise GoalError(
            f"refusing to observe: the newest tf {target} -> {source} "
            f"({latest.header.stamp.to_sec():.3f}) is "
            f"{(stamp - latest.header.stamp).to_sec():.3f} s older than the detections "
            f"({stamp.to_sec():.3f}; tolerance {self.stale_tolerance:g} s) and none newer "
            f"came within {self.pose_timeout:g} s")

    def joints_at(self, stamp):
        """Lift, pan and tilt from the first joint state stamped at or after `stamp` (or the
        newest, when at most ~stale_tolerance older); waits up to ~pose_timeout, then refuses."""
        deadline = rospy.Time.now() + rospy.Duration(self.pose_timeout)
        with self.cond:
            while True:
                newest = None
                for joint_stamp, positions in self.joint_history:
                    if all(name in positions for name in self.joints):
                        if joint_stamp >= stamp:
                            return [positions[name] for name in self.joints]
                        newest = (joint_stamp, positions)
                if newest and (stamp - newest[0]).to_sec() <= self.stale_tolerance:
                    return [newest[1][name] for name in self.joints]
                self.check_preempt()
                if rospy.Time.now() >= deadline:
                    age = "none" if newest is None else f"{(stamp - newest[0]).to_sec():.3f} s"
                    raise GoalError(
                        f"refusing to observe: no joint state of {', '.join(self.joints)} "
                        f"stamped at or after the detections (newest older by {age}; "
                        f"tolerance {self.stale_tolerance:g} s) within {self.pose_timeout:g} s")
                self.cond.wait(0.1)

    def robot_state_at(self, stamp):
        """The API's robotState at `stamp` (tf map -> base, joint states) and the pose's stamp."""
        base = self.transform_at(self.map_frame, self.base_frame, stamp)
        lift, pan, tilt = self.joints_at(stamp)
        pose = Rigid.of_transform(base.transform)
        return ({"x": pose.t[0], "y": pose.t[1], "yaw": pose.yaw(), "lift": lift, "pan": pan,
                 "tilt": tilt}, base.header.stamp)

    def detections_in_map(self, msg):
        """The API's detections: each box moved into the map frame through tf at its stamp.
        A frame that is neither the camera's nor the map's nor known to tf is refused."""
        out = []
        for det in msg.detections:
            frame = det.header.frame_id or msg.header.frame_id
            stamp = det.header.stamp if det.header.frame_id else msg.header.stamp
            if not frame:
                raise GoalError("detections without a frame_id (expected the camera frame "
                                f"'{self.camera_frame}' or the map frame '{self.map_frame}')")
            if frame == self.map_frame:
                to_map = Rigid()
            else:
                if frame != self.camera_frame and not self.tf.can_transform(
                        self.map_frame, frame, rospy.Time(0), rospy.Duration(1.0)):
                    raise GoalError(
                        f"detections in frame '{frame}': not the camera frame "
                        f"'{self.camera_frame}' nor the map frame '{self.map_frame}', and tf "
                        f"has no transform from '{frame}' to '{self.map_frame}'")
                to_map = Rigid.of_transform(
                    self.transform_at(self.map_frame, frame, stamp).transform)
            box = to_map * Rigid.of_pose(det.bbox.center)
            size = det.bbox.size
            out.append({
                "id": det.id,
                "box": {"center": list(box.t), "yaw": box.yaw(),
                        "size": [size.x, size.y, size.z]},
                "moveability": min(max(float(det.moveability), 0.0), 1.0),
                "faces": [{"corner": int(f.corner), "score": min(max(float(f.score), 0.0), 1.0)}
                          for f in det.faces],
            })
        return out

    # -- the robot --

    def send_to_robot(self, action, stamp):
        """Sends the action; waits for the robot; whether it reports the action done."""
        if action["type"] == "MOVE":
            c = action["configuration"]
            pose = PoseStamped()
            pose.header.stamp, pose.header.frame_id = stamp, self.map_frame
            pose.pose.position.x, pose.pose.position.y = c["x"], c["y"]
            q = quat_from_rpy(0.0, 0.0, c["yaw"])
            (pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z,
             pose.pose.orientation.w) = q
            self.base_pub.publish(pose)
            goal = FollowJointTrajectoryGoal()
            goal.trajectory = JointTrajectory()
            goal.trajectory.header.stamp = stamp
            goal.trajectory.joint_names = list(self.joints)
            goal.trajectory.points = [JointTrajectoryPoint(
                positions=[c["lift"], c["pan"], c["tilt"]], time_from_start=rospy.Duration(1.0))]
            result = self.run_robot_action(self.trajectory, goal, "follow_joint_trajectory")
            ok = result is not None and result.error_code == 0
            if not ok:
                rospy.logwarn("npfkct: trajectory not executed: %s",
                              "no result" if result is None else result.error_string)
            return ok
        goal = ObjectCommandGoal(command=OBJECT_COMMANDS[action["type"]],
                                 object_id=action["objectId"])
        goal.header.stamp, goal.header.frame_id = stamp, self.map_frame
        box = action.get("objectBox")
        if box:
            pose = Rigid(box["center"], quat_from_rpy(0.0, 0.0, box.get("yaw", 0.0)))
            pose.to_pose(goal.bbox.center)
            goal.bbox.size.x, goal.bbox.size.y, goal.bbox.size.z = box["size"]
        result = self.run_robot_action(self.object_command, goal, "object_command")
        return result is not None and result.succeeded

    def run_robot_action(self, client, goal, name):
        """Sends a goal to one of the robot's action servers and waits for its result, polling
        for cancellation; None when the robot ended it without success."""
        if not client.wait_for_server(rospy.Duration(self.action_timeout)):
            raise GoalError(f"the robot's {name} action server did not answer")
        client.send_goal(goal)
        deadline = rospy.Time.now() + rospy.Duration(self.action_timeout)
        while not client.wait_for_result(rospy.Duration(0.1)):
            if self.server.is_preempt_requested() or rospy.is_shutdown():
                client.cancel_goal()
                raise Preempted()
            if rospy.Time.now() > deadline:
                client.cancel_goal()
                raise GoalError(f"the robot's {name} did not finish within "
                                f"{self.action_timeout:g} s")
        if client.get_state() not in (GoalStatus.SUCCEEDED, GoalStatus.ABORTED):
            return None
        return client.get_result()

    def wait_detections(self, sent):
        """The first detections stamped at or after `sent` (the action's send time)."""
        deadline = rospy.Time.now() + rospy.Duration(self.action_timeout)
        with self.cond:
            while self.detections is None or self.detections.header.stamp < sent:
                self.check_preempt()
                if rospy.Time.now() > deadline:
                    raise GoalError(f"no detections stamped after the action within "
                                    f"{self.action_timeout:g} s")
                self.cond.wait(0.1)
            return self.detections
