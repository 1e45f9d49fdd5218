"""The dashboard's engine: a control session on its own thread, fed by the page.

:class:`DashboardRunner` opens a session (the same
:func:`~wovenskin.runtime.session.open_session` wiring as ``wovenskin run``), steps it on
a thread at the skin's full rate (200 Hz recognition and control) and, at the page's rate
(30-60 Hz), stores the newest :func:`~wovenskin.ui.dashboard.snapshot.build_snapshot`
for the server to send: latest only, so a slow browser never slows control.  Page
commands (:meth:`submit`) are queued and carried out on the session thread between
steps (:mod:`.page_commands` says what each does); virtual touches (:meth:`touch`) go
straight to the simulated skin's physics, never to the recogniser or the robot.

A command that cannot be carried out (a bad value, a robot that refuses, a skin that is
not simulated) is reported as one line in the page's messages; it never stops the loop.

A study task (``pick_place``, ``pour``: :mod:`wovenskin.tasks`) is chosen like a skin or
robot: the session is reopened on the task's scene (the opener gets ``task=`` a new
:class:`~wovenskin.tasks.Task`).  The page's keyboard and pendant (:mod:`.teleop`) are
inputs of every session; trials are run by :mod:`.trials` into the study folder.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wovenskin.control.session import ControlSession
from wovenskin.errors import ConfigError
from wovenskin.gestures import CLASS_NAMES
from wovenskin.runtime.sources import skin_spec
from wovenskin.signal.live_skin import RateMeter
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.skin.ports import list_ports
from wovenskin.tasks import TASKS, Task, make_task
from wovenskin.ui.dashboard.adapt_flow import AdaptFlow
from wovenskin.ui.dashboard.page_commands import COMMANDS, carry_out, checked_task
from wovenskin.ui.dashboard.plan import next_step
from wovenskin.ui.dashboard.questionnaire import forms
from wovenskin.ui.dashboard.scene import ArmScene, TaskScene
from wovenskin.ui.dashboard.snapshot import Timeline, TimelineEntry, build_snapshot
from wovenskin.ui.dashboard.teleop import INTERFACES, PageInputs
from wovenskin.ui.dashboard.trials import StudyPanel

SessionOpener = Callable[..., ControlSession]
"""``opener(skin_spec, robot_spec)`` -> an unstarted session; with a task chosen it is
called as ``opener(skin_spec, robot_spec, task=Task)`` (``open_session(..., task=)``), and
with ``model=DIR`` added once the page put another model in use (record and adapt)."""

UI_RATE_HZ = 40.0
"""Page states sent per second unless asked otherwise (``run --ui-rate``, ``bench
dashboard --ui-rate``)."""
TASK_STATE_PERIOD_S = 0.2  # the task's measures in the page: 5 per second (pour: 1 ms each)
KEEP = object()  # _switch: keep the model in use
DEFAULT_SIM_LOOKAHEAD = "0.03"  # s of frames the simulated skin renders ahead (touch latency)


@dataclass
class TouchLatency:
    """Wall-clock times from the first virtual contact to the command and to motion."""

    touch_wall: float | None = None
    command_s: float | None = None
    motion_s: float | None = None
    command: str | None = None

    def to_dict(self) -> dict:
        def ms(v: float | None) -> float | None:
            return None if v is None else round(v * 1000.0, 1)

        return {
            "touch_to_command_ms": ms(self.command_s),
            "touch_to_motion_ms": ms(self.motion_s),
            "command": self.command,
        }


class DashboardRunner:
    """Runs one session for the page (see the module docstring)."""

    def __init__(
        self,
        opener: SessionOpener,
        skin: str,
        robot: str,
        *,
        ui_rate_hz: float = UI_RATE_HZ,
        record_dir: str | Path = "recordings",
        task: str | None = None,
        interface: str = "skin",
        study_dir: str | Path | None = None,
        adapt: AdaptFlow | None = None,
    ) -> None:
        if not 1.0 <= ui_rate_hz <= 120.0:
            raise ConfigError(f"page update rate must be 1-120 Hz, got {ui_rate_hz}")
        self._opener = opener
        self.skin_spec = skin
        self.robot_spec = robot
        self.ui_rate_hz = float(ui_rate_hz)
        self.record_dir = Path(record_dir)
        self.session: ControlSession | None = None
        self.scene: ArmScene | None = None
        self.task_name = checked_task(task)
        self.task: Task | None = None  # the running session's scene
        self.task_scene: TaskScene | None = None
        self.inputs = PageInputs(interface)
        self.study = StudyPanel(study_dir)
        self.plan: dict | None = None  # the page's participant's next planned condition
        self.model: str | None = None  # a model the page put in use (None: the opener's)
        self.adapt = adapt if adapt is not None else AdaptFlow()  # record and adapt (panel)
        self._task_state: tuple[float, dict | None] = (-1.0, None)
        self.timeline = Timeline()
        self.latency = TouchLatency()
        self._commands: queue.Queue[dict] = queue.Queue()
        self._lock = threading.Lock()
        self._snapshot: dict | None = None
        self._seq = 0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._next_publish = 0.0
        self._gesture: str | None = None
        self._stops_seen = 0
        self._touching = False
        self._loop_rate = RateMeter()
        self._ui_rate = RateMeter()
        self.failure: str = ""

    # -- lifecycle

    def start(self) -> None:
        """Open and start the session (errors propagate: nothing runs), then the thread."""
        self.session = self._open(self.skin_spec, self.robot_spec, self.task_name)
        self._thread = threading.Thread(target=self._loop, name="dashboard-session", daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self.adapt.close()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self.session is not None:
            self.study.abandon(float(self.session.now))
            self.session.close()
            self.session = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # -- what the server calls (any thread)

    def latest(self) -> dict | None:
        with self._lock:
            return self._snapshot

    def _class_names(self) -> tuple[str, ...]:
        """The running model's class names (custom gestures included), else the 15."""
        session = self.session
        names = tuple(session.state.class_names) if session is not None else ()
        return names or CLASS_NAMES

    def describe(self) -> dict:
        """What the page needs once: classes, scene shapes, commands, gestures to perform."""
        return {
            "type": "scene",
            "classes": list(self._class_names()),
            "gestures": [name for name in CLASS_NAMES if name != "invalid"],
            "scene": self.scene.describe() if self.scene is not None else None,
            "workspace": self._workspace(),
            "ui_rate_hz": self.ui_rate_hz,
            "ports": _serial_ports(),
            "skin": self.skin_spec,
            "robot": self.robot_spec,
            "task": self.task_scene.describe() if self.task_scene is not None else None,
            "tasks": ["none", *TASKS],
            "interfaces": list(INTERFACES),
            "keys": self.inputs.key_map(self.session) if self.session is not None else [],
            "study": None if self.study.study_dir is None else str(self.study.study_dir),
            "questionnaires": forms(self.study.study_dir),
        }

    @property
    def scene_key(self) -> str:
        """What the page's 3D view and class bars show: it needs :meth:`describe` again when
        this changes."""
        return f"{self.robot_spec}|{self.task_name or ''}|{self.model or ''}"

    def _workspace(self) -> dict | None:
        """The safety layer's workspace box (m, base frame), drawn in the 3D view."""
        if self.session is None:
            return None
        limits = self.session.safety.limits
        return {
            "lower": [round(float(v), 4) for v in limits.workspace_lower],
            "upper": [round(float(v), 4) for v in limits.workspace_upper],
        }

    def submit(self, command: dict) -> None:
        """Queue a page command (``{"cmd": name, ...}``) for the session thread."""
        if not isinstance(command, dict) or command.get("cmd") not in COMMANDS:
            raise ConfigError(f"unknown dashboard command: {str(command)[:80]}")
        self._commands.put(command)

    def note(self, text: str) -> None:
        """Add a line to the page's messages (from any thread; the session thread writes it)."""
        self._commands.put({"cmd": "note", "text": str(text)[:200]})

    def touch(self, touches: dict[int, Any], client_t: float | None = None) -> None:
        """Put virtual fingertips on the simulated skin (``{id: Fingertip}``), at
        ``client_t`` on the page's clock when given (see ``SimulatedSkinSource.set_touches``)."""
        source = self._sim_source()
        if source is None:
            raise ConfigError("the virtual skin needs the simulated skin (skin source sim)")
        if touches and not self._touching:
            self.latency = TouchLatency(touch_wall=time.monotonic())
        self._touching = bool(touches)
        source.set_touches(touches, client_t)

    # -- the session thread

    def _open(self, skin: str, robot: str, task: str | None) -> ControlSession:
        """Build and start a session for ``skin``, ``robot`` and ``task`` (errors propagate)."""
        skin = _with_lookahead(skin)
        session, scene = self._build(skin, robot, task)
        return self._begin(session, skin, robot, scene)

    def _build(self, skin: str, robot: str, task: str | None) -> tuple[ControlSession, Task | None]:
        """An unstarted session (on a new scene of ``task``, when given) and that scene."""
        extra = {"model": self.model} if self.model is not None else {}
        if task is None:
            return self._opener(skin, robot, **extra), None
        scene = make_task(task)
        return self._opener(skin, robot, task=scene, **extra), scene

    def _begin(
        self, session: ControlSession, skin: str, robot: str, task: Task | None = None
    ) -> ControlSession:
        """Start a built session and make it this runner's view of the world."""
        try:
            session.start()
        except Exception:
            session.close()
            raise
        self.skin_spec, self.robot_spec = skin, robot
        self.task, self.task_name = task, (task.name if task is not None else None)
        self.task_scene = TaskScene(task) if task is not None else None
        self._task_state = (-1.0, None)
        self.inputs.attach(session)
        self.scene = ArmScene.for_robot(session.robot)
        if self.scene is None:
            session.state.messages.append("no kinematic model of this arm: the view shows the TCP")
        elif self.scene.caveat:
            session.state.messages.append(self.scene.caveat)
        self._gesture, self._stops_seen = None, 0
        return session

    def _loop(self) -> None:
        while not self._stop.is_set():
            session = self.session
            assert session is not None
            self._drain_commands()
            try:
                ticks = session.step()
            except Exception as exc:  # keep the page alive: report, stop the arm, go on
                self.failure = f"session step failed: {type(exc).__name__}: {exc}"
                session.emergency_stop(self.failure)
                session.state.messages.append(f"error: {self.failure}")
                time.sleep(0.05)
                ticks = 0
            self.adapt.tick(self, session)
            now = time.monotonic()
            if ticks:
                self._loop_rate.add(ticks, now)
            self._watch(session, now)
            try:
                line = self.study.tick(float(session.now))
            except Exception as exc:  # a trial that cannot log ends; the session goes on
                line = f"error: trial stopped: {type(exc).__name__}: {exc}"
                self.study.trial = self.study.recorder = None
            if line:
                session.state.messages.append(line)
                self._replan()
            if now >= self._next_publish:  # a fixed schedule: the rate holds on average
                period = 1.0 / self.ui_rate_hz
                self._next_publish = max(self._next_publish + period, now)
                try:
                    self._publish(session, now)
                except Exception as exc:  # a view bug must not stop control: say it once
                    if not self.failure:
                        self.failure = f"page update failed: {type(exc).__name__}: {exc}"
                        session.state.messages.append(f"error: {self.failure}")

    def _watch(self, session: ControlSession, now: float) -> None:
        state = session.state
        if state.gesture != self._gesture:
            self._gesture = state.gesture
            self.timeline.add(TimelineEntry(session.now, "command", state.gesture))
            lat = self.latency
            if state.gesture and lat.touch_wall is not None and lat.command_s is None:
                lat.command_s, lat.command = now - lat.touch_wall, state.gesture
        stops = session.safety.stops
        for stop in stops[self._stops_seen :]:
            self.timeline.add(TimelineEntry(stop.t, "stop", stop.source, stop.reason))
        self._stops_seen = len(stops)
        lat = self.latency
        robot = state.robot
        moved = robot is not None and robot.tcp_speed > 1e-3
        if lat.command_s is not None and lat.motion_s is None and moved:
            lat.motion_s = now - lat.touch_wall

    def _publish(self, session: ControlSession, now: float) -> None:
        self._ui_rate.add(1, now)
        self._seq += 1
        extras = {
            "rates": {
                "control_hz": round(self._loop_rate.rate(now), 1),
                "ui_hz": round(self._ui_rate.rate(now), 1),
            },
            "latency": self.latency.to_dict(),
            "autoplay": self._autoplay(),
            "failure": self.failure,
            "teleop": self.inputs.part(session),
            "study": {**self.study.part(float(session.now)), "plan": self.plan},
            "task": self._task_part(session),
            "sim_slowed_s": None if (source := self._sim_source()) is None else source.slowed_s,
            "adapt": self.adapt.part(self, float(session.now)),
        }
        snapshot = build_snapshot(
            session,
            seq=self._seq,
            source_spec=self.skin_spec,
            robot_spec=self.robot_spec,
            scene=self.scene,
            timeline=self.timeline,
            virtual=self._sim_source() is not None,
            extras=extras,
        )
        with self._lock:
            self._snapshot = snapshot

    def _task_part(self, session: ControlSession) -> dict | None:
        """The task's name, measures (every :data:`TASK_STATE_PERIOD_S`) and poses."""
        if self.task is None or self.task_scene is None:
            return None
        t = float(session.now)
        last_t, state = self._task_state
        if state is None or not 0.0 <= t - last_t < TASK_STATE_PERIOD_S:
            state = self.task.to_dict()
            self._task_state = (t, state)
        return {"name": self.task.name, "state": state, **self.task_scene.poses()}

    def _drain_commands(self) -> None:
        while True:
            try:
                command = self._commands.get_nowait()
            except queue.Empty:
                return
            try:
                carry_out(self, command)
            except Exception as exc:  # one line in the page; the loop goes on
                line = " ".join(f"{command.get('cmd')}: {exc}".split())
                if self.session is not None:
                    self.session.state.messages.append(f"error: {line}")

    def _replan(self, participant: object = None) -> None:
        """The plan's next step for ``participant`` (default: the one shown)."""
        who = participant or (self.plan or {}).get("participant")
        self.plan = next_step(self.study.study_dir, who)

    def _switch(self, skin: str, robot: str, task: str | None = None, model: Any = KEEP) -> None:
        """Replace this session by one with another skin, robot or ``model`` (a checkpoint
        directory; None: the opener's own).

        The new session is built completely first (spec parsed, skin source and robot
        backend created, replay files read, model and mapping loaded: everything short of
        connecting), while the old one keeps running; a spec that fails there changes
        nothing (arm, counters, timeline and messages stay).  Only then is the old session
        closed and the new one started; if starting fails (a device that does not answer)
        the old one is reopened, so the page never ends up with nothing.
        """
        if self.study.running:
            raise ConfigError("a trial is running: end it before switching")
        old_model, self.model = self.model, (self.model if model is KEEP else model)
        try:
            skin = _with_lookahead(skin)
            candidate, scene = self._build(skin, robot, task)  # builds all, connects nothing
        except Exception as exc:
            self.model = old_model
            why = " ".join(str(exc).split()) or type(exc).__name__
            raise ConfigError(
                f"kept skin {self.skin_spec} and robot {self.robot_spec}: "
                f"cannot use skin {skin!r} with robot {robot!r}: {why}"
            ) from exc
        old = self.session
        assert old is not None
        old_skin, old_robot, old_task = self.skin_spec, self.robot_spec, self.task_name
        speed, messages = old.speed_scale, list(old.state.messages)
        old.close()
        try:
            self.session = self._begin(candidate, skin, robot, scene)
            failure = None
        except Exception as exc:
            self.model = old_model
            self.session = self._open(old_skin, old_robot, old_task)
            failure = exc
        self.session.speed_scale = speed
        self.session.state.messages.extend(messages)
        if failure is not None:
            why = f"could not start skin {skin!r} with robot {robot!r}: {failure}"
            raise ConfigError(why) from failure
        on = f", task {self.task_name}" if self.task_name else ""
        now = f"now: skin {self.skin_spec}, robot {self.robot_spec}{on}"
        self.session.state.messages.append(now)

    def _sim_source(self) -> SimulatedSkinSource | None:
        source = self.session.live_skin.source if self.session is not None else None
        return source if isinstance(source, SimulatedSkinSource) else None

    def _autoplay(self) -> bool | None:
        source = self._sim_source()
        return None if source is None else bool(source.autonomous)


def _with_lookahead(skin: str) -> str:
    """``skin`` with the simulated skin's default touch lookahead added where it has none;
    a :class:`~wovenskin.errors.ConfigError` for a spec that does not parse."""
    spec = skin_spec(skin)
    if spec.kind != "sim" or "lookahead" in spec.options:
        return skin
    option = f"lookahead={DEFAULT_SIM_LOOKAHEAD}"
    if "?" in spec.text:
        return f"{spec.text}&{option}"
    return f"{spec.text},{option}" if spec.options else f"{spec.text.rstrip(':')}:{option}"


def _serial_ports() -> list[str]:
    """Serial ports for the page's skin choices, likely skins first (none if listing fails)."""
    try:
        ports = list_ports()
    except Exception:  # a port listing problem must not break the page
        return []
    return [p.device for p in sorted(ports, key=lambda p: not p.likely_skin)]
