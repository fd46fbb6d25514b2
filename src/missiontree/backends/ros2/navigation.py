"""NavigateToPose goals as action handles: through the action client, or through /goal_pose.

:class:`ActionGoal` talks to Nav2's ``navigate_to_pose`` action server (nav2_msgs, built locally
by scripts/setup-ros2.sh): feedback, result code and message, cancel. :class:`TopicGoal` is the
fallback when nav2_msgs is absent: it publishes the goal on /goal_pose (bt_navigator turns it into
an action goal), follows it on the action's status topic and cancels it through the action's
cancel service. Both never block: every method returns at once, and a goal nobody answers is
aborted with a reason after the profile's ``server_timeout``.

Handles are advanced from two threads: the tick thread (``status()``) and the executor thread
(callbacks and the robot's 10 Hz timer), so their state sits behind a lock. Requests (send goal,
cancel) are always issued *on the executor thread* through ``in_executor``: rclpy's action and
service clients register a request only after sending it, so a response that the executor
thread takes in between is dropped ("Ignoring unexpected goal response") and the goal is lost.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalInfo, GoalStatus, GoalStatusArray
from action_msgs.srv import CancelGoal

from missiontree.backends.ros2.conversions import pose_from_msg, sec_to_time, time_to_sec
from missiontree.robot.actions import INFRASTRUCTURE, ActionResult, ActionStatus, NavFeedback
from missiontree.types import Pose2D, Tolerance

#: action_msgs/GoalStatus codes → our statuses.
_STATUS = {
    GoalStatus.STATUS_UNKNOWN: ActionStatus.PENDING,
    GoalStatus.STATUS_ACCEPTED: ActionStatus.ACCEPTED,
    GoalStatus.STATUS_EXECUTING: ActionStatus.RUNNING,
    GoalStatus.STATUS_CANCELING: ActionStatus.RUNNING,
    GoalStatus.STATUS_SUCCEEDED: ActionStatus.SUCCEEDED,
    GoalStatus.STATUS_CANCELED: ActionStatus.CANCELED,
    GoalStatus.STATUS_ABORTED: ActionStatus.ABORTED,
}

_ACTIVE = {GoalStatus.STATUS_EXECUTING, GoalStatus.STATUS_CANCELING}


class NavGoal:
    """What both kinds of goal share: the state behind a lock, ending once, a pose-based feedback.

    Args:
        goal: The goal pose in the map frame.
        server_timeout: Seconds to wait for the server before aborting.
        pose_now: Returns the robot's latest map pose (for feedback when the server sends none).
        in_executor: Runs a function on the executor thread (default: at once, for tests without one).
    """

    def __init__(self, goal: Pose2D, server_timeout: float, pose_now: Callable[[], Pose2D | None],
                 in_executor: Callable[[Callable[[], None]], Any] | None = None) -> None:
        self.goal = goal
        self._in_executor = in_executor or (lambda fn: fn())
        #: Set once a cancel request is on its way; done when the server answered it.
        self.cancel_future: Any = None
        self._cancel_scheduled = False
        self.server_timeout = server_timeout
        self._pose_now = pose_now
        self._lock = threading.RLock()
        self._status = ActionStatus.PENDING
        self._result: ActionResult | None = None
        self._feedback: NavFeedback | None = None
        self._started = time.monotonic()
        self._cancel_requested = False
        #: The caller's tolerance; the robot ends the goal early once within it (see Ros2Robot).
        self.tolerance: Tolerance | None = None

    # ---- the ActionHandle protocol
    def status(self) -> ActionStatus:
        """Current status (advances the goal first)."""
        self.advance()
        with self._lock:
            return self._status

    def feedback(self) -> NavFeedback | None:
        """Latest feedback from the server, else computed from the robot's pose."""
        with self._lock:
            if self._feedback is not None:
                return self._feedback
        pose = self._pose_now()
        if pose is None:
            return None
        return NavFeedback(pose, pose.distance_to(self.goal), time.monotonic() - self._started)

    def result(self) -> ActionResult | None:
        """How the goal ended, None while it has not."""
        self.advance()
        with self._lock:
            return self._result

    def cancel(self) -> None:
        """Ask the server to cancel; idempotent, safe after the end."""
        raise NotImplementedError

    # ---- shared machinery
    def advance(self) -> None:
        """Move the goal on (send when the server appears, time out); called often, returns at once."""

    def cancel_settled(self) -> bool:
        """True unless a cancel request is pending.

        Pending: scheduled, waiting for the server's answer, or asked for before the server's
        acceptance arrived (it goes out with the acceptance).
        """
        with self._lock:
            if not self._cancel_scheduled:
                return not self._cancel_requested or self._status.done
            return self.cancel_future is not None and self.cancel_future.done()

    @property
    def done(self) -> bool:
        """True once the goal has ended."""
        with self._lock:
            return self._status.done

    def within_tolerance(self) -> None:
        """End the goal as succeeded: the robot is within the caller's tolerance (Nav2 was cancelled)."""
        self._finish(ActionStatus.SUCCEEDED)

    def _finish(self, status: ActionStatus, reason: str = "", code: int = 0, kind: str = "") -> None:
        with self._lock:
            if self._status.done:
                return
            self._status = status
            self._result = ActionResult(status, reason, code, kind=kind)

    def _set_status(self, status: ActionStatus) -> None:
        with self._lock:
            if not self._status.done:
                self._status = status

    def _timed_out(self) -> bool:
        return time.monotonic() - self._started > self.server_timeout


