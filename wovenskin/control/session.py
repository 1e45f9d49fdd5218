"""A robot control session: skin -> recogniser -> active command -> safe robot motion.

:class:`ControlSession` owns the control loop.  Each :class:`~wovenskin.signal.live_skin.LiveSkin`
block goes through the recognition :class:`~wovenskin.recognition.pipeline.LivePipeline`
once; then the loop ticks once per frame of the block, at the frame's time on the skin
clock (200 Hz for the default skin): the command active at that time is mapped
(:class:`~wovenskin.control.mapping.ActionMapping`) to a target twist, shaped by
:class:`~wovenskin.control.motion.TwistShaper` and sent through
:class:`~wovenskin.control.safety.SafetyLayer`, and a simulated robot is advanced to the
tick's time -- so a replay runs faster than real time and gives the same motion every
time.  A simulated robot follows the session clock, not only the frames: while no frames
arrive it is stepped to the session clock too (a stalled live skin), so it stops with the
watchdog and reports its true state; the trace gets a line per idle step during a stall.
One robot step covers at most ``SessionSettings.max_robot_step_s`` (a jump in the skin's
timestamps is cut, with a message).  Pose actions start a joint move to the stored pose
(:class:`PoseStore`) and, when hold-to-run, stop as soon as the command ends.  Inputs beside
the skin (keyboard, pendant: :mod:`~wovenskin.control.session_inputs`) are polled every tick
and take the same path; the session counts and logs every command.

Safety: every skin frame is a skin heartbeat and every tick a command heartbeat; the
layer's watchdogs run on the session clock, which is the skin clock while frames arrive and
advances with the wall clock while they do not, so a gap in a replayed stream and a stalled
live skin both stop the robot.  :meth:`ControlSession.emergency_stop` (the stop key) latches
until :meth:`ControlSession.resume`; watchdog stops clear once the skin streams again and no
command is active.  Bad blocks and robot errors are one line and never move the robot.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from wovenskin.control.gesture_motion import GestureMotion
from wovenskin.control.mapping import ActionMapping, PoseAction, TwistAction
from wovenskin.control.motion import TwistShaper
from wovenskin.control.poses import PoseStore
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.control.session_inputs import CommandInput, JointJog, SessionInputs
from wovenskin.control.session_poses import PoseMove, PoseMoves
from wovenskin.control.session_record import SessionRecording
from wovenskin.control.session_state import (
    SessionResult,
    SessionSettings,
    SessionState,
)
from wovenskin.control.session_views import SessionViews
from wovenskin.control.trace import TraceWriter
from wovenskin.errors import ConfigError
from wovenskin.recognition.arbiter import LIFT_OFF
from wovenskin.robots.base import Robot, RobotError

log = logging.getLogger(__name__)


class ControlSession(PoseMoves, SessionRecording, SessionInputs, SessionViews):
    """The control loop of one session (see the module docstring).

    Pose moves (:class:`~wovenskin.control.session_poses.PoseMoves`), the recording
    (:class:`~wovenskin.control.session_record.SessionRecording`), the inputs beside the
    skin and the command count (:class:`~wovenskin.control.session_inputs.SessionInputs`)
    and what views ask (:class:`~wovenskin.control.session_views.SessionViews`) are in
    their own modules; ``inputs`` are polled every tick (:meth:`add_input` adds more).
    ``live_skin`` and ``pipeline`` come from
    :func:`~wovenskin.runtime.session.open_session` or are built by the
    caller (``LivePipeline.for_live_skin``); ``robot`` is the raw backend, which the
    session wraps in its own :class:`SafetyLayer`.  ``trace`` gets a line per tick;
    ``recorder`` (the :class:`~wovenskin.recording.native.RecordingWriter` also given to
    the ``LiveSkin``) gets predictions, commands, robot state, stops and errors as
    annotations.  ``on_tick(session)`` runs after every tick (frames: ``tick_block``).
    """

    def __init__(
        self,
        live_skin: Any,
        pipeline: Any,
        robot: Robot,
        mapping: ActionMapping | None = None,
        *,
        limits: SafetyLimits | None = None,
        poses: PoseStore | None = None,
        settings: SessionSettings | None = None,
        trace: TraceWriter | None = None,
        recorder: Any = None,
        on_message: Callable[[str], None] | None = None,
        on_tick: Callable[[ControlSession], None] | None = None,
        wall_clock: Callable[[], float] = time.monotonic,
        inputs: Iterable[CommandInput] = (),
    ) -> None:
        self.live_skin = live_skin
        self.pipeline = pipeline
        self.robot = robot
        self.mapping = mapping if mapping is not None else ActionMapping.load()
        self.settings = settings or SessionSettings()
        self.poses = poses
        self.safety = SafetyLayer(robot, limits, clock=self._clock)
        robot.use_mapping_frame(self.mapping.settings.frame)
        self.shaper = TwistShaper(self.mapping.settings, self.safety.capabilities().release_stop_s)
        self.gesture_motion = GestureMotion(self.mapping)
        self.trace = trace
        self.recorder = recorder
        self._on_message = on_message or (lambda _message: None)
        self._on_tick = on_tick
        self._wall = wall_clock
        self.state = SessionState(class_names=tuple(getattr(pipeline, "class_names", ())))
        self._now = 0.0
        self._last_t: float | None = None  # stream time of the newest frame seen
        self._last_wall: float | None = None  # wall time when it arrived
        self._last_seq = -1
        self._tick_t: float | None = None
        self._robot_t: float | None = None  # session time a simulated robot has reached
        self._traced_t: float | None = None  # time of the newest trace line
        self._pose_move: PoseMove | None = None
        self._pose_tried: float | None = None  # gesture_since of the last pose command
        self._stops_seen = 0
        self._user_stop = False  # the stop key latches until resume()
        self._commands = 0
        self._error_times: dict[str, float] = {}
        self._quit = ""
        self._quit_asked = False  # request_quit() since the last run() ended
        self._held_over: tuple[np.ndarray, deque] | None = None  # frames past a run's end
        self._started_wall: float | None = None
        self._first_t: float | None = None
        self._seconds: float | None = None
        self._end_t: float | None = None  # session time at which run() ends
        self._simulated = type(robot).step is not Robot.step
        self.speed_scale = 1.0  # set_speed_scale: fraction of the mapping's speeds
        self.recording_context: dict[str, Any] = {}  # what start_recording writes as settings
        self.last_block_compute_s = 0.0  # recogniser + control + robot for the last block
        self.tick_block: Any = None  # the LiveBlock whose frames are being ticked
        self._steps_through_safety = type(self.safety).step is not Robot.step
        self._init_inputs(inputs)

    # -- the session clock

    def _clock(self) -> float:
        return self._now

    @property
    def now(self) -> float:
        """The session clock: skin time, advanced by the wall clock while no frames arrive."""
        return self._now

    @property
    def user_stopped(self) -> bool:
        """Whether the stop key (:meth:`emergency_stop`) holds the robot."""
        return self._user_stop

    # -- lifecycle

    def start(self) -> None:
        """Connect the robot (``RobotError`` if it is not there) and start the skin."""
        self.safety.connect()
        for check in self.safety.capabilities().left_to_controller:
            self._message(f"robot {self.robot.name}: left to the arm's controller: {check}")
        self._started_wall = self._wall()
        try:
            self.state.robot = self.safety.state()
        except RobotError as exc:
            self._error(f"robot: {exc}")
        self.live_skin.start()

    def close(self) -> None:
        """Stop the robot, disconnect it and close the skin, trace and recorder."""
        try:
            self.safety.stop()
        except RobotError as exc:
            self._error(f"robot: {exc}")
        finally:
            try:
                self.safety.disconnect()
            finally:
                self.live_skin.close()
                if self.trace is not None:
                    self.trace.close()
                if self.recorder is not None:
                    self.recorder.close()

    def request_quit(self, reason: str = "quit by the user") -> None:
        """End :meth:`run` after the current step (or the next run, if none is running)."""
        self._quit = reason
        self._quit_asked = True

    def emergency_stop(self, reason: str = "stop key") -> None:
        """Stop everything now; motion resumes only after :meth:`resume`."""
        self._user_stop = True
        self._pose_move = None
        self.shaper.reset()
        self.gesture_motion.cancel()
        self.safety.emergency_stop(reason)
        self._report_new_stops()

    def resume(self) -> None:
        """Clear a stop; the robot moves again only on a new command."""
        self._user_stop = False
        self.safety.clear_stop()
        self.shaper.reset()
        self.state.stopped = self.safety.stopped
        self._message("stop cleared: the robot moves again on the next command")

    def set_speed_scale(self, scale: float) -> None:
        """Scale twists, steps and pose moves by ``scale`` (0.01-1, a pendant's 1-100 %
        override); the caps still hold."""
        scale = float(scale)
        if not np.isfinite(scale) or not 0.01 <= scale <= 1.0:
            raise ConfigError(f"speed scale must be between 0.01 and 1, got {scale}")
        self.speed_scale = scale
        self._message(f"speed scaled to {scale:.0%}")

    # -- the loop

    def run(
        self,
        seconds: float | None = None,
        should_continue: Callable[[], bool] | None = None,
    ) -> SessionResult:
        """Step until the skin ends, :meth:`request_quit`, ``seconds`` of session time
        pass, or ``should_continue()`` returns False; returns the session's figures.
        It may be called again: the next run goes on from where this one ended (the
        frames of its last block that lay past its end come first)."""
        if self._started_wall is None:
            self.start()
        if not self._quit_asked:
            self._quit = ""  # the previous run's own end, not a request to quit
        self._seconds = seconds
        self._end_t = None
        if seconds is not None and self._first_t is not None:
            self._end_t = self._now + seconds
        if self._held_over is not None and not self._quit:
            times, pending = self._held_over
            self._held_over = None
            self._tick_frames(times, pending)
        try:
            return self._run_loop(should_continue)
        finally:
            self._quit_asked = False

    def _run_loop(self, should_continue: Callable[[], bool] | None) -> SessionResult:
        seconds = self._seconds
        while True:
            if self._quit:
                break
            self.step()
            if self._quit:
                break
            if self.state.ended:
                self._quit = "the skin stream ended"
                break
            if self._end_t is not None and self._now >= self._end_t:
                self._quit = f"{seconds:g} s elapsed"
                break
            if should_continue is not None and not should_continue():
                self._quit = self._quit or "stopped by the caller"
                break
        return self.result()

    def result(self) -> SessionResult:
        stream_s = 0.0 if self._first_t is None else self._now - self._first_t
        wall_s = 0.0 if self._started_wall is None else self._wall() - self._started_wall
        return SessionResult(
            self.state.ticks,
            stream_s,
            wall_s,
            self._commands,
            list(self.safety.stops),
            self.state.errors,
            self._quit or "running",
        )

    def step(self, timeout: float | None = None) -> int:
        """One skin poll and the ticks of the frames it brought; returns the tick count."""
        timeout = self.settings.idle_timeout_s if timeout is None else timeout
        block = self.live_skin.step(timeout=timeout)
        polled = time.perf_counter()
        skin = self.live_skin.state
        self.state.ended = bool(skin.ended)
        arrived = skin.seq != self._last_seq and skin.seq >= 0  # also while calibrating
        if arrived:
            self._last_seq = skin.seq
            self._frames_arrived(float(skin.t))
        if block is None or len(block.t) == 0:
            if arrived:  # frames but no conditioned output (calibrating): the skin is alive
                self._now = max(self._now, float(skin.t))
                self._check_watchdogs(float(skin.t))
                self.safety.heartbeat_skin(float(skin.t))
            else:
                self._idle()
            return 0
        ticks = self._on_block(block)
        self.last_block_compute_s = time.perf_counter() - polled
        return ticks

    def _frames_arrived(self, t: float) -> None:
        if self._first_t is None:  # the first poll may bring many frames: its first one
            frames = max(1, self.live_skin.stats().good_frames)
            self._first_t = t - (frames - 1) / self.live_skin.info.sample_rate_hz
            if self._seconds is not None:
                self._end_t = self._first_t + self._seconds
        self._last_t = t
        self._last_wall = self._wall()

    def _idle(self) -> None:
        """No conditioned frames: let the watchdogs see the time that passes."""
        if self._last_t is None or self._last_wall is None:
            return
        if not self.settings.wall_clock_stalls:
            return
        self._now = max(self._now, self._last_t + (self._wall() - self._last_wall))
        self._check_watchdogs(self._now)
        if not self._simulated:
            return
        self._advance_robot(self._now)
        self._read_robot()
        stalled = self._now - self._last_t > self.safety.limits.watchdog_s
        if stalled and self.state.robot is not None:
            self._trace(self._now)

    def _advance_robot(self, t: float) -> None:
        """Step a simulated robot from the time it has reached to ``t`` (never backwards,
        at most ``max_robot_step_s`` at once: a longer gap is cut and reported)."""
        if not self._simulated:
            return
        if self._robot_t is None:
            self._robot_t = t
            return
        dt = t - self._robot_t
        if not dt > 0.0:
            return
        self._robot_t = t
        cap = self.settings.max_robot_step_s
        if dt > cap:
            text = f"skin time jumped by {dt:.3g} s: the simulated arm is stepped {cap:g} s"
            log.warning("%s", text)
            self._message(f"{t:8.2f} s  {text} (capped)")
            dt = cap
        try:
            if self._steps_through_safety:
                self.safety.step(dt)
            else:
                self.robot.step(dt)
        except RobotError as exc:
            self._robot_failed(exc)

    def _on_block(self, block: Any) -> int:
        times = np.asarray(block.t, dtype=np.float64).reshape(-1)
        try:
            changes = list(self.pipeline.feed(block))
        except ValueError as exc:  # the command ends: no motion on frames we cannot trust
            self._error(f"skin frames dropped: {exc}")  # one line however many frames
            ended = self.pipeline.reset(float(times[0]))
            changes = [] if ended is None else [ended]
        self._record_predictions(float(times[-1]))
        self.tick_block = block
        self._tick_frames(times, deque(sorted(changes, key=lambda c: c.t)))
        return len(times)

    def _tick_frames(self, times: np.ndarray, pending: deque) -> None:
        """Tick the frames at ``times``, applying the recogniser's ``pending`` changes as
        their times come; frames past the run's end are held over for the next run."""
        for i, t in enumerate(times):
            if self._end_t is not None and t > self._end_t:
                self._quit = f"{self._seconds:g} s elapsed"
                self._held_over = (times[i:], pending)
                return
            while pending and pending[0].t <= t:
                self._apply_change(pending.popleft())
            self._tick(float(t))
        while pending:  # changes stamped after the block's last frame (none expected)
            self._apply_change(pending.popleft())

    def _apply_change(self, change: Any) -> None:
        self._commands += 1
        if change.gesture is not None:  # an activation is a command; its end is none
            self.count_command(float(change.t), "skin", change.gesture, "gesture")
        self.state.gesture = change.gesture
        self.state.gesture_since = float(change.t)
        if change.gesture is not None:
            action = self.mapping.action_for(change.gesture)
            self.gesture_motion.started(action, self.gesture_frame, float(change.t))
        else:
            self.gesture_motion.ended(float(change.t), lifted=change.reason == LIFT_OFF)
        name = change.gesture or "none"
        self._message(f"{change.t:8.2f} s  command {name} ({change.reason})")
        if self.recorder is not None:
            payload = {"gesture": change.gesture, "reason": change.reason}
            self.recorder.add_annotation("commands", float(change.t), payload)

    # -- one tick

    def _tick(self, t: float) -> None:
        dt = 0.0 if self._tick_t is None else max(0.0, t - self._tick_t)
        self._tick_t = t
        self._now = max(self._now, t)
        self._check_watchdogs(t)  # before the heartbeat: a gap in the stream is a stall
        self.safety.heartbeat_skin(t)
        self._clear_recovered_stops()
        self._poll_inputs(t)
        self._control(t, dt)
        self._advance_robot(t)
        self._read_robot()
        self.state.t = t
        self.state.ticks += 1
        self.state.stopped = self.safety.stopped
        if self.state.robot is not None:
            self._trace(t)
        if self._on_tick is not None:
            self._on_tick(self)

    def _trace(self, t: float) -> None:
        """The trace line and recorded robot state at ``t`` (never out of order)."""
        if self._traced_t is not None and t <= self._traced_t:
            return
        self._traced_t = t
        if self.trace is not None:
            self.trace.write(t, self.state.gesture, self.state.robot)
        if self.recorder is not None:
            self._record_robot(t)

    def _control(self, t: float, dt: float) -> None:
        label, action, frame, since = self._active_command()
        if self.safety.stopped:
            self._pose_move = None
            self.shaper.reset()
            self.gesture_motion.cancel()
            self.state.twist = np.zeros(6)
            self.state.action = "stopped"
            return
        if self._pose_move is not None and not self._continue_pose_move(action):
            self._pose_move = None
        if self._pose_move is not None:
            self.safety.heartbeat_command(t)
            return
        if isinstance(action, PoseAction):
            if self._pose_tried != since:  # once per command
                self._pose_tried = since
                if self._start_pose_move(action, t):
                    self.safety.heartbeat_command(t)
                    return
            action = None  # reached, or the move could not start: hold still
        skin = label is not None and label == self.state.gesture
        if label is not None and not skin:
            self.gesture_motion.cancel()  # another input took over
        moves = isinstance(action, TwistAction | JointJog)
        self._send_twist(label if moves else None, action, frame, t, dt, skin)

    def _send_twist(
        self,
        label: str | None,
        action: Any,
        frame: str | None,
        t: float,
        dt: float,
        skin: bool = False,
    ) -> None:
        robot = self.state.robot
        target = np.zeros(6)
        doing = f"twist {label}" if label is not None else "-"
        if label is not None and robot is not None:
            target = self._target_twist(action, frame, robot) * self.speed_scale
            if skin:  # the gestures' speed profile (control/profile.py)
                target = target * self.gesture_motion.speed_fraction(t)
        elif robot is not None and self.gesture_motion.nudging:
            s = self.mapping.settings
            nudge = self.gesture_motion.nudge_target(
                t, robot.tcp, self.shaper.twist, self.shaper.release_stop_s,
                (s.linear_accel, s.angular_accel),
            )  # fmt: skip
            if nudge is not None:
                target = nudge * self.speed_scale
                doing = "nudge"
        step = min(dt, self.settings.max_shaper_dt_s)
        twist = self.shaper.update(target, step)
        self.gesture_motion.add_way(twist, step)
        self.state.action = doing
        try:
            self.safety.send_twist(twist)
        except (RobotError, ValueError) as exc:
            self._robot_failed(exc)
            return
        self.state.twist = np.asarray(twist, dtype=float)
        self.safety.heartbeat_command(t)

    def _robot_failed(self, exc: Exception) -> None:
        self._error(f"robot: {exc}")
        self._pose_move = None
        self.shaper.reset()
        self.state.twist = np.zeros(6)
        try:
            self.safety.stop()
        except RobotError as again:
            self._error(f"robot: stop failed: {again}")

    def _read_robot(self) -> None:
        try:
            self.state.robot = self.safety.state()
        except RobotError as exc:
            self._error(f"robot: {exc}")

    # -- safety bookkeeping

    def _check_watchdogs(self, now: float) -> None:
        try:
            self.safety.check(now)
        except RobotError as exc:
            self._error(f"robot: {exc}")
        self._report_new_stops()

    def _report_new_stops(self) -> None:
        stops = self.safety.stops
        for stop in stops[self._stops_seen :]:
            self.state.stops.append(stop)
            self._message(f"{stop.t:8.2f} s  STOP ({stop.source}): {stop.reason}")
            if self.recorder is not None:
                payload = {"reason": stop.reason, "source": stop.source}
                self.recorder.add_annotation("stops", float(stop.t), payload)
        self._stops_seen = len(stops)
        self.state.stopped = self.safety.stopped

    def _clear_recovered_stops(self) -> None:
        """A watchdog stop ends once frames flow again and no command is active."""
        active = self.state.gesture is not None or self._held is not None
        if self._user_stop or not self.safety.stopped or active:
            return
        last = self.safety.stops[-1] if self.safety.stops else None
        self.safety.clear_stop()
        self.shaper.reset()
        why = f" ({last.reason})" if last is not None else ""
        self._message(f"{self._now:8.2f} s  recovered from the stop{why}")

    # -- reporting

    def _message(self, text: str) -> None:
        self.state.messages.append(text)
        self._on_message(text)

    def _error(self, text: str) -> None:
        line = " ".join(str(text).split())
        self.state.errors += 1
        self.state.last_error = line
        now = self._wall()
        if now - self._error_times.get(line, -np.inf) >= self.settings.error_repeat_s:
            self._error_times[line] = now
            self._message(f"error: {line}")
        if self.recorder is not None:
            self.recorder.add_annotation("errors", self._now, {"message": line})
