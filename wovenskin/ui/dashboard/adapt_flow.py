"""The dashboard's "Record & adapt" panel: record a person, adapt the model, put it in use.

:class:`AdaptFlow` runs on the dashboard's session thread, beside the control session and
on the skin that session runs (simulated or serial):

1. **record** (``{"name", "gestures", "trials", "perform"}``): a guided recording into
   ``runs/adapt/<name>-<timestamp>/<name>.wsrec``, driven by the same
   :class:`~wovenskin.ui.record_session.RecordDriver` as ``wovenskin record``: the skin is
   recalibrated (hands off), then every gesture of the running model is prompted
   ``trials`` times (default: ``record``'s plan) with a countdown, plus ``record``'s
   invalid-touch trials.  The driver sees every block of the session's live skin
   (``LiveSkin.on_block``), so contact windows are exact to the frame.  On the simulated
   skin the simulated person performs each prompt (``perform``, default on; off: the
   person draws on the virtual skin).
2. **The arm ignores gestures while recording**: the flow latches the session's stop
   (:meth:`~wovenskin.control.session.ControlSession.emergency_stop`), so no command of
   the recogniser reaches the robot, and the runner refuses ``resume`` and anything else
   that would change the session until the recording ends.  The stop stays latched
   afterwards: the arm moves again only when the person presses Resume (or puts a model
   in use, which opens a new session).
3. **adapt**: when the recording is complete, :class:`~.adapt_job.AdaptJob` adapts the
   running model to it in a child process (progress from its
   :class:`~wovenskin.training.adapt.AdaptEvent`\\ s), into ``<run>/model``.  Without
   PyTorch the recording is kept and the panel says so in one line.
4. **the verdict**: the report's before/after figures on the held-out trials.
5. **use** switches the live recogniser to the adapted model (a new session, as a skin or
   robot switch does), refused when adapt refused it; **revert** goes back to the model
   used before.  **cancel** stops a recording (what was recorded is kept) or an adapt run;
   **reset** clears a finished run from the panel.

Page requests are checked twice: by :meth:`AdaptFlow.request` when the server receives
them (bad input or a busy flow is one line back at once) and again on the session thread
(:meth:`AdaptFlow.command`), which alone changes anything.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Callable, Sequence
from dataclasses import asdict
from datetime import datetime
from pathlib import Path
from typing import Any

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURES, INVALID
from wovenskin.recording.writer import RecordingWriter
from wovenskin.ui.dashboard.adapt_job import WORKER_COMMAND, AdaptJob, torch_missing
from wovenskin.ui.record_session import RecordAborted, RecordDriver, RecordPlan, provenance_for
from wovenskin.wording import quantity

ADAPT_ROOT = Path("runs") / "adapt"
HOLD_REASON = "recording for adapt: the arm ignores gestures until the recording ends"
BLOCKED_WHILE_RECORDING = frozenset(
    {"resume", "record", "switch", "task", "calibrate", "perform", "autoplay", "trial",
     "interface", "gripper", "home", "initial"}
)  # fmt: skip
REPLIES = {
    "record": "recording starts: keep hands off the skin while it calibrates",
    "cancel": "cancelling",
    "use": "switching to the adapted model",
    "revert": "switching back to the previous model",
    "reset": "cleared",
}
OPS = tuple(REPLIES)
MAX_TRIALS = 20
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,39}")
_PLAN = RecordPlan([])  # ``wovenskin record``'s defaults
LIMITS = {"countdown_s": (0.2, 10.0), "trial_s": (0.5, 15.0), "invalid_trials": (0, MAX_TRIALS)}


def check_record_request(
    body: dict, gestures: Sequence[str], simulated: bool, custom: dict[str, CustomGesture]
) -> dict:
    """A record request made whole: ``name`` (letters, digits, ``_.-``, at most 40),
    ``gestures`` (default: all of ``gestures``), ``trials`` per gesture (default 3),
    ``perform`` (the simulated person performs; simulated skins only) and optionally
    ``countdown_s``, ``trial_s``, ``invalid_trials``.  One ConfigError line if bad."""
    name = str(body.get("name", "")).strip().replace(" ", "_")
    if not _NAME.fullmatch(name):
        raise ConfigError(
            "enter a name: 1-40 letters, digits, '_', '.' or '-', starting with a letter or digit"
        )
    chosen = body.get("gestures") or list(gestures)
    if not isinstance(chosen, list) or not all(isinstance(g, str) for g in chosen):
        raise ConfigError("gestures must be a list of gesture names")
    unknown = [g for g in chosen if g not in gestures]
    if unknown:
        raise ConfigError(
            f"the model does not know {', '.join(map(repr, unknown))}; it knows "
            f"{', '.join(gestures)}"
        )
    trials = body.get("trials") if body.get("trials") is not None else _PLAN.trials_per_gesture
    plan = {
        "gestures": list(dict.fromkeys(chosen)),
        "trials_per_gesture": _within(trials, "trials", 1, MAX_TRIALS, whole=True),
    }
    for key, (low, high) in LIMITS.items():
        if body.get(key) is not None:
            plan[key] = _within(body[key], key, low, high, whole=key == "invalid_trials")
    perform = bool(body.get("perform", True)) and simulated
    if perform:
        blind = [g for g in plan["gestures"] if g in custom and not custom[g].strokes]
        blind += [g for g in plan["gestures"] if g not in custom and g not in _BUILT_IN]
        if blind:
            raise ConfigError(
                f"the simulated person cannot perform {', '.join(map(repr, blind))} (no strokes):"
                " untick 'the simulated person performs' and draw it on the virtual skin"
            )
    return {"name": name, "plan": plan, "perform": perform}


_BUILT_IN = frozenset(g.name for g in GESTURES)


def _number(value: object, key: str) -> float:
    """A finite number from a JSON value (or numeric text); one ConfigError line if not."""
    try:
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            raise ValueError
        number = float(value)
        if number != number or abs(number) == float("inf"):
            raise ValueError
    except ValueError:
        raise ConfigError(f"{key} must be a finite number, got {str(value)[:40]!r}") from None
    return number


def _within(value: object, key: str, low: float, high: float, whole: bool) -> float:
    """``value`` as a number in ``[low, high]`` (a whole one if ``whole``), or ConfigError."""
    number = _number(value, key)
    if whole and number != int(number):
        raise ConfigError(f"{key} must be a whole number, got {number:g}")
    if not low <= number <= high:
        raise ConfigError(f"{key} must lie in {low:g}-{high:g}, got {number:g}")
    return int(number) if whole else number


def gesture_hint(label: str, mapping: Any, custom: dict[str, CustomGesture]) -> str:
    """How a prompted gesture is made and what it does: its fingers and mapped action."""
    if label == INVALID:
        return ""
    fingers = custom[label].fingers if label in custom else _FINGERS.get(label)
    parts = [quantity(fingers, "finger")] if fingers else []
    action = mapping.action_for(label) if mapping is not None else None
    if action is not None:
        parts.append(f"its action: {action} (held while recording)")
    return " · ".join(parts)


_FINGERS = {g.name: g.fingers for g in GESTURES}


def report_summary(report: dict | None) -> dict | None:
    """The page's before/after table of an adapt report (``AdaptReport.to_dict()``)."""
    if not isinstance(report, dict) or not isinstance(report.get("held_out_after"), dict):
        return None
    before, after = report.get("held_out_before"), report["held_out_after"]

    def figure(scores: dict | None, key: str, scale: float = 1.0) -> float | None:
        value = None if scores is None else scores.get(key)
        return None if value is None else round(float(value) * scale, 3)

    figures = [
        {"name": name, "before": figure(before, key, scale), "after": figure(after, key, scale)}
        for name, key, scale in (
            ("event F1", "f1", 1.0),
            ("false activations / min", "false_activations_per_min", 1.0),
            ("median latency from contact (ms)", "median_latency_s", 1000.0),
        )
    ]
    recall_before = (before or {}).get("per_class_recall") or {}
    events = after.get("per_class_events") or {}
    classes = [
        {"name": name, "events": events.get(name), "after": round(float(recall), 3),
         "before": None if name not in recall_before else round(float(recall_before[name]), 3)}
        for name, recall in sorted((after.get("per_class_recall") or {}).items())
    ]  # fmt: skip
    others = report.get("other_people")
    return {
        "figures": figures,
        "classes": classes,
        "other_people": others if isinstance(others, dict) else None,
        "min_probability": (report.get("arbiter") or {}).get("min_probability"),
        "new_classes": report.get("new_classes") or [],
        "accepted": bool(report.get("accepted")),
        "seconds": report.get("seconds"),
    }