class ServerWatch:
    """When a robot last saw its NavigateToPose server: across goals, not one goal's own view.

    A goal sent long after the server vanished must not wait ``server_timeout`` again from its own
    start (a tree that keeps replacing its goals, such as a servo preempting a patrol, would never
    see the loss): it aborts at once when the server, once seen, has been gone that long. A server
    never seen keeps the old rule (each goal waits ``server_timeout``: the robot may be starting).

    Args:
        client: The action client (``server_is_ready()``).
    """

    def __init__(self, client: Any) -> None:
        self._client = client
        #: Monotonic time the server was last seen ready; None until it first was.
        self.last_seen: float | None = None

    def ready(self) -> bool:
        """Whether the server is there now (remembering when it was)."""
        if self._client.server_is_ready():
            self.last_seen = time.monotonic()
            return True
        return False

    def gone_for(self) -> float:
        """Seconds since the server was last seen (0 while it never was)."""
        return 0.0 if self.last_seen is None else time.monotonic() - self.last_seen


class ActionGoal(NavGoal):
    """A goal sent through the NavigateToPose action client.

    Args:
        client: An ``rclpy.action.ActionClient`` for ``nav2_msgs/action/NavigateToPose``.
        goal_msg: The NavigateToPose.Goal to send.
        goal: The goal pose (for pose-based feedback before the server's first).
        server_timeout: Seconds to wait for the server.
        pose_now: Latest robot pose.
        action_name: Shown in reasons.
        watch: The robot's :class:`ServerWatch` (default: one of the goal's own).
    """

    def __init__(self, client: Any, goal_msg: Any, goal: Pose2D, server_timeout: float,
                 pose_now: Callable[[], Pose2D | None], action_name: str,
                 in_executor: Callable[[Callable[[], None]], Any] | None = None,
                 watch: ServerWatch | None = None) -> None:
        super().__init__(goal, server_timeout, pose_now, in_executor)
        self._client = client
        self._watch = watch or ServerWatch(client)
        self._goal_msg = goal_msg
        self._action_name = action_name
        self._sent = False
        self._goal_handle: Any = None
        self._last_seen_server = time.monotonic()

    def advance(self) -> None:
        """Send once the server is up; abort when it never appears or goes away mid-goal."""
        with self._lock:
            if self._status.done:
                return
            ready = self._watch.ready()
            now = time.monotonic()
            if ready:
                self._last_seen_server = now
            if not self._sent:
                if ready:
                    self._sent = True
                    self._in_executor(self._send)
                elif self._watch.gone_for() > self.server_timeout:
                    self._finish(ActionStatus.ABORTED,
                                 f"the NavigateToPose server on {self._action_name} went away "
                                 f"{self._watch.gone_for():.0f} s ago (more than {self.server_timeout:g} s)",
                                 kind=INFRASTRUCTURE)
                elif self._timed_out():
                    self._finish(ActionStatus.ABORTED,
                                 f"no NavigateToPose action server on {self._action_name} after "
                                 f"{self.server_timeout:g} s (is Nav2 running, in this ROS_DOMAIN_ID?)",
                                 kind=INFRASTRUCTURE)
                return
            if self._goal_handle is None and self._timed_out():
                self._finish(ActionStatus.ABORTED, f"the NavigateToPose server on {self._action_name} did "
                             f"not answer the goal within {self.server_timeout:g} s", kind=INFRASTRUCTURE)
            elif now - self._last_seen_server > self.server_timeout:
                self._finish(ActionStatus.ABORTED, f"the NavigateToPose server on {self._action_name} "
                             f"went away for more than {self.server_timeout:g} s during the goal",
                             kind=INFRASTRUCTURE)
            elif self._goal_handle is not None and self._goal_handle.status in _ACTIVE:
                self._status = ActionStatus.RUNNING

    def cancel(self) -> None:
        """Cancel the goal: at once if not yet sent, else through the action's cancel service."""
        with self._lock:
            if self._status.done or self._cancel_requested:
                return
            self._cancel_requested = True
            if not self._sent:
                self._finish(ActionStatus.CANCELED, "cancelled before it was sent")
            elif self._goal_handle is not None:
                self._schedule_cancel()

    def _send(self) -> None:
        """Send the goal (on the executor thread)."""
        future = self._client.send_goal_async(self._goal_msg, feedback_callback=self._on_feedback)
        future.add_done_callback(self._on_goal_response)

    def _schedule_cancel(self) -> None:
        self._cancel_scheduled = True
        handle = self._goal_handle

        def send() -> None:
            self.cancel_future = handle.cancel_goal_async()

        self._in_executor(send)

    def _on_goal_response(self, future: Any) -> None:
        goal_handle = future.result()
        with self._lock:
            if goal_handle is None or not goal_handle.accepted:
                self._finish(ActionStatus.REJECTED, f"the NavigateToPose server on {self._action_name} "
                             "rejected the goal")
                return
            self._goal_handle = goal_handle
            self._set_status(ActionStatus.ACCEPTED)
            if self._cancel_requested:
                self._cancel_scheduled = True
                self.cancel_future = goal_handle.cancel_goal_async()  # already on the executor thread
        goal_handle.get_result_async().add_done_callback(self._on_result)

    def _on_feedback(self, message: Any) -> None:
        fb = message.feedback
        feedback = NavFeedback(pose_from_msg(fb.current_pose.pose), float(fb.distance_remaining),
                               time_to_sec(fb.navigation_time), int(fb.number_of_recoveries))
        with self._lock:
            self._feedback = feedback
            self._set_status(ActionStatus.RUNNING)

    def _on_result(self, future: Any) -> None:
        wrapped = future.result()
        if wrapped is None:
            self._finish(ActionStatus.ABORTED, "the result of the goal was lost", kind=INFRASTRUCTURE)
            return
        status = _STATUS.get(wrapped.status, ActionStatus.ABORTED)
        code, message = int(wrapped.result.error_code), str(wrapped.result.error_msg)
        if status is ActionStatus.SUCCEEDED:
            self._finish(status, "", code)
        elif status is ActionStatus.CANCELED:
            self._finish(status, message or "cancelled", code)
        else:
            self._finish(ActionStatus.ABORTED, message or f"Nav2 aborted the goal (error code {code})", code)


