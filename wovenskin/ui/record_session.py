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
"""

from __future__ import annotations

import getpass
import platform
import random
import sys
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from rich.console import Console, Group
from rich.panel import Panel
from rich.text import Text

from wovenskin import __version__
from wovenskin.gestures import INVALID
from wovenskin.runtime.pipeline import open_live_skin
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.skin.frames import SkinInfo
from wovenskin.ui.terminal import heatmap, live_screen

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
            f"wrote {self.path}: {self.frames} frames, {len(self.trials)} labelled trials"
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
) -> SessionSummary:
    """Run a guided recording session into ``out`` and return what was recorded."""
    console = console or Console()
    messages: list[str] = []
    chain = open_live_skin(
        skin,
        conditioning=config,
        record=out,
        overwrite=overwrite,
        provenance=lambda info: _provenance(skin, info, provenance),
        recorded={"plan": asdict(plan)},
        on_message=messages.append,
    )
    source, live_skin, writer = chain.source, chain.live_skin, chain.recorder
    assert writer is not None
    summary = SessionSummary(Path(out), 0)
    perform = getattr(source, "perform", None)
    if isinstance(source, SimulatedSkinSource):
        source.autonomous = False  # the simulated person performs only what is prompted
    live_skin.start()
    try:
        with live_screen(console, auto_refresh=False) as live:
            _Session(live_skin, plan, writer, live, messages, perform, summary).run()
    except KeyboardInterrupt:
        summary.aborted = "interrupted by the user (Ctrl-C)"
        summary.interrupted = True
    except _Abort as exc:
        summary.aborted = str(exc)
    finally:
        live_skin.close()
        summary.frames = live_skin.stats().good_frames
        writer.close()
    return summary


def _provenance(skin: str, info: SkinInfo, given: dict | None) -> dict:
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


class _Abort(Exception):
    pass


class _Session:
    """The prompt/countdown/trial state machine, driven by stream time."""

    def __init__(self, live_skin, plan, writer, live, messages, perform, summary) -> None:
        self.skin = live_skin
        self.plan = plan
        self.writer = writer
        self.live = live
        self.messages = messages
        self.perform = perform
        self.summary = summary
        self._last_draw = -1.0

    def _pump(self, prompt: Text) -> tuple[float, object]:
        block = self.skin.step(timeout=0.02)
        state = self.skin.state
        if state.ended:
            raise _Abort("the skin source ended")
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

    def run(self) -> None:
        self._calibrate()
        queue = self.plan.trials()
        total = len(queue)
        retried: set[int] = set()
        index = 0
        while index < len(queue):
            label = queue[index]
            number = f"{min(index, total - 1) + 1} of {total}"
            result = self._trial(label, number)
            self.summary.trials.append(result)
            self.writer.add_label(
                label,
                result.contact_start_s
                if result.contact_start_s is not None
                else result.prompt_start_s,
                result.contact_end_s if result.contact_end_s is not None else result.prompt_end_s,
                kind="trial",
                prompt_start_s=result.prompt_start_s,
                prompt_end_s=result.prompt_end_s,
                contact_found=result.contact_start_s is not None,
                interrupted=result.interrupted,
            )
            if result.interrupted and index not in retried:
                retried.add(index)
                queue.append(label)
                self.messages.append(f"trial {number} was interrupted; it will be repeated")
            index += 1

    def _calibrate(self) -> None:
        start = None
        while self.skin.state.calibrating:
            t, _ = self._pump(Text("Calibrating: keep hands off the skin", style="bold yellow"))
            start = t if start is None else start
            if t - start > self.plan.calibration_timeout_s:
                raise _Abort("calibration did not finish (is the skin streaming?)")

    def _wait(self, seconds: float, prompt_fn) -> None:
        t0 = self.skin.state.t
        while True:
            t, _ = self._pump(prompt_fn(max(0.0, seconds - (self.skin.state.t - t0))))
            if t - t0 >= seconds:
                return

    def _trial(self, label: str, number: str) -> TrialResult:
        what = INVALID_PROMPT if label == INVALID else label.replace("_", " ")

        def countdown(left: float) -> Text:
            text = Text(f"Trial {number}\n", style="bold")
            text.append(f"Next: {what}\n", style="bold cyan")
            text.append(f"get ready... {left:0.1f} s", style="yellow")
            return text

        self._wait(self.plan.countdown_s, countdown)
        if callable(self.perform):
            self.perform(label)
        tracker = _TrialTracker()
        stalled = False
        t0 = self.skin.state.t
        end = t0 + self.plan.trial_s
        while True:
            left = end - self.skin.state.t
            text = Text(f"Trial {number}\n", style="bold")
            text.append(f"NOW: {what}\n", style="bold green")
            text.append(f"{max(0.0, left):0.1f} s left", style="green")
            t, block = self._pump(text)
            if block is not None:
                tracker.update(block.t, block.cond.touched)
            stalled = stalled or self.skin.state.stalled
            overrun = tracker.touching and t < end + self.plan.max_overrun_s
            if t >= end and not overrun:
                break
        return TrialResult(label, t0, self.skin.state.t, tracker.first, tracker.last, stalled)


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return ""
