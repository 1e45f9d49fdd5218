"""``wovenskin bench gestures``: recognition and motion on independent labelled streams.

Issue 22: measured on people and skins made apart from :mod:`wovenskin.sim` (the
simulator that trained the shipped model), by :mod:`wovenskin.independent`.

- *Recognition:* ``streams`` mixed streams of ``seconds`` each (seeds ``seed``,
  ``seed + 1``, ...) through the whole live pipeline
  (:func:`~wovenskin.recognition.pipeline.run_pipeline`, exactly as ``wovenskin
  eval-stream``) scored by :mod:`wovenskin.recognition.event_scoring`: event F1,
  precision, recall, false activations per minute, the recall of every class, the median
  latency from first contact and from the start of the motion (the generator records it).
- *Motion:* flicks and held swipes, each its own stream, through a full control session on
  the simulated TM5-900 with the default mapping (:mod:`wovenskin.bench.gesture_motion`):
  the share that moved the arm, TCP travel, and after the release the brake start and the
  time until the TCP is at rest.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Group
from rich.table import Table

from wovenskin.bench.gesture_motion import GestureMotion, run_motion, summarise
from wovenskin.bench.results import BenchResult, figure_table
from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID
from wovenskin.independent import mixed_stream
from wovenskin.io import to_jsonable
from wovenskin.recognition.event_scoring import EventScores, aggregate, score_commands, score_stream
from wovenskin.recognition.pipeline import (
    PipelineSettings,
    pipeline_settings_for_model,
    run_pipeline,
)
from wovenskin.recording.formats import LabelledStream, write_labelled_stream

Progress = Callable[[str], None]

# The bench's defaults, each written once (``wovenskin bench gestures`` falls through to them).
DEFAULT_STREAMS = 4  # mixed independent streams for recognition
DEFAULT_SECONDS = 120.0  # length of each mixed stream
DEFAULT_BASE_SEED = 22000  # streams seed, seed+1, ...; flicks seed+1000+k; held seed+2000+k
DEFAULT_FLICKS = 40  # flicks through the simulated arm
DEFAULT_HELD = 14  # held swipes through the simulated arm
DEFAULT_HOLD_S = 2.5  # seconds a held swipe's finger stays still after the motion
DEFAULT_GAIN_SCALE = 1.0  # the mixed streams' skins at their drawn response


@dataclass
class GesturesBenchResult(BenchResult):
    model: str
    streams: int
    seconds: float
    seed: int
    recognition: dict[str, Any] = field(default_factory=dict)  # pooled EventScores.to_dict()
    per_stream: list[dict[str, Any]] = field(default_factory=list)
    recall_by_kind: dict[str, dict[str, Any]] = field(default_factory=dict)  # flick, push_smooth..
    motion: dict[str, dict[str, Any]] = field(default_factory=dict)  # per kind
    motion_runs: list[dict[str, Any]] = field(default_factory=list)
    hold_s: float = DEFAULT_HOLD_S
    gain_scale: float = DEFAULT_GAIN_SCALE
    wall_s: float = 0.0
    warnings: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return to_jsonable(super().to_dict())  # numpy scalars in drawn parameters

    def table(self) -> Group:
        parts: list[Any] = []
        if self.streams:
            parts += [self._recognition_table(), self._class_table(), self._kind_table()]
        if self.motion:
            parts.append(self._motion_table())
        return Group(*parts)

    def _recognition_table(self) -> Table:
        r = self.recognition
        table = figure_table(
            f"wovenskin bench gestures: recognition on {self.streams} independent mixed "
            f"streams of {self.seconds:g} s (seeds {self.seed}..{self.seed + self.streams - 1})"
        )
        table.add_row("events (valid / invalid)", f"{r['events']} / {r['invalid_events']}")
        table.add_row("event F1", f"{r['f1']:.3f}")
        table.add_row("precision / recall", f"{r['precision']:.3f} / {r['recall']:.3f}")
        table.add_row(
            "false activations per minute",
            f"{r['false_activations_per_min']:.2f} ({r['false_activations']} in "
            f"{r['duration_s'] / 60:.1f} min; {r['duplicates']} duplicates)",
        )
        table.add_row(
            "invalid touches acted on", f"{r['invalid_events_acted_on']} of {r['invalid_events']}"
        )
        table.add_row(
            "median latency from the start of the motion", _ms(r["median_motion_latency_s"])
        )
        table.add_row("median latency from first contact", _ms(r["median_latency_s"]))
        table.add_row("model", self.model)
        return table

    def _class_table(self) -> Table:
        table = Table("class", "events", "recall", "false activations", title="recall per class")
        recall, events = self.recognition["per_class_recall"], self.recognition["per_class_events"]
        false = self.recognition["false_by_gesture"]
        for name in sorted(set(recall) | set(false)):
            table.add_row(
                name,
                str(events.get(name, 0)),
                f"{recall[name]:.3f}" if name in recall else "-",
                str(false.get(name, 0)),
            )
        return table

    def _kind_table(self) -> Table:
        table = Table("kind", "events", "recall", title="recall per way of performing")
        for kind, counts in self.recall_by_kind.items():
            table.add_row(kind, str(counts["events"]), f"{counts['recall']:.3f}")
        return table

    def _motion_table(self) -> Table:
        table = Table(
            "kind",
            "streams",
            "recognised",
            "moved the arm",
            "TCP travel mm (median / p90)",
            "brake start after release s",
            "at rest after release s",
            title="motion on the simulated TM5-900 (default mapping; one gesture per stream; "
            "brake and rest times over the streams that moved; release: last fingertip off)",
        )
        for kind, m in self.motion.items():
            name = kind if kind != "held_swipe" else f"held swipe ({self.hold_s:g} s)"
            table.add_row(
                name,
                str(m["streams"]),
                f"{m['recognised']}",
                f"{m['moved']} ({100 * m['moved_share']:.0f} %)",
                _pair(m["travel_mm"], "{:.1f}"),
                _pair(m["brake_s"], "{:+.3f}"),
                _pair(m["rest_s"], "{:+.3f}")
                + (f"; {m['still_moving']} still moving" if m["still_moving"] else ""),
            )
        return table


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{1000 * seconds:.0f} ms"


def _pair(figures: dict[str, Any], fmt: str) -> str:
    if figures.get("median") is None:
        return "-"
    return f"{fmt.format(figures['median'])} / {fmt.format(figures['p90'])}"


def run_recognition(
    recognizer: Any,
    settings: PipelineSettings | None,
    streams: int,
    seconds: float,
    seed: int,
    progress: Progress | None = None,
    save_dir: Path | None = None,
    on_warning: Progress | None = None,
    gain_scale: float = DEFAULT_GAIN_SCALE,
) -> tuple[EventScores, list[dict[str, Any]]]:
    """Mixed independent streams through the live pipeline, scored event by event; each
    stream's skin responds ``gain_scale`` times as strongly as drawn."""
    rows, details = [], []
    for k in range(streams):
        stream_seed = seed + k
        if progress is not None:
            progress(f"mixed stream {k + 1} of {streams} (seed {stream_seed})")
        stream = mixed_stream(seconds, stream_seed, gain_scale=gain_scale)
        if save_dir is not None:
            write_labelled_stream(save_dir / f"mixed-{stream_seed}.npz", stream, overwrite=True)
        result = run_pipeline(stream, recognizer, settings, on_warning=on_warning)
        scores = score_stream(result.commands, stream)
        rows.append(scores)
        details.append(
            {"seed": stream_seed, **scores.to_dict(), "by_kind": by_kind(result.commands, stream)}
        )
    return aggregate(rows), details