class TopicGoal(NavGoal):
    """A goal published on /goal_pose and followed on the NavigateToPose action's status topic.

    Args:
        publish_goal: Publishes the goal pose; called once the topic has a subscriber.
        has_subscriber: True when /goal_pose has a subscriber (bt_navigator).
        cancel_client: An rclpy client for ``action_msgs/srv/CancelGoal`` on the action's cancel service.
        goal: The goal pose.
        server_timeout: Seconds to wait for a subscriber and for the goal to show on the status topic.
        pose_now: Latest robot pose (feedback comes from it: the feedback topic needs nav2_msgs).
        now: ROS time in seconds (goal stamps are compared with it).
        topic: /goal_pose's resolved name, shown in reasons.
        known_goals: Ids of the goals on the status topic before this one was sent (never ours).
    """

    def __init__(self, publish_goal: Callable[[], None], has_subscriber: Callable[[], bool],
                 cancel_client: Any, goal: Pose2D, server_timeout: float,
                 pose_now: Callable[[], Pose2D | None], now: Callable[[], float], topic: str,
                 known_goals: set[bytes] | None = None,
                 in_executor: Callable[[Callable[[], None]], Any] | None = None) -> None:
        super().__init__(goal, server_timeout, pose_now, in_executor)
        self._publish_goal = publish_goal
        self._has_subscriber = has_subscriber
        self._cancel_client = cancel_client
        self._now = now
        self._topic = topic
        self._sent_at: float | None = None
        self._known_before: set[bytes] = set(known_goals or ())
        self._goal_id: bytes | None = None

    def advance(self) -> None:
        """Publish once /goal_pose has a subscriber; abort when nobody answers in time."""
        with self._lock:
            if self._status.done or self._sent_at is not None:
                if not self._status.done and self._goal_id is None and self._timed_out():
                    self._finish(ActionStatus.ABORTED, f"the goal sent on {self._topic} never showed on the "
                                 f"NavigateToPose status topic within {self.server_timeout:g} s",
                                 kind=INFRASTRUCTURE)
                return
            if self._has_subscriber():
                self._sent_at = self._now()
                self._started = time.monotonic()
                self._publish_goal()
            elif self._timed_out():
                self._finish(ActionStatus.ABORTED, f"nobody subscribes to {self._topic} after "
                             f"{self.server_timeout:g} s (is Nav2's bt_navigator running?)",
                             kind=INFRASTRUCTURE)

    def on_status(self, msg: GoalStatusArray) -> None:
        """Follow our goal in a status message of the NavigateToPose action."""
        with self._lock:
            if self._status.done:
                return
            entries = {bytes(s.goal_info.goal_id.uuid): s for s in msg.status_list}
            if self._sent_at is None:
                self._known_before |= set(entries)
                return
            if self._goal_id is None:
                earliest = self._sent_at - 0.5  # the server stamps acceptance; allow for clock skew
                fresh = [(time_to_sec(s.goal_info.stamp), gid) for gid, s in entries.items()
                         if gid not in self._known_before and time_to_sec(s.goal_info.stamp) >= earliest]
                if not fresh:
                    return
                self._goal_id = max(fresh)[1]
                if self._cancel_requested:
                    self._send_cancel()
            entry = entries.get(self._goal_id)
            if entry is None:
                return
            status = _STATUS.get(entry.status, ActionStatus.PENDING)
            if status is ActionStatus.SUCCEEDED:
                self._finish(status)
            elif status is ActionStatus.CANCELED:
                self._finish(status, "cancelled")
            elif status is ActionStatus.ABORTED:
                self._finish(status, "Nav2 aborted the goal (its reason travels only in the action's result: "
                                     "install nav2_msgs with scripts/setup-ros2.sh to see it)")
            else:
                self._set_status(status)

    def cancel(self) -> None:
        """Cancel through the action's cancel service (at once if the goal was not yet published)."""
        with self._lock:
            if self._status.done or self._cancel_requested:
                return
            self._cancel_requested = True
            if self._sent_at is None:
                self._finish(ActionStatus.CANCELED, "cancelled before it was sent")
            elif self._goal_id is not None:
                self._send_cancel()
            else:
                # Not yet seen on the status topic: cancel every goal Nav2 accepted since we sent ours.
                self._send_cancel(since=self._sent_at)

    def preempted(self) -> None:
        """Mark the goal as ended because a newer goal replaced it (Nav2 preempts on /goal_pose)."""
        self._finish(ActionStatus.CANCELED, "preempted by a newer goal")

    def _send_cancel(self, since: float | None = None) -> None:
        request = CancelGoal.Request()
        info = GoalInfo()
        if since is None and self._goal_id is not None:
            info.goal_id.uuid = list(self._goal_id)
        else:
            # Zero id with a stamp: cancel every goal accepted at or before the stamp (action_msgs rules),
            # so use a stamp slightly in the future to include ours.
            info.goal_id.uuid = list(uuid.UUID(int=0).bytes)
            info.stamp = sec_to_time(self._now() + 1.0)
        request.goal_info = info
        if self._cancel_client.service_is_ready():
            self._cancel_scheduled = True

            def send() -> None:
                self.cancel_future = self._cancel_client.call_async(request)

            self._in_executor(send)
