"""A robot control session: skin -> recogniser -> active command -> safe robot motion.

:class:`ControlSession` owns the control loop and composes its parts, each an object of
its own: the safety layer (:class:`~wovenskin.control.safety.SafetyLayer`), the inputs
beside the skin (:class:`~wovenskin.control.session_inputs.Inputs`), the pose moves
(:class:`~wovenskin.control.session_poses.PoseMover`), the recording
(:class:`~wovenskin.control.session_record.SessionRecorder`) and the messages
(:class:`~wovenskin.control.session_state.Reporter`).  The way from a gesture to the robot
reads top to bottom in :meth:`ControlSession._tick` and :class:`~wovenskin.control.drive.Drive`
(the path the mapping's speeds take to the robot).  Each ``LiveSkin``
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
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.control.delegated import Delegated
from wovenskin.control.drive import Drive
from wovenskin.control.mapping import ActionMapping, PoseAction
from wovenskin.control.poses import PoseStore
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.control.session_inputs import (
    CommandInput,
    InputEvent,
    Inputs,
    active_command,
    resolve_input,
    step_goal,
)
from wovenskin.control.session_loop import SkinLoop
from wovenskin.control.session_poses import PoseMover
from wovenskin.control.session_record import SessionRecorder, robot_payload
from wovenskin.control.session_state import (
    Reporter,
    SessionResult,
    SessionSettings,
    SessionState,
    min_probability_of,
    update_predictions,
)
from wovenskin.control.session_views import holding
from wovenskin.control.trace import TraceWriter
from wovenskin.errors import ConfigError
from wovenskin.recognition.arbiter import LIFT_OFF
from wovenskin.robots.base import Robot, RobotError

log = logging.getLogger(__name__)


class ControlSession:
    """The control loop of one session (see the module docstring).

    ``live_skin`` and ``pipeline`` come from :func:`~wovenskin.runtime.session.open_session`
    or are built by the caller (``LivePipeline.for_live_skin``); ``robot`` is the raw
    backend, which the session wraps in its own :class:`SafetyLayer`.  ``trace`` gets a
    line per tick; ``recorder`` (the :class:`~wovenskin.recording.native.RecordingWriter`
    also given to the ``LiveSkin``) gets predictions, commands, robot state, stops and
    errors as annotations.  ``inputs`` are polled every tick (:meth:`add_input` adds
    more).  ``on_tick(session)`` runs after every tick (frames: ``tick_block``).
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
        self.state = SessionState(class_names=tuple(getattr(pipeline, "class_names", ())))
        self._wall = wall_clock
        # the parts, each with what it needs and no more
        self.safety = SafetyLayer(robot, limits, clock=self._clock)
        robot.use_mapping_frame(self.mapping.settings.frame)
        self.record = SessionRecorder(live_skin, recorder, self._say)
        self.report = Reporter(
            self.state, on_message or (lambda _message: None), wall_clock,
            self.settings.error_repeat_s, self.record.note, self._clock,
        )  # fmt: skip
        self.inputs = Inputs(inputs)
        self.pose_mover = PoseMover(self.safety, poses, self._say, self._error)
        self.drive = Drive(
            self.mapping, self.safety, self.pose_mover, self.state, self.settings, self.report
        )
        self.loop = SkinLoop(
            live_skin, pipeline, self.settings, self.state, wall_clock,
            tick=self._tick, change=self._apply_change, predictions=self._note_predictions,
            alive=self._skin_alive, idle=self._idle, error=self._error,
            watchdog_s=self.safety.limits.watchdog_s,
        )  # fmt: skip
        self.trace = trace
        self._on_tick = on_tick
        self._tick_t: float | None = None
        self._traced_t: float | None = None  # time of the newest trace line
        self._stops_seen = 0
        self._user_stop = False  # the stop key latches until resume()
        self._commands = 0

    # -- what callers read and set: the parts' own attributes under the session's names

    shaper = Delegated("drive", "shaper")
    gesture_motion = Delegated("drive", "gesture_motion")
    speed_scale = Delegated("drive", "speed_scale", settable=True)  # of the mapping's speeds
    poses = Delegated("pose_mover", "poses")
    recorder = Delegated("record", "writer", settable=True)  # the writer while one runs
    recording = Delegated("record", "active")
    recording_context = Delegated("record", "context", settable=True)  # open_session's
    command_log = Delegated("inputs", "command_log")
    held_input = Delegated("inputs", "held_label")
    gripper_closed = Delegated("inputs", "gripper_closed")
    gesture_frame = Delegated("inputs", "gesture_frame", settable=True)
    on_gripper = Delegated("inputs", "on_gripper", settable=True)

    tick_block = Delegated("loop", "tick_block")  # the LiveBlock whose frames are ticked
    last_block_compute_s = Delegated("loop", "last_block_compute_s")  # the last block's cost

    @property
    def now(self) -> float:
        """The session clock: skin time, advanced by the wall clock while no frames arrive."""
        return self.loop.now

    @property
    def user_stopped(self) -> bool:
        """Whether the stop key (:meth:`emergency_stop`) holds the robot."""
        return self._user_stop

    @property
    def command_count(self) -> int:
        """Commands so far, as the paper counts them (discrete inputs)."""
        return len(self.inputs.command_log)

    def holding(self) -> tuple[str, ...]:
        """Which limits hold the arm back now, one line each, for the views."""
        key_held = self.inputs.held is not None
        return holding(self.safety, self.state, self.robot, self._user_stop, key_held)

    def add_input(self, source: CommandInput) -> None:
        """Poll ``source`` every tick from now on."""
        self.inputs.devices.append(source)

    def start_recording(self, path: str | Path, overwrite: bool = False) -> Path:
        return self.record.start(path, overwrite)

    def stop_recording(self) -> Path | None:
        return self.record.stop()

    def store_pose(self, name: str) -> None:
        """Store the arm's current joints as the ``name`` pose."""
        self.pose_mover.store(name)

    def gripper_was_opened(self) -> None:
        """The gripper was opened outside the inputs (a task scene's reset): the next
        toggle closes it."""
        self.inputs.gripper_closed = False

    def count_command(self, t: float, source: str, name: str, kind: str) -> None:
        """Count one command and log it (and into the recording, when one runs)."""
        self.inputs.count(t, source, name, kind)
        self.record.note("inputs", t, {"source": source, "name": name, "kind": kind})

    # -- lifecycle

    def _clock(self) -> float:
        return self.loop.now

    def start(self) -> None:
        """Connect the robot (``RobotError`` if it is not there) and start the skin."""
        self.safety.connect()
        for check in self.safety.capabilities().left_to_controller:
            self._say(f"robot {self.robot.name}: left to the arm's controller: {check}")
        self.loop.started_wall = self._wall()
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
                self.record.close()

    def request_quit(self, reason: str = "quit by the user") -> None:
        """End :meth:`run` after the current step (or the next run, if none is running)."""
        self.loop.request_quit(reason)

    def emergency_stop(self, reason: str = "stop key") -> None:
        """Stop everything now; motion resumes only after :meth:`resume`."""
        self._user_stop = True
        self.drive.halt()
        self.safety.emergency_stop(reason)
        self._report_new_stops()

    def resume(self) -> None:
        """Clear a stop; the robot moves again only on a new command."""
        self._user_stop = False
        self.safety.clear_stop()
        self.shaper.reset()
        self.state.stopped = self.safety.stopped
        self._say("stop cleared: the robot moves again on the next command")

    def set_speed_scale(self, scale: float) -> None:
        """Scale twists, steps and pose moves by ``scale`` (0.01-1, a pendant's 1-100 %
        override); the caps still hold."""
        scale = float(scale)
        if not np.isfinite(scale) or not 0.01 <= scale <= 1.0:
            raise ConfigError(f"speed scale must be between 0.01 and 1, got {scale}")
        self.drive.speed_scale = scale
        self._say(f"speed scaled to {scale:.0%}")

    # -- the loop (polls and the clock: SkinLoop), and what a tick is told

    def run(
        self,
        seconds: float | None = None,
        should_continue: Callable[[], bool] | None = None,
    ) -> SessionResult:
        """Step until the skin ends, :meth:`request_quit`, ``seconds`` of session time
        pass, or ``should_continue()`` returns False; returns the session's figures.
        It may be called again: the next run goes on from where this one ended."""
        if self.loop.started_wall is None:
            self.start()
        self.loop.run(seconds, should_continue)
        return self.result()

    def step(self, timeout: float | None = None) -> int:
        """One skin poll and the ticks of the frames it brought; returns the tick count."""
        return self.loop.step(timeout)

    def result(self) -> SessionResult:
        stream_s, wall_s = self.loop.figures()
        return SessionResult(
            self.state.ticks, stream_s, wall_s, self._commands, list(self.safety.stops),
            self.state.errors, self.loop.quit or "running",
        )  # fmt: skip

    def _skin_alive(self, t: float) -> None:
        """Frames arrived without conditioned output (calibrating): the skin is alive."""
        self._check_watchdogs(t)
        self.safety.heartbeat_skin(t)

    def _idle(self, now: float, stalled: bool) -> None:
        """No frames: the watchdogs see the time pass; a simulated arm moves on to ``now``
        (and is traced once the stall is a watchdog's)."""
        self._check_watchdogs(now)
        if not self.drive.simulated:
            return
        self.drive.advance_robot(now)
        self._read_robot()
        if stalled and self.state.robot is not None:
            self._trace(now)

    def _apply_change(self, change: Any) -> None:
        """The recogniser's command changed at ``change.t``: a gesture began or ended."""
        self._commands += 1
        if change.gesture is not None:  # an activation is a command; its end is none
            self.count_command(float(change.t), "skin", change.gesture, "gesture")
        self.state.gesture = change.gesture
        self.state.gesture_since = float(change.t)
        if change.gesture is not None:
            action = self.mapping.action_for(change.gesture)
            self.gesture_motion.started(action, self.inputs.gesture_frame, float(change.t))
        else:
            self.gesture_motion.ended(float(change.t), lifted=change.reason == LIFT_OFF)
        self._say(f"{change.t:8.2f} s  command {change.gesture or 'none'} ({change.reason})")
        payload = {"gesture": change.gesture, "reason": change.reason}
        self.record.note("commands", change.t, payload)

    def _note_predictions(self, t: float) -> None:
        probabilities = getattr(self.pipeline, "latest_probabilities", None)
        if probabilities is None:
            return
        probabilities = np.asarray(probabilities, dtype=np.float32)
        shown = np.asarray(getattr(self.pipeline, "evidence", probabilities), dtype=np.float32)
        contacts = getattr(getattr(self.live_skin, "state", None), "contacts", None)
        minimum = min_probability_of(self.pipeline)
        update_predictions(self.state, shown, minimum, bool(contacts), t)
        top, p = self.state.top
        self.record.note("predictions", t, {"top": top, "p": p, "probabilities": probabilities})

    # -- one tick: from the active command to the robot, top to bottom

    def _tick(self, t: float) -> None:
        dt = 0.0 if self._tick_t is None else max(0.0, t - self._tick_t)
        self._tick_t = t
        self._check_watchdogs(t)  # before the heartbeat: a gap in the stream is a stall
        self.safety.heartbeat_skin(t)
        self._clear_recovered_stops()
        for event in self.inputs.poll(t):
            self._apply_input(event, t)
        command = active_command(
            self.inputs, self.state.gesture, self.state.gesture_since, self.mapping
        )
        self.drive.control(command, t, dt, self._tick_t)
        self.drive.advance_robot(t)
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
        if self.record.active:
            self.record.note("robot", t, robot_payload(self.state))

    # -- pose moves, inputs beside the skin

    def go_to_pose(self, name: str) -> bool:
        """Start a move to the stored ``name`` pose that runs to completion (the dashboard's
        go-home button); a gesture, the stop key or a watchdog ends it.  Returns whether
        the move started: not while stopped, nor without a stored (or built-in) pose."""
        if name not in ("home", "initial"):
            raise ConfigError(f"unknown pose {name!r}: use home or initial")
        if self.safety.stopped:
            self._error(f"cannot go to the {name} pose while stopped: clear the stop first")
            return False
        started = self.drive.start_pose(PoseAction(name, hold_to_run=False), self.now)
        self._read_robot()  # the next tick must see the move, not the state before it
        return started

    def apply_input(self, event: InputEvent, t: float | None = None) -> None:
        """Apply ``event`` now (at session time ``t``, default the session clock)."""
        self._apply_input(event, self.now if t is None else float(t))

    def _apply_input(self, event: InputEvent, t: float) -> None:
        if event.counts:
            self.count_command(t, event.source, event.name, event.kind)
        try:
            if event.kind == "press":
                action = resolve_input(event, self.mapping, self.safety.model.jacobian is not None)
                if self.inputs.press(event, action, t):
                    self._say(f"{t:8.2f} s  {event.source}: {event.name}")
            elif event.kind == "release":
                self.inputs.release(event.name)
            elif event.kind == "step":
                self.inputs.held = None
                self._step(event, t)
            elif event.kind == "go_to":
                self.inputs.held = None
                self.go_to_pose(event.name)
            elif event.kind == "gripper":
                self.inputs.gripper(event.name, t, self.safety, self._say, self._error)
            elif event.kind == "speed":
                self.set_speed_scale(1.0 if event.amount is None else event.amount)
            else:
                self._say(f"{t:8.2f} s  {event.source}: {event.name}")
        except ConfigError as exc:
            self._error(f"{event.source}: {exc}")
        self.state.held = self.inputs.held_label

    def _step(self, event: InputEvent, t: float) -> None:
        """Move by a fixed increment: a joint move to the goal of ``event``."""
        robot = self.state.robot
        if self.safety.stopped:
            raise ConfigError("cannot step while stopped: clear the stop first")
        if robot is None:
            raise ConfigError("cannot step: no robot state yet")
        goal = step_goal(np.asarray(robot.q, dtype=float), event, self.mapping, self.safety.model)
        if self.drive.start_step(goal, event.name, t):
            self._read_robot()
        else:
            self._report_new_stops()

    # -- the robot's state, its stops and the messages

    def _read_robot(self) -> None:
        try:
            self.state.robot = self.safety.state()
        except RobotError as exc:
            self._error(f"robot: {exc}")

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
            self._say(f"{stop.t:8.2f} s  STOP ({stop.source}): {stop.reason}")
            self.record.note("stops", stop.t, {"reason": stop.reason, "source": stop.source})
        self._stops_seen = len(stops)
        self.state.stopped = self.safety.stopped

    def _clear_recovered_stops(self) -> None:
        """A watchdog stop ends once frames flow again and no command is active."""
        active = self.state.gesture is not None or self.inputs.held is not None
        if self._user_stop or not self.safety.stopped or active:
            return
        last = self.safety.stops[-1] if self.safety.stops else None
        self.safety.clear_stop()
        self.shaper.reset()
        why = f" ({last.reason})" if last is not None else ""
        self._say(f"{self.now:8.2f} s  recovered from the stop{why}")

    def _say(self, text: str) -> None:
        self.report.say(text)

    def _error(self, text: str) -> None:
        self.report.warn(text)