class AdaptFlow:
    """The record-and-adapt panel's state (see the module docstring).

    ``root`` holds the runs; ``worker`` is the adapt child's command line (tests give a
    fast stand-in); ``settings`` go to ``AdaptSettings``; ``defaults`` are record-request
    values used where a request gives none (e.g. shorter trials)."""

    def __init__(
        self,
        root: str | Path = ADAPT_ROOT,
        worker: Sequence[str] = WORKER_COMMAND,
        settings: dict | None = None,
        defaults: dict | None = None,
    ) -> None:
        self.root = Path(root)
        self.defaults = dict(defaults or {})
        self.worker = list(worker)
        self.settings = dict(settings or {})
        self.phase = "idle"  # idle, recording, adapting, done, refused, failed, saved
        self.message = ""
        self.name = ""
        self.run_dir: Path | None = None
        self.recording: Path | None = None
        self.driver: RecordDriver | None = None
        self.job: AdaptJob | None = None
        self.report: dict | None = None
        self.summary: dict | None = None
        self.model_in_use: str | None = None  # None: the model the dashboard started with
        self.previous: list[str | None] = []  # the models to go back to, newest last
        self._hints: dict[str, str] = {}
        self._blocks: list = []
        self._autonomous: bool | None = None
        self._progress: dict | None = None
        self.torch = torch_missing()  # "" when PyTorch is installed: asked once

    @property
    def recording_now(self) -> bool:
        return self.phase == "recording"

    # -- from the server (any thread): check, then queue for the session thread

    def request(self, op: str, body: dict, runner: Any) -> str:
        """Check a page request now and queue it; returns what the page should say."""
        if op not in OPS:
            raise ConfigError(f"unknown adapt request {op[:40]!r}; known: {', '.join(OPS)}")
        self._check(op, body, runner)
        runner.submit({"cmd": "adapt", "op": op, "body": body})
        return REPLIES[op]

    def _check(self, op: str, body: dict, runner: Any) -> dict | None:
        """One ConfigError line when ``op`` cannot be done now; a record request made whole."""
        busy = self.phase in ("recording", "adapting")
        if op == "record":
            if busy:
                raise ConfigError(f"already {self.phase}: cancel it first")
            session = runner.session
            if session is None:
                raise ConfigError("the dashboard has no session running")
            if session.recorder is not None:
                raise ConfigError(
                    f"the session is recording to {session.recorder.path}: stop that first"
                )
            if runner.study.running:
                raise ConfigError("a study trial is running: end it first")
            simulated = runner._sim_source() is not None
            request = {**self.defaults, **body}
            gestures = self.model_gestures(runner)
            return check_record_request(request, gestures, simulated, dict(session.mapping.custom))
        if op == "cancel" and not busy:
            raise ConfigError("nothing to cancel: no recording or adapt run")
        if op == "use":
            if self.phase == "refused":
                raise ConfigError(
                    "adapt refused this model (worse than the base on the held-out trials)"
                )
            if self.phase != "done" or self.run_dir is None:
                raise ConfigError("no adapted model yet: record and adapt first")
            if runner.study.running:
                raise ConfigError("a study trial is running: end it first")
        if op == "revert" and not self.previous:
            raise ConfigError("no previous model to go back to")
        if op == "reset" and busy:
            raise ConfigError(f"still {self.phase}: cancel it first")
        return None

    @staticmethod
    def model_gestures(runner: Any) -> list[str]:
        """The running model's gestures (its classes but ``invalid``)."""
        return [name for name in runner._class_names() if name != INVALID]

    # -- on the session thread

    def command(self, runner: Any, session: Any, command: dict) -> None:
        """Carry out a queued request (ConfigError: one line in the page's messages)."""
        op = str(command.get("op"))
        body = command.get("body") if isinstance(command.get("body"), dict) else {}
        try:
            self._carry_out(runner, session, op, body)
        except Exception as exc:
            self.message = " ".join(f"{op}: {exc}".split())[:300]  # the panel says it too
            raise

    def _carry_out(self, runner: Any, session: Any, op: str, body: dict) -> None:
        if op not in OPS:
            raise ConfigError(f"unknown adapt request {op[:40]!r}")
        checked = self._check(op, body, runner)
        if op == "record":
            self._start_recording(runner, session, checked)
        elif op == "cancel":
            if self.phase == "recording":
                self._end_recording(session, why="cancelled", runner=runner)
            elif self.job is not None:
                self.job.cancel()
        elif op == "use":
            assert self.run_dir is not None
            self._use(runner, str(self.run_dir / "model"), push=True)
        elif op == "revert":
            self._use(runner, self.previous[-1], push=False)
        elif op == "reset":
            self.phase, self.message, self.report, self.summary = "idle", "", None, None
            self.job, self.driver, self._progress = None, None, None

    def _start_recording(self, runner: Any, session: Any, checked: dict) -> None:
        name, live = checked["name"], session.live_skin
        chosen = checked["plan"]["gestures"]
        custom = {g: c for g, c in session.mapping.custom.items() if g in chosen}
        plan = RecordPlan(**checked["plan"])
        stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
        run_dir = self.root / f"{name}-{stamp}"
        for k in range(2, 100):
            if not run_dir.exists():
                break
            run_dir = self.root / f"{name}-{stamp}-{k}"
        run_dir.mkdir(parents=True)
        path = run_dir / f"{name}.wsrec"
        settings = {"conditioning": live.config.to_dict(), **session.recording_context,
                    "plan": asdict(plan)}  # fmt: skip
        if custom:
            settings["custom_gestures"] = {g: c.to_dict() for g, c in custom.items()}
        given = {"participant": name, "notes": "dashboard: record and adapt"}
        writer = RecordingWriter(
            path, live.info, provenance_for(runner.skin_spec, live.info, given), settings
        )
        session.emergency_stop(HOLD_REASON)  # before anything else: the arm holds still
        session.recorder, live.recorder = writer, writer
        source = runner._sim_source()
        perform: Callable[[str], None] | None = None
        if source is not None:
            self._autonomous, source.autonomous = source.autonomous, False
            if checked["perform"]:
                source.define_gestures(custom)
                perform = source.perform
        prompts = {g: c.prompt for g, c in custom.items()}
        self._hints = {g: gesture_hint(g, session.mapping, custom) for g in plan.gestures}
        self.driver = RecordDriver(plan, writer, prompts, perform, session.state.messages)
        self._blocks = []
        live.on_block = self._blocks.append
        live.recalibrate()
        self.name, self.run_dir, self.recording = name, run_dir, path
        self.phase, self.report, self.summary, self.job = "recording", None, None, None
        self.message = f"recording {path}: the arm ignores gestures until it ends"
        session.state.messages.append(self.message)

    def tick(self, runner: Any, session: Any) -> None:
        """After every session step: feed the recording, or follow the adapt run.  Never
        raises: an error ends the recording (kept) and is one line in the panel."""
        try:
            self._tick(runner, session)
        except Exception as exc:  # noqa: BLE001 - the control loop must go on
            why = f"stopped by an error: {type(exc).__name__}: {exc}"
            if self.phase == "recording":
                with contextlib.suppress(Exception):
                    self._end_recording(session, why=why, runner=runner)
            self.phase, self.message = "failed", " ".join(why.split())[:300]
            session.state.messages.append(f"error: adapt: {self.message}")

    def _tick(self, runner: Any, session: Any) -> None:
        if self.phase == "recording" and self.driver is not None:
            live = session.live_skin
            blocks, self._blocks[:] = list(self._blocks), []
            state = live.state
            try:
                if state.ended:
                    raise RecordAborted("the skin source ended")
                for block in blocks or [None]:
                    t = float(block.t[-1]) if block is not None else float(state.t)
                    self.driver.feed(t, block, state.calibrating, state.stalled)
            except RecordAborted as exc:
                self._end_recording(session, why=str(exc), runner=runner)
                return
            if self.driver.done:
                self._end_recording(session, runner=runner)
        elif self.phase == "adapting" and self.job is not None:
            status = self.job.status()
            self._progress = {"stage": status.stage, "done": status.done, "total": status.total,
                              "note": status.note, "seconds": round(status.seconds, 1),
                              "stages": status.stages}  # fmt: skip
            if status.finished:
                self._adapted(session, status)

    def _end_recording(self, session: Any, why: str = "", runner: Any = None) -> None:
        """Close the recording (kept in any case), then adapt when it is complete."""
        session.live_skin.on_block = None
        session.stop_recording()
        source = runner._sim_source() if runner is not None else None
        if source is not None and self._autonomous is not None:
            source.autonomous = self._autonomous
        self._autonomous = None
        trials = len(self.driver.trials) if self.driver is not None else 0
        kept = f"{self.recording} ({quantity(trials, 'trial')})"
        if why:
            self.phase = "idle" if why == "cancelled" else "failed"
            self.message = f"recording {why}; kept {kept}; the arm stays stopped until Resume"
        elif self.torch:
            self.phase, self.message = "saved", f"recording saved: {kept}. {self.torch}"
        else:
            self._start_adapt(session)
            return
        session.state.messages.append(self.message)

    def _start_adapt(self, session: Any) -> None:
        assert self.run_dir is not None and self.recording is not None
        self.job = AdaptJob(
            [self.recording], self.run_dir / "model", _base_model(self.model_in_use, session),
            settings=self.settings, command=self.worker, log=self.run_dir / "adapt.log",
        )  # fmt: skip
        try:
            self.job.start()
        except OSError as exc:
            self.phase, self.message = "failed", f"adapt could not start: {exc}"
        else:
            self.phase = "adapting"
            self.message = "recording saved; adapting (a few minutes): the arm stays stopped"
            self._progress = {"stage": "starting", "done": 0, "total": 0, "note": "",
                              "seconds": 0.0, "stages": []}  # fmt: skip
        session.state.messages.append(self.message)

    def _adapted(self, session: Any, status: Any) -> None:
        self.report, self.summary = status.report, report_summary(status.report)
        self.phase = {"done": "done", "refused": "refused", "cancelled": "idle"}.get(
            status.state, "failed"
        )
        self.message = status.message or status.state
        session.state.messages.append(f"adapt: {self.message}")

    def _use(self, runner: Any, model: str | None, push: bool) -> None:
        """Put ``model`` in use (None: the dashboard's starting model) by a session switch
        (the runner's switch: the old session and model stay when it fails)."""
        before = runner.model
        runner._switch(runner.skin_spec, runner.robot_spec, runner.task_name, model=model)
        if push:
            self.previous.append(before)
        else:
            self.previous.pop()
        self.model_in_use = model
        shown = model if model is not None else "the model the dashboard started with"
        runner.session.state.messages.append(f"recogniser: now {shown}")

    def close(self) -> None:
        """Stop an adapt run (the dashboard closes); a recording closes with its session."""
        if self.job is not None:
            self.job.close()

    def part(self, runner: Any, t: float) -> dict:
        """The panel's state for the page (every snapshot)."""
        prompt, adapted = None, None
        if self.phase == "done" and self.run_dir is not None:
            adapted = str(self.run_dir / "model")
        if self.phase == "recording" and self.driver is not None:
            shown = self.driver.prompt(t)
            prompt = {**shown.to_dict(), "hint": self._hints.get(shown.label or "", "")}
        return {
            "phase": self.phase,
            "message": self.message,
            "torch": self.torch,
            "name": self.name,
            "run_dir": None if self.run_dir is None else str(self.run_dir),
            "recording": None if self.recording is None else str(self.recording),
            "prompt": prompt,
            "trials_done": 0 if self.driver is None else len(self.driver.trials),
            "progress": self._progress if self.phase == "adapting" else None,
            "summary": self.summary,
            "verdict": self.message if self.phase in ("done", "refused") else "",
            "model": {
                "in_use": self.model_in_use,
                "adapted": adapted,
                "can_use": self.phase == "done" and self.model_in_use != adapted,
                "can_revert": bool(self.previous),
            },
            "gestures": self.model_gestures(runner),
            "defaults": {
                "trials": self.defaults.get("trials", _PLAN.trials_per_gesture),
                "invalid_trials": self.defaults.get("invalid_trials", _PLAN.invalid_trials),
                "trial_seconds": self.defaults.get("countdown_s", _PLAN.countdown_s)
                + self.defaults.get("trial_s", _PLAN.trial_s),
                "simulated": runner._sim_source() is not None,
            },
        }


def _base_model(in_use: str | None, session: Any) -> str | None:
    """The model to adapt: the one in use (a directory), else the shipped one (None)."""
    if in_use is not None:
        return in_use
    model = (session.recording_context.get("session") or {}).get("model")
    return str(model) if model and (Path(str(model)) / "meta.json").is_file() else None
