"""``wovenskin bench recognition``: the live pipeline on unseen simulated streams, by condition.

A fixed robustness suite.  Each *condition* is a named recipe of simulator overrides laid
over a randomly drawn person and skin; each of its streams is simulated fresh, in memory,
from its own seed, and goes through the whole live pipeline exactly as ``wovenskin
eval-stream`` runs a stream file (:func:`~wovenskin.recognition.pipeline.run_pipeline`:
calibration, conditioning with the model's settings, streaming recogniser, arbiter with the
model's recommended execution rules), then is scored by
:mod:`~wovenskin.recognition.event_scoring`.

The conditions, their seeds and how each stream is made are :mod:`.conditions`'.

Figures per condition and pooled (``aggregate`` over every stream of every condition; all
keys of :meth:`EventScores.to_dict
<wovenskin.recognition.event_scoring.EventScores.to_dict>`, plus):

- ``p90_latency_s``: the 90th percentile of the latency from first contact (None: none);
- ``p90_motion_latency_s``: the same from the start of the characteristic motion;

and in the JSON document (:meth:`RecognitionBenchResult.to_dict`): ``model``, ``settings``
(``every`` and the arbiter's settings), ``suite`` (``base_seed``, ``streams_per_condition``,
``seconds``, ``conditions``), ``conditions`` (name -> ``description``, ``seeds``, the
figures and ``per_stream``: each stream's seed and main figures), ``pooled`` (the figures),
``worst_condition`` (``name``, ``f1``), ``targets`` (a list of ``name``, ``value``,
``target``, ``comparison``, ``passed``), ``passed`` (all targets met), ``warnings``
(calibration warnings, prefixed by condition and seed), and the times ``wall_s``,
``simulate_s`` and ``pipeline_s``.

Targets (:data:`TARGETS`): pooled event F1 >= 0.97, false activations <= 0.5 per minute,
median latency <= 150 ms from the motion start and <= 250 ms from first contact, and no
condition below event F1 0.93.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from rich import box
from rich.console import Group
from rich.table import Table
from rich.text import Text

from wovenskin.bench.conditions import (
    CONDITIONS,
    DEFAULT_SECONDS,
    condition_names,
    make_stream,
    stream_seed,
)
from wovenskin.errors import ConfigError
from wovenskin.recognition.event_scoring import EventScores, aggregate, score_stream
from wovenskin.recognition.pipeline import (
    pipeline_settings_for_model,
    run_pipeline,
)

DEFAULT_BASE_SEED = 9000
DEFAULT_STREAMS_PER_CONDITION = 3

ProgressCallback = Callable[[int, int, str], None]
"""``progress(streams done, streams in all, what runs next)``."""


@dataclass(frozen=True)
class Target:
    """A figure the bench checks: ``value >= threshold`` (``at_least``) or ``<=``."""

    name: str
    threshold: float
    at_least: bool
    unit_scale: float = 1.0  # shown as value * scale (e.g. 1000 for ms)
    unit: str = ""

    def passed(self, value: float | None) -> bool:
        if value is None:
            return False
        return value >= self.threshold if self.at_least else value <= self.threshold

    @property
    def comparison(self) -> str:
        return ">=" if self.at_least else "<="

    def text(self) -> str:
        return f"{self.comparison} {self.threshold * self.unit_scale:g}{self.unit}"


TARGETS: tuple[Target, ...] = (
    Target("f1", 0.97, at_least=True),
    Target("false_activations_per_min", 0.5, at_least=False),
    Target("median_motion_latency_s", 0.150, at_least=False, unit_scale=1000, unit=" ms"),
    Target("median_latency_s", 0.250, at_least=False, unit_scale=1000, unit=" ms"),
    Target("worst_condition_f1", 0.93, at_least=True),
)
"""Pooled targets, and the least F1 of any condition (``worst_condition_f1``)."""


def _p90(values: Sequence[float]) -> float | None:
    return float(np.percentile(values, 90)) if len(values) else None


def figures(scores: EventScores) -> dict:
    """The scores' :meth:`to_dict` plus the p90 latencies (see the module doc)."""
    return {
        **scores.to_dict(),
        "p90_latency_s": _p90(scores.latencies_s),
        "p90_motion_latency_s": _p90(scores.motion_latencies_s),
    }


