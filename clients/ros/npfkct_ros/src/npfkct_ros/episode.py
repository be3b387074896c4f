"""One object-search episode against an npfkct server, without ROS: the session's life (create,
plan, observe, delete), HTTP retries with recovery of a retried plan or observation, and the step
loop. A robot front (the ROS 1 node, find_object.py; a ROS 2 node) supplies a Robot: how to send
an action, what was observed after it, the time, and whether to stop."""

import math

from npfkct_client import ApiError

from npfkct_ros import retry


class GoalError(Exception):
    """Ends a goal as aborted, with this message in the result."""


class Preempted(Exception):
    """The goal was cancelled (or replaced) or the node is shutting down."""


def angle_diff(a, b):
    """a - b wrapped into (-pi, pi]."""
    return math.atan2(math.sin(a - b), math.cos(a - b))


def reached(asked, state, base_tolerance, yaw_tolerance):
    """Whether the base of robot state `state` is within the tolerances of the MOVE
    configuration `asked` (lift and head are the trajectory's to report)."""
    return (math.hypot(state["x"] - asked["x"], state["y"] - asked["y"]) <= base_tolerance
            and abs(angle_diff(state["yaw"], asked["yaw"])) <= yaw_tolerance)


class Robot:
    """What an episode needs of the robot's side. Every method may raise GoalError (the goal
    aborts) or Preempted (it was cancelled). A MOVE counts as executed when the robot says so and
    its observed base is within base_tolerance (m) and yaw_tolerance (rad) of the goal."""

    base_tolerance = 0.05
    yaw_tolerance = 0.05

    def now(self):
        """The robot's clock (a stamp the robot's observations are compared with)."""
        raise NotImplementedError

    def execute(self, action, sent):
        """Carries out `action` (the API's action JSON), sent at `sent`; whether the robot
        reports it done."""
        raise NotImplementedError

    def observe(self, sent):
        """What the robot saw after the action sent at `sent`: (robotState, detections), the
        API's fields, the robot's state paired with the detections' stamp."""
        raise NotImplementedError

    def preempted(self):
        """Whether the goal was cancelled or the node is going down."""
        return False

    def sleep(self, seconds):
        """Waits between retries (ending early when the node shuts down)."""
        raise NotImplementedError

    def log(self, level, message):
        """level: "info", "warn" or "error"."""


class Episode:
    """A session on `client` (NpfkctClient) for one goal. `policy` (retry.RetryPolicy) governs the
    HTTP retries; `robot` (Robot) acts and sees."""

    def __init__(self, client, policy, robot):
        self.client = client
        self.policy = policy
        self.robot = robot
        self.session_id = None

    def http(self, fn):
        """fn() with retries and backoff; stops retrying when the goal is cancelled."""
        value, _ = retry.call(fn, self.policy, sleep=self.robot.sleep,
                              log=lambda m: self.robot.log("warn", m),
                              stop=self.robot.preempted)
        return value

    def create(self, world, **kwargs):
        """Creates the session (NpfkctClient.create_session's arguments)."""
        session = self.http(lambda: self.client.create_session(world, **kwargs))
        self.session_id = session.id
        return session

    def plan(self, budget_ms):
        """(actionId, action JSON, expected value). A retried :plan whose first try reached the
        server finds the action pending (FAILED_PRECONDITION): it is taken from the session."""
        tries = [0]

        def once():
            tries[0] += 1
            return self.client.plan(self.session_id, time_ms=budget_ms)

        try:
            plan = self.http(once)
        except ApiError as e:
            if e.status != "FAILED_PRECONDITION" or tries[0] < 2:
                raise
            pending = self.http(lambda: self.client.get_session(self.session_id)).raw.get(
                "pendingAction")
            if not pending:
                raise
            self.robot.log("warn", f"a retried plan found action {pending['actionId']} "
                           "pending; executing it")
            return pending["actionId"], pending["action"], float("nan")
        return plan.action_id, plan.action.to_json(), plan.expected_value

    def observe(self, action_id, body):
        """(done, reward, session). A retried :observe whose first try reached the server is
        refused (FAILED_PRECONDITION): the session then shows the step taken; its reward is lost
        and counted as 0."""
        tries = [0]

        def once():
            tries[0] += 1
            return self.client.observe(self.session_id, action_id, body=body)

        try:
            observed = self.http(once)
        except ApiError as e:
            if e.status != "FAILED_PRECONDITION" or tries[0] < 2:
                raise
            session = self.http(lambda: self.client.get_session(self.session_id))
            if session.pending_action_id == action_id:
                raise
            self.robot.log("warn", "a retried observe had reached the server; reward unknown")
            return session.state == "DONE", 0.0, session
        return observed.done, observed.reward, observed.session

    def delete(self, why):
        """Deletes the session (one try: a shutting-down node cannot wait long)."""
        session_id, self.session_id = self.session_id, None
        if session_id is None:
            return
        try:
            self.client.delete_session(session_id)
            self.robot.log("info", f"{why}: session {session_id} deleted")
        except (ApiError, OSError) as e:
            self.robot.log("error", f"{why}: deleting session {session_id} failed: {e}")

    def run(self, budget_ms, max_steps, on_step=None, on_change=None):
        """Plan, execute, observe until the target is removed or `max_steps` steps: (success,
        the session's steps, the summed reward, a message). on_step(step, action_id, action,
        value, succeeded, body, reward, done, session) hears each step; on_change(session_id)
        each plan and each observation (the belief changed)."""
        step, total, steps = 0, 0.0, 0
        while step < max_steps:
            if self.robot.preempted():
                raise Preempted()
            action_id, action, value = self.plan(budget_ms)
            if on_change:
                on_change(self.session_id)
            sent = self.robot.now()
            succeeded = self.robot.execute(action, sent)
            state, detections = self.robot.observe(sent)
            if action["type"] == "MOVE" and succeeded:
                asked = action["configuration"]
                succeeded = reached(asked, state, self.robot.base_tolerance,
                                    self.robot.yaw_tolerance)
                if not succeeded:
                    self.robot.log("warn", "base at ({x:.3f}, {y:.3f}, {yaw:.3f}), asked "
                                   "({ax:.3f}, {ay:.3f}, {ayaw:.3f})".format(
                                       ax=asked["x"], ay=asked["y"], ayaw=asked["yaw"], **state))
            body = {"succeeded": succeeded, "robotState": state, "detections": detections}
            done, reward, session = self.observe(action_id, body)
            if on_change:
                on_change(self.session_id)
            step += 1
            total += reward
            steps = session.step
            if on_step:
                on_step(step, action_id, action, value, succeeded, body, reward, done, session)
            if done:
                return True, steps, total, f"target removed after {step} steps"
        return False, steps, total, f"target not removed within {max_steps} steps"
