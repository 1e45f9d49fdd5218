"""``wovenskin record``: a guided session that prompts gestures and labels every trial.

The session records every raw frame at the full rate from the moment the source starts
(calibration frames included, so the baseline can be recomputed later), writes the
calibration it used, and for each trial a label with the prompt window and the contact
window that the conditioning saw (first contact to last lift-off).  All timing runs on
the stream clock, so a replayed or simulated source at any speed produces the same
session.  Ctrl-C, a stalled or unplugged skin, or an exception still leave a readable
recording: the writer flushes at least every second.  Ctrl-C is reported in
:attr:`SessionSummary.interrupted`, so the command can exit non-zero (130).

With the simulated skin (``--skin sim``) the simulated person performs each prompted
gesture, which makes the whole flow testable without hardware.

The prompts, countdowns, trials and labels are one state machine, :class:`RecordDriver`,
fed by whoever steps the skin: the terminal here, and the web dashboard's record-and-adapt
panel (:mod:`wovenskin.ui.dashboard.adapt_flow`) on the skin its session runs.

A user's own gestures (``custom``: :class:`~wovenskin.custom_gestures.CustomGesture`, from a
mapping file's ``[custom_gestures]``) are prompted with their descriptions and labelled
with their names; their definitions are kept in the recording's settings
(``custom_gestures``).  On the simulated skin the person performs them from their stroke
scripts; one without strokes is refused in one line before anything is recorded.
"""

from __future__ import annotations

import getpass
import platform
import random
import sys
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from rich.console import Console, Group
from rich.panel import Panel
from rich.text import Text

from wovenskin import __version__
from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID, known_classes
from wovenskin.runtime.pipeline import open_live_skin
from wovenskin.runtime.sources import skin_spec
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.skin.frames import SkinInfo
from wovenskin.ui.terminal import heatmap, live_screen
from wovenskin.wording import quantity

INVALID_PROMPT = "touch WITHOUT a gesture: tap, palm, grasp the link, brush past, 3-4 fingers"


@dataclass
class RecordPlan:
    """Which trials to prompt, and how long each phase lasts (seconds of stream time)."""

    gestures: list[str]
    trials_per_gesture: int = 3
    invalid_trials: int = 3
    countdown_s: float = 2.0
    trial_s: float = 3.0
    max_overrun_s: float = 2.0
    calibration_timeout_s: float = 10.0
    seed: int = 0

    def trials(self) -> list[str]:
        """The trial order: every gesture ``trials_per_gesture`` times, shuffled by ``seed``."""
        order = [g for g in self.gestures for _ in range(self.trials_per_gesture)]
        order += [INVALID] * self.invalid_trials
        random.Random(self.seed).shuffle(order)
        return order


@dataclass
class TrialResult:
    label: str
    prompt_start_s: float
    prompt_end_s: float
    contact_start_s: float | None
    contact_end_s: float | None
    interrupted: bool = False


@dataclass
class SessionSummary:
    path: Path
    frames: int
    trials: list[TrialResult] = field(default_factory=list)
    aborted: str = ""
    interrupted: bool = False  # Ctrl-C cut the session short (``record`` exits 130)

    def __str__(self) -> str:
        missed = sum(t.contact_start_s is None for t in self.trials)
        text = (
            f"wrote {self.path}: {quantity(self.frames, 'frame')}, "
            f"{quantity(len(self.trials), 'labelled trial')}"
            f" ({missed} without contact)"
        )
        return text + (f"; stopped early: {self.aborted}" if self.aborted else "")


class _TrialTracker:
    """Finds the contact window of one trial from the debounced ``touched`` flag."""

    def __init__(self) -> None:
        self.first: float | None = None
        self.last: float | None = None
        self.touching = False

    def update(self, t, touched) -> None:
        for ti, on in zip(t, touched, strict=True):
            if on and self.first is None:
                self.first = float(ti)
            if on:
                self.last = float(ti)
            self.touching = bool(on)