@dataclass
class StreamRun:
    """One stream of the suite and its scores."""

    seed: int
    scores: EventScores

    def to_dict(self) -> dict:
        s = self.scores
        return {
            "seed": self.seed,
            "events": s.n_events,
            "detected": s.n_detected,
            "false_activations": s.n_false,
            "duplicates": s.n_duplicates,
            "f1": s.f1,
            "median_latency_s": s.median_latency_s,
            "median_motion_latency_s": s.median_motion_latency_s,
        }


@dataclass
class ConditionRun:
    """The streams of one condition and their pooled scores."""

    name: str
    description: str
    streams: list[StreamRun] = field(default_factory=list)

    @property
    def scores(self) -> EventScores:
        return aggregate(s.scores for s in self.streams)

    def to_dict(self) -> dict:
        return {
            "description": self.description,
            "seeds": [s.seed for s in self.streams],
            **figures(self.scores),
            "per_stream": [s.to_dict() for s in self.streams],
        }


@dataclass
class RecognitionBenchResult:
    """Figures of one run of the suite (see the module doc)."""

    model: str
    settings: dict
    base_seed: int
    streams_per_condition: int
    seconds: float
    conditions: list[ConditionRun]
    wall_s: float = 0.0
    simulate_s: float = 0.0
    pipeline_s: float = 0.0
    warnings: list[str] = field(default_factory=list)

    @property
    def pooled(self) -> EventScores:
        return aggregate(s.scores for c in self.conditions for s in c.streams)

    @property
    def worst_condition(self) -> tuple[str, float] | None:
        """The condition with the lowest event F1 (the first of a tie) and its F1."""
        if not self.conditions:
            return None
        worst = min(self.conditions, key=lambda c: c.scores.f1)
        return worst.name, worst.scores.f1

    def target_values(self) -> dict[str, float | None]:
        pooled = figures(self.pooled)
        worst = self.worst_condition
        values = {t.name: pooled.get(t.name) for t in TARGETS}
        values["worst_condition_f1"] = worst[1] if worst is not None else None
        return values

    def targets(self) -> list[dict]:
        values = self.target_values()
        return [
            {
                "name": t.name,
                "value": values[t.name],
                "target": t.threshold,
                "comparison": t.comparison,
                "passed": t.passed(values[t.name]),
            }
            for t in TARGETS
        ]

    @property
    def passed(self) -> bool:
        return all(t["passed"] for t in self.targets())

    def to_dict(self) -> dict:
        worst = self.worst_condition
        return {
            "benchmark": "recognition",
            "model": self.model,
            "settings": dict(self.settings),
            "suite": {
                "base_seed": self.base_seed,
                "streams_per_condition": self.streams_per_condition,
                "seconds": self.seconds,
                "conditions": [c.name for c in self.conditions],
            },
            "conditions": {c.name: c.to_dict() for c in self.conditions},
            "pooled": figures(self.pooled),
            "worst_condition": None if worst is None else {"name": worst[0], "f1": worst[1]},
            "targets": self.targets(),
            "passed": self.passed,
            "warnings": list(self.warnings),
            "wall_s": self.wall_s,
            "simulate_s": self.simulate_s,
            "pipeline_s": self.pipeline_s,
        }

    def table(self):
        """Per-condition and pooled figures, the targets beside the pooled ones, and times."""

        def ms(median: float | None, p90: float | None) -> str:
            if median is None or p90 is None:
                return "-"
            return f"{1000 * median:.0f}/{1000 * p90:.0f}"

        table = Table(
            title=(
                f"bench recognition: {self.streams_per_condition} x {self.seconds:g} s unseen "
                f"streams per condition"
            ),
            caption="FA: false activations; latency ms (median/p90) from first contact and "
            "from the start of the motion",
            box=box.SIMPLE_HEAD,
            show_edge=False,
            padding=(0, 1, 0, 0),
        )
        table.add_column("condition", no_wrap=True)
        for name in ("events", "hits", "prec", "recall", "F1", "FA/min", "contact\nms"):
            table.add_column(name, justify="right", no_wrap=True)
        table.add_column("motion\nms", justify="right", no_wrap=True)

        def row(name: str, s: EventScores, style: str | None = None) -> None:
            f = figures(s)
            table.add_row(
                name,
                *s.table_cells(),
                ms(f["median_latency_s"], f["p90_latency_s"]),
                ms(f["median_motion_latency_s"], f["p90_motion_latency_s"]),
                style=style,
            )

        for c in self.conditions:
            row(c.name, c.scores)
        table.add_section()
        row("pooled", self.pooled, style="bold")

        targets = Table(
            "pooled figure", "value", "target", "", title="targets", box=box.SIMPLE_HEAD
        )
        worst = self.worst_condition
        labels = {
            "f1": "event F1",
            "false_activations_per_min": "false activations / min",
            "median_motion_latency_s": "median latency from motion start",
            "median_latency_s": "median latency from first contact",
            "worst_condition_f1": "worst condition's F1"
            + (f" ({worst[0]})" if worst is not None else ""),
        }
        by_name = {t.name: t for t in TARGETS}
        for check in self.targets():
            target = by_name[check["name"]]
            value = check["value"]
            shown = "-" if value is None else f"{value * target.unit_scale:.3g}{target.unit}"
            if target.name == "false_activations_per_min" and value is not None:
                shown = f"{value:.2f}"
            verdict = Text("pass", "green") if check["passed"] else Text("miss", "bold red")
            targets.add_row(labels[check["name"]], shown, target.text(), verdict)
        overall = "all targets met" if self.passed else "targets missed"
        times = Text(
            f"{overall}; wall time {self.wall_s:.1f} s (simulation {self.simulate_s:.1f} s, "
            f"pipeline {self.pipeline_s:.1f} s); base seed {self.base_seed}; settings "
            + ", ".join(
                f"{k} {'off' if v is None else format(v, 'g')}" for k, v in self.settings.items()
            )
        )
        return Group(table, targets, times)


