"""``wovenskin bench adapt``: a person the model never saw, before and after ``adapt``.

Issue 23's measure of :mod:`wovenskin.training.adapt`.  For each of ``people`` people,
drawn with their skin by the independent generator (:mod:`wovenskin.independent`,
made apart from the simulator that trained the shipped model; a *weak* skin responds with
a fifth of a typical skin's change):

1. one labelled stream of ``adapt_seconds`` (the person's recording) is adapted on, timed;
2. ``test_streams`` further streams of the same person and skin (other trials, other
   noise) are scored by the whole live pipeline with the base model and with the adapted
   one (its own execution settings): event F1, false activations a minute, median latency
   from first contact, recall per class.

With ``custom`` the person also performs two gestures of their own (three-finger swipes
up and down, the example of ``docs/custom-gestures.md``), ``custom_rounds`` times as
often as each built-in one; adapt adds them as classes.  Their F1 is reported per class,
and the built-in classes' F1 (built-in events and activations only) beside the base
model's, which is what the custom classes may cost the others.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rich.table import Table

from wovenskin.bench.results import BenchResult
from wovenskin.custom_gestures import CustomGesture
from wovenskin.gestures import GESTURE_NAMES
from wovenskin.independent import mixed_stream
from wovenskin.independent.skins import WEAK_GAIN
from wovenskin.recognition.event_scoring import EventScores, aggregate, score_stream
from wovenskin.recognition.pipeline import (
    load_recognizer,
    pipeline_settings_for_model,
    run_pipeline,
)
from wovenskin.recording.formats import LabelledStream, write_labelled_stream
from wovenskin.training.adapt import AdaptRefused, adapt_model
from wovenskin.training.adapt_settings import AdaptSettings

CUSTOM: tuple[CustomGesture, ...] = (
    CustomGesture(
        "swipe_up_3f",
        3,
        "three fingers side by side, swipe up about 3 cm",
        strokes=(((0.0, 15.0), (0.0, -15.0)),),
    ),  # fmt: skip
    CustomGesture(
        "swipe_down_3f",
        3,
        "three fingers side by side, swipe down about 3 cm",
        strokes=(((0.0, -15.0), (0.0, 15.0)),),
    ),  # fmt: skip
)
"""The worked example of docs/custom-gestures.md."""

Progress = Callable[[str], None]


def class_f1(scores: EventScores, names: Sequence[str]) -> float:
    """Event F1 over the classes ``names`` only: their detections and misses, and the false
    activations of those gestures (duplicates are not split by class and left out)."""
    tp = sum(scores.per_class[n].detected for n in names if n in scores.per_class)
    events = sum(scores.per_class[n].events for n in names if n in scores.per_class)
    fp = sum(scores.false_by_gesture.get(n, 0) for n in names)
    fn = events - tp
    return 2 * tp / (2 * tp + fp + fn) if (tp or fp or fn) else 1.0


def _figures(scores: EventScores, custom: Sequence[str]) -> dict[str, Any]:
    out = {
        "f1": scores.f1,
        "false_activations_per_min": scores.false_per_min,
        "median_latency_s": scores.median_latency_s,
        "events": scores.n_events,
        "detected": scores.n_detected,
        "per_class_recall": {k: v.recall for k, v in sorted(scores.per_class.items())},
        "false_by_gesture": dict(sorted(scores.false_by_gesture.items())),
    }
    if custom:
        out["builtin_f1"] = class_f1(scores, GESTURE_NAMES)
        out["custom_f1"] = {name: class_f1(scores, [name]) for name in custom}
    return out


@dataclass
class AdaptBenchResult(BenchResult):
    people: int
    weak: bool
    adapt_seconds: float
    test_streams: int
    custom: list[str]
    runs: list[dict[str, Any]] = field(default_factory=list)
    base: dict[str, Any] = field(default_factory=dict)  # pooled over people
    adapted: dict[str, Any] = field(default_factory=dict)
    wall_s: float = 0.0

    def table(self) -> Table:
        title = (
            f"adapt on {self.adapt_seconds:g} s of each of {self.people} new "
            f"{'weak-skin ' if self.weak else ''}people; {self.test_streams} more streams each"
        )
        table = Table(title=title)
        table.add_column("figure")
        table.add_column("base", justify="right")
        table.add_column("adapted", justify="right")
        b, a = self.base, self.adapted

        def ms(value) -> str:
            return "-" if value is None else f"{1000 * value:.0f} ms"

        table.add_row("event F1", f"{b['f1']:.3f}", f"{a['f1']:.3f}")
        table.add_row(
            "false activations / min",
            f"{b['false_activations_per_min']:.2f}",
            f"{a['false_activations_per_min']:.2f}",
        )
        table.add_row("median latency", ms(b["median_latency_s"]), ms(a["median_latency_s"]))
        if self.custom:
            table.add_row(
                "built-in classes' F1", f"{b['builtin_f1']:.3f}", f"{a['builtin_f1']:.3f}"
            )
            for name in self.custom:
                table.add_row(f"{name} F1", f"{b['custom_f1'][name]:.3f}",
                              f"{a['custom_f1'][name]:.3f}")  # fmt: skip
        seconds = [r["adapt_s"] for r in self.runs]
        table.add_row("adapt wall time", "", f"{min(seconds):.0f}-{max(seconds):.0f} s")
        installed = sum(1 for r in self.runs if r["accepted"])
        table.add_row("adapted models installed", "", f"{installed} of {len(self.runs)}")
        return table


SEED = 23000
"""Person ``i`` (and their skin) is drawn with ``seed + i``; their streams with
``seed + 100 i + k``."""


def _stream(
    person: int, k: int, seconds: float, weak: bool, custom, rounds, seed: int = SEED
) -> LabelledStream:
    return mixed_stream(
        seconds, seed=seed + 100 * person + k, person_seed=seed + person,
        skin_seed=seed + person, gain=WEAK_GAIN if weak else None,
        custom=list(custom) or None, custom_rounds=rounds,
    )  # fmt: skip


def _score(model, streams: Sequence[LabelledStream], known: Sequence[str]) -> EventScores:
    recognizer = load_recognizer(model)
    settings = pipeline_settings_for_model(recognizer)
    return aggregate(
        score_stream(run_pipeline(s, recognizer, settings).commands, s, known=known)
        for s in streams
    )


def run_adapt_benchmark(
    out: Path,
    people: int = 2,
    weak: bool = True,
    adapt_seconds: float = 120.0,
    test_streams: int = 3,
    test_seconds: float = 120.0,
    custom: bool = False,
    custom_rounds: float = 3.0,
    base: Path | None = None,
    settings: AdaptSettings | None = None,
    progress: Progress | None = None,
    seed: int = SEED,
) -> AdaptBenchResult:
    """Run the benchmark of the module doc; recordings and models are kept under ``out``."""
    say = progress or (lambda what: None)
    started = time.monotonic()
    defs = CUSTOM if custom else ()
    names = [g.name for g in defs]
    result = AdaptBenchResult(people, weak, adapt_seconds, test_streams, names)
    base_parts, adapted_parts = [], []
    for person in range(people):
        folder = out / f"person-{person}"
        folder.mkdir(parents=True, exist_ok=True)
        say(f"person {person}: rendering streams")
        recording = folder / "recording.npz"
        write_labelled_stream(
            recording,
            _stream(person, 0, adapt_seconds, weak, defs, custom_rounds, seed),
            overwrite=True,
        )
        tests = [
            _stream(person, k, test_seconds, weak, defs, custom_rounds, seed)
            for k in range(1, test_streams + 1)
        ]
        say(f"person {person}: adapting")
        clock = time.monotonic()
        model_dir = folder / "model"
        try:
            report = adapt_model([recording], model_dir, base, settings)
        except AdaptRefused as refused:
            report = refused.report
        adapt_s = time.monotonic() - clock
        say(f"person {person}: scoring")
        used = model_dir if report.accepted else model_dir / "rejected"
        base_scores = _score(base, tests, names)
        adapted_scores = _score(used, tests, names)
        base_parts.append(base_scores)
        adapted_parts.append(adapted_scores)
        result.runs.append(
            {
                "person": person,
                "adapt_s": adapt_s,
                "accepted": report.accepted,
                "held_out": report.to_dict()["held_out_after"],
                "held_out_base": report.to_dict()["held_out_before"],
                "min_probability": report.arbiter.get("min_probability"),
                "keep_probability": report.arbiter.get("keep_probability"),
                "base": _figures(base_scores, names),
                "adapted": _figures(adapted_scores, names),
            }
        )
    result.base = _figures(aggregate(base_parts), names)
    result.adapted = _figures(aggregate(adapted_parts), names)
    result.wall_s = time.monotonic() - started
    return result