def run_record_session(
    out: Path,
    skin: str,
    plan: RecordPlan,
    provenance: dict | None = None,
    overwrite: bool = False,
    console: Console | None = None,
    config: ConditioningConfig | None = None,
    custom: Mapping[str, CustomGesture] | None = None,
) -> SessionSummary:
    """Run a guided recording session into ``out`` and return what was recorded.

    ``custom``: the definitions of the plan's custom gestures (prompted with their
    descriptions; on the simulated skin performed from their strokes)."""
    console = console or Console()
    custom = dict(custom or {})
    _check_plan(plan, skin, custom)
    messages: list[str] = []
    recorded: dict = {"plan": asdict(plan)}
    if custom:
        recorded["custom_gestures"] = {name: g.to_dict() for name, g in custom.items()}
    chain = open_live_skin(
        skin,
        conditioning=config,
        record=out,
        overwrite=overwrite,
        provenance=lambda info: provenance_for(skin, info, provenance),
        recorded=recorded,
        on_message=messages.append,
    )
    source, live_skin, writer = chain.source, chain.live_skin, chain.recorder
    assert writer is not None
    summary = SessionSummary(Path(out), 0)
    perform = getattr(source, "perform", None)
    if isinstance(source, SimulatedSkinSource):
        source.autonomous = False  # the simulated person performs only what is prompted
        source.define_gestures(custom)
    live_skin.start()
    prompts = {name: g.prompt for name, g in custom.items()}
    driver = RecordDriver(plan, writer, prompts, perform, messages)
    try:
        with live_screen(console, auto_refresh=False) as live:
            _Session(live_skin, driver, live, messages).run()
    except KeyboardInterrupt:
        summary.aborted = "interrupted by the user (Ctrl-C)"
        summary.interrupted = True
    except RecordAborted as exc:
        summary.aborted = str(exc)
    finally:
        summary.trials = driver.trials
        live_skin.close()
        summary.frames = live_skin.stats().good_frames
        writer.close()
    return summary


def prompt_for(label: str, prompts: Mapping[str, str] | None = None) -> str:
    """What a trial of ``label`` asks the person to do: :data:`INVALID_PROMPT`, a custom
    gesture's prompt from ``prompts`` (its name and description), or the gesture's name."""
    if label == INVALID:
        return INVALID_PROMPT
    return (prompts or {}).get(label, label.replace("_", " "))


def _check_plan(plan: RecordPlan, skin: str, custom: dict[str, CustomGesture]) -> None:
    """One ConfigError line, before anything is opened, for a gesture the plan cannot
    prompt: unknown, or custom without strokes on the simulated skin."""
    known = known_classes(custom)
    for name in plan.gestures:
        if name not in known:
            raise ConfigError(f"unknown gesture {name!r}; known: {', '.join(known)}")
    if isinstance(skin, str) and skin_spec(skin).kind == "sim":
        for name in dict.fromkeys(plan.gestures):
            if name in custom and not custom[name].strokes:
                raise ConfigError(
                    f"custom gesture {name!r} has no strokes, so the simulated person cannot "
                    f"perform it: add strokes under [custom_gestures.{name}] or record it on "
                    "a real skin"
                )


def provenance_for(skin: str, info: SkinInfo, given: dict | None) -> dict:
    """Who recorded what, where and with which software (``given`` first)."""
    provenance = {
        "participant": "anonymous",
        **(given or {}),
        "skin_source": skin,
        "started_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "host": platform.node(),
        "user": _user(),
        "wovenskin_version": __version__,
        "command": " ".join(sys.argv),
    }
    if not provenance.get("skin_id"):
        provenance["skin_id"] = info.device_id or skin
    return provenance


class RecordAborted(Exception):
    """The session cannot go on (the source ended, calibration never finished); ``str`` is why."""


@dataclass(frozen=True)
class Prompt:
    """What the person is asked to do now, for any front end to draw.

    ``phase``: ``calibrating`` (hands off), ``countdown`` (get ready for ``what``), ``trial``
    (perform ``what`` now) or ``done``; ``number`` of ``total`` is the trial shown (1-based);
    ``seconds_left`` of the countdown or the trial."""

    phase: str
    label: str | None = None
    what: str = ""
    number: int = 0
    total: int = 0
    seconds_left: float = 0.0

    def to_dict(self) -> dict:
        return {**asdict(self), "seconds_left": round(self.seconds_left, 2)}