def run_recognition_benchmark(
    recognizer: Any,
    settings: Any = None,
    conditions: str | Sequence[str] | None = None,
    streams_per_condition: int = DEFAULT_STREAMS_PER_CONDITION,
    seconds: float = DEFAULT_SECONDS,
    base_seed: int = DEFAULT_BASE_SEED,
    progress: ProgressCallback | None = None,
) -> RecognitionBenchResult:
    """Run the suite (or the named ``conditions``) through the live pipeline and score it.

    ``settings`` (a :class:`~wovenskin.recognition.pipeline.PipelineSettings`) defaults to
    the model's recommended execution rules, as ``eval-stream`` runs without options.
    """
    if not (isinstance(streams_per_condition, int) and streams_per_condition >= 1):
        raise ConfigError(f"streams per condition must be >= 1, got {streams_per_condition!r}")
    if not (np.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"stream length must be positive, got {seconds}")
    names = condition_names(conditions)
    index = {name: i for i, name in enumerate(CONDITIONS)}
    if settings is None:
        settings = pipeline_settings_for_model(recognizer)
    checkpoint = getattr(recognizer, "checkpoint_dir", None)
    result = RecognitionBenchResult(
        model=str(checkpoint.resolve()) if checkpoint is not None else type(recognizer).__name__,
        settings={"every": settings.every, **asdict(settings.arbiter)},
        base_seed=int(base_seed),
        streams_per_condition=streams_per_condition,
        seconds=float(seconds),
        conditions=[],
    )
    total = len(names) * streams_per_condition
    started = time.perf_counter()
    done = 0
    for name in names:
        run = ConditionRun(name, CONDITIONS[name].description)
        result.conditions.append(run)
        for j in range(streams_per_condition):
            seed = stream_seed(base_seed, index[name], j)
            if progress is not None:
                progress(done, total, f"{name} #{j + 1}")
            t0 = time.perf_counter()
            stream = make_stream(name, seed, seconds)
            t1 = time.perf_counter()

            def warn(message: str, where: str = f"{name} seed {seed}") -> None:
                result.warnings.append(f"{where}: {message}")

            output = run_pipeline(stream, recognizer, settings, on_warning=warn)
            result.simulate_s += t1 - t0
            result.pipeline_s += time.perf_counter() - t1
            run.streams.append(StreamRun(seed, score_stream(output.commands, stream)))
            done += 1
    if progress is not None:
        progress(done, total, "done")
    result.wall_s = time.perf_counter() - started
    return result