def by_kind(commands: list[Any], stream: LabelledStream) -> dict[str, dict[str, int]]:
    """Valid events and detections per generator kind (``flick``, ``held_swipe``,
    ``push_smooth``, ...): each kind's events scored alone, which detects the same events
    as scoring them all since the generator's events are further apart than the
    tolerance."""
    kinds = [str(e["kind"]) for e in stream.metadata["events"]]
    labels = np.asarray(stream.event_labels).astype(str)
    out = {}
    for kind in sorted(set(kinds)):
        mask = np.array([k == kind for k in kinds]) & (labels != INVALID)
        if not mask.any():
            continue
        scores = score_commands(
            commands, stream.event_start_s[mask], stream.event_end_s[mask], labels[mask],
            len(stream.t) / stream.sample_rate_hz,
        )  # fmt: skip
        out[kind] = {"events": scores.n_events, "detected": scores.n_detected}
    return out


def pool_kinds(details: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per-kind events, detections and recall pooled over streams."""
    pooled: dict[str, dict[str, Any]] = {}
    for row in details:
        for kind, counts in row["by_kind"].items():
            into = pooled.setdefault(kind, {"events": 0, "detected": 0})
            into["events"] += counts["events"]
            into["detected"] += counts["detected"]
    for counts in pooled.values():
        counts["recall"] = counts["detected"] / counts["events"]
    return dict(sorted(pooled.items()))


def run_gestures_benchmark(
    recognizer: Any,
    settings: PipelineSettings | None = None,
    streams: int = DEFAULT_STREAMS,
    seconds: float = DEFAULT_SECONDS,
    seed: int = DEFAULT_BASE_SEED,
    flicks: int = DEFAULT_FLICKS,
    held: int = DEFAULT_HELD,
    hold_s: float = DEFAULT_HOLD_S,
    progress: Progress | None = None,
    save_dir: str | Path | None = None,
    gain_scale: float = DEFAULT_GAIN_SCALE,
) -> GesturesBenchResult:
    """Recognition on ``streams`` mixed streams and motion of ``flicks`` flicks and ``held``
    held swipes (``hold_s`` still after the motion); ``save_dir`` keeps every stream;
    ``gain_scale`` scales the mixed streams' skin response (a weak or a strong skin).
    ``settings`` default to the model's own (``pipeline_settings_for_model``)."""
    if settings is None:
        settings = pipeline_settings_for_model(recognizer)
    if streams < 0 or flicks < 0 or held < 0:
        raise ConfigError("--streams, --flicks and --held must be >= 0")
    if streams and not seconds >= 10.0:
        raise ConfigError(f"mixed streams must last at least 10 s, got {seconds:g}")
    if not 0.0 <= hold_s <= 30.0:
        raise ConfigError(f"--hold must lie in [0, 30] s, got {hold_s:g}")
    started = time.perf_counter()
    model = str(getattr(recognizer, "checkpoint_dir", "given recogniser"))
    result = GesturesBenchResult(model=model, streams=streams, seconds=seconds, seed=seed)
    result.hold_s = hold_s
    result.gain_scale = gain_scale
    folder = Path(save_dir) if save_dir is not None else None
    if folder is not None:  # never overwrite unasked: a new or empty folder
        if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
            raise ConfigError(f"{folder} is not an empty folder: give a new one to save streams")
        folder.mkdir(parents=True, exist_ok=True)
    if streams:
        total, details = run_recognition(
            recognizer, settings, streams, seconds, seed, progress, folder,
            on_warning=result.warnings.append, gain_scale=gain_scale,
        )  # fmt: skip
        result.recognition = total.to_dict()
        result.per_stream = details
        result.recall_by_kind = pool_kinds(details)
    if flicks or held:
        runs: list[GestureMotion] = run_motion(
            recognizer, flicks, held, seed, hold_s, progress, folder, settings
        )
        for kind in ("flick", "held_swipe"):
            of_kind = [r for r in runs if r.kind == kind]
            if of_kind:
                summary = summarise(kind, of_kind)
                result.motion[kind] = {**vars(summary), "moved_share": summary.moved_share}
        result.motion_runs = [r.to_dict() for r in runs]
    result.wall_s = time.perf_counter() - started
    return result