class RecordDriver:
    """The prompt/countdown/trial state machine of a guided session, driven by stream time.

    A front end steps the skin and calls :meth:`feed` after every step (with the block of
    conditioned frames it brought, or ``None``), and draws :meth:`prompt`.  The driver
    labels every trial in ``writer`` (``add_label``, kind ``trial``), repeats a trial once
    when the skin stalled during it (a line in ``messages``), calls ``perform(label)`` as
    each trial starts (the simulated person) and raises :class:`RecordAborted` when
    calibration does not finish within the plan's timeout.  The terminal (``wovenskin
    record``) and the dashboard's record-and-adapt panel both drive this one class.
    """

    def __init__(
        self,
        plan: RecordPlan,
        writer,
        prompts: Mapping[str, str] | None = None,
        perform: Callable[[str], None] | None = None,
        messages: list[str] | None = None,
    ) -> None:
        self.plan = plan
        self.writer = writer
        self.prompts: dict[str, str] = dict(prompts or {})  # custom gestures' descriptions
        self.perform = perform
        self.messages = messages if messages is not None else []
        self.trials: list[TrialResult] = []
        self.queue = plan.trials()
        self.total = len(self.queue)
        self.index = 0
        self.phase = "calibrating"
        self._retried: set[int] = set()
        self._calibration_start: float | None = None
        self._t0 = 0.0  # when the countdown or the trial began (stream time)
        self._tracker = _TrialTracker()
        self._stalled = False

    @property
    def done(self) -> bool:
        return self.phase == "done"

    def feed(self, t: float, block=None, calibrating: bool = False, stalled: bool = False) -> None:
        """Advance to stream time ``t`` (the newest frame's), given the step's ``block``
        (conditioned frames with ``t`` and ``cond.touched``, or None) and the skin's state."""
        if self.phase == "calibrating":
            start = self._calibration_start = (
                t if self._calibration_start is None else self._calibration_start
            )
            if t - start > self.plan.calibration_timeout_s:
                raise RecordAborted("calibration did not finish (is the skin streaming?)")
            if not calibrating:
                self._next(t)
        elif self.phase == "countdown":
            if t - self._t0 >= self.plan.countdown_s:
                if callable(self.perform):
                    self.perform(self.queue[self.index])
                self.phase, self._t0 = "trial", t
                self._tracker, self._stalled = _TrialTracker(), False
        elif self.phase == "trial":
            if block is not None:
                self._tracker.update(block.t, block.cond.touched)
            self._stalled = self._stalled or stalled
            end = self._t0 + self.plan.trial_s
            overrun = self._tracker.touching and t < end + self.plan.max_overrun_s
            if t >= end and not overrun:
                self._finish_trial(t)

    def prompt(self, t: float) -> Prompt:
        """What to show at stream time ``t``."""
        if self.phase in ("calibrating", "done"):
            return Prompt(self.phase, total=self.total)
        label = self.queue[self.index]
        number = min(self.index, self.total - 1) + 1
        length = self.plan.countdown_s if self.phase == "countdown" else self.plan.trial_s
        left = max(0.0, length - (t - self._t0))
        return Prompt(self.phase, label, prompt_for(label, self.prompts), number, self.total, left)

    def _next(self, t: float) -> None:
        """Count down to the next trial from ``t``, or end."""
        self.phase = "countdown" if self.index < len(self.queue) else "done"
        self._t0 = t

    def _finish_trial(self, t: float) -> None:
        label, tracker = self.queue[self.index], self._tracker
        result = TrialResult(label, self._t0, t, tracker.first, tracker.last, self._stalled)
        self.trials.append(result)
        self.writer.add_label(
            label,
            result.contact_start_s if result.contact_start_s is not None else result.prompt_start_s,
            result.contact_end_s if result.contact_end_s is not None else result.prompt_end_s,
            kind="trial",
            prompt_start_s=result.prompt_start_s,
            prompt_end_s=result.prompt_end_s,
            contact_found=result.contact_start_s is not None,
            interrupted=result.interrupted,
        )
        if result.interrupted and self.index not in self._retried:
            self._retried.add(self.index)
            self.queue.append(label)
            number = f"{min(self.index, self.total - 1) + 1} of {self.total}"
            self.messages.append(f"trial {number} was interrupted; it will be repeated")
        self.index += 1
        self._next(t)


class _Session:
    """``wovenskin record``'s front end: steps the skin, draws the driver's prompt and the
    heatmap in the terminal (at most every 0.04 s of stream time) and feeds the driver."""

    def __init__(self, live_skin, driver: RecordDriver, live, messages: list[str]) -> None:
        self.skin = live_skin
        self.driver = driver
        self.live = live
        self.messages = messages
        self._last_draw = -1.0

    def run(self) -> None:
        while not self.driver.done:
            t, block = self._pump(prompt_text(self.driver.prompt(self.skin.state.t)))
            state = self.skin.state
            self.driver.feed(t, block, state.calibrating, state.stalled)

    def _pump(self, prompt: Text) -> tuple[float, object]:
        block = self.skin.step(timeout=0.02)
        state = self.skin.state
        if state.ended:
            raise RecordAborted("the skin source ended")
        if state.t - self._last_draw >= 0.04 or self._last_draw < 0:
            self._last_draw = state.t
            self.live.update(self._render(prompt), refresh=True)
        return state.t, block

    def _render(self, prompt: Text) -> Group:
        state = self.skin.state
        shape = (self.skin.info.rows, self.skin.info.cols)
        heat = heatmap(state.signal, state.contacts, shape=shape)
        footer = Text("\n".join(self.messages[-3:]), style="dim")
        return Group(Panel(prompt, title="wovenskin record"), heat, footer)


def prompt_text(prompt: Prompt) -> Text:
    """The terminal's rendering of a :class:`Prompt`."""
    if prompt.phase == "calibrating":
        return Text("Calibrating: keep hands off the skin", style="bold yellow")
    text = Text(f"Trial {prompt.number} of {prompt.total}\n", style="bold")
    if prompt.phase == "countdown":
        text.append(f"Next: {prompt.what}\n", style="bold cyan")
        text.append(f"get ready... {prompt.seconds_left:0.1f} s", style="yellow")
    elif prompt.phase == "trial":
        text.append(f"NOW: {prompt.what}\n", style="bold green")
        text.append(f"{prompt.seconds_left:0.1f} s left", style="green")
    return text


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return ""
