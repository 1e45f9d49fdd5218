"""Scoring a command log against a stream's labelled events (issue 3, section 4).

Definitions (``tolerance_s`` = 0.1 s by default):

- *Activation*: a command-log entry whose gesture is not null and differs from the
  command before it (repeated lines are not new activations).  A flick (the arbiter's
  reason ``"flick"``: a command and its end on the same frame, at the lift) is an
  activation like any other, so it detects its gesture's event -- or is a false
  activation.
- An event's *window* is ``[start, end + tolerance_s]``: from its first contact to
  ``tolerance_s`` after its last lift-off, both ends included.
- *Matching*: valid (non-``invalid``) events are taken in order of their start; each is
  matched to the earliest not yet matched activation *of its own class* inside its
  window.  A matched event is *detected*; its *latency* is activation time minus event
  start (first contact).  Each activation matches at most one event.
- Every activation that is not matched is either a *duplicate* -- of the class of a
  detected event and inside that event's window (the same command issued again, e.g.
  after a brief lift of one finger) -- or a *false activation* (a wrong class during an
  event, anything during an ``invalid`` event, anything outside all windows).
- Precision = detected / activations (duplicates count against it); recall = detected /
  valid events; F1 = ``2 TP / (2 TP + FP + FN)`` with TP = detected, FP = false
  activations + duplicates, FN = missed events.  A ratio with nothing to count (no
  activations, no events) is 1.0.
- False activations per minute: false activations (duplicates excluded: the right
  command issued again is no wrong robot motion) over the stream's length.
- Median latency: the median over detected events (``None`` when none).
- *Motion latency*: where the start of each event's characteristic motion is known
  (simulated streams record it per event in ``metadata["events"][i]["phases"]
  ["motion_start_s"]``; see :func:`motion_starts`), a detected event also records its
  activation time minus its motion start.  It may be negative (a command issued before the
  fingers begin to move, e.g. a push recognised from its landing).  The median over the
  events with a known motion start is ``None`` when there are none.
- ``invalid`` events are not detected or missed; ``invalid_acted`` counts those with any
  activation inside their window (all such activations are false activations).
- Event labels must be wovenskin's 15 classes: a stream with any other label (a typo,
  another project's gesture) is refused with a ``ValueError`` rather than scored, since
  no command could ever match it and it would silently count as a miss.

:func:`aggregate` pools several streams: counts and durations add up, latencies are pooled
before taking the median (not a median of medians); so do motion latencies.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from wovenskin.gestures import INVALID, known_classes
from wovenskin.recognition.commandlog import CommandLike, changes_only
from wovenskin.recording.formats import LabelledStream

DETECTION_TOLERANCE_S = 0.1
"""How long after an event's last lift-off its activation still counts."""


@dataclass
class ClassCounts:
    """Valid events of one class and how many were detected."""

    events: int = 0
    detected: int = 0

    @property
    def recall(self) -> float:
        return self.detected / self.events if self.events else 1.0


@dataclass
class EventScores:
    """Event-level scores of one stream or, aggregated, of several."""

    n_events: int = 0
    n_detected: int = 0
    n_activations: int = 0
    n_false: int = 0
    n_duplicates: int = 0
    n_invalid_events: int = 0
    n_invalid_acted: int = 0
    duration_s: float = 0.0
    latencies_s: list[float] = field(default_factory=list)
    motion_latencies_s: list[float] = field(default_factory=list)
    per_class: dict[str, ClassCounts] = field(default_factory=dict)
    false_by_gesture: dict[str, int] = field(default_factory=dict)
    n_streams: int = 1

    @property
    def n_missed(self) -> int:
        return self.n_events - self.n_detected

    @property
    def precision(self) -> float:
        return self.n_detected / self.n_activations if self.n_activations else 1.0

    @property
    def recall(self) -> float:
        return self.n_detected / self.n_events if self.n_events else 1.0

    @property
    def f1(self) -> float:
        tp, fp, fn = self.n_detected, self.n_false + self.n_duplicates, self.n_missed
        return 2 * tp / (2 * tp + fp + fn) if (tp or fp or fn) else 1.0

    @property
    def false_per_min(self) -> float:
        return self.n_false / (self.duration_s / 60.0) if self.duration_s > 0 else 0.0

    @property
    def median_latency_s(self) -> float | None:
        return float(np.median(self.latencies_s)) if self.latencies_s else None

    @property
    def median_motion_latency_s(self) -> float | None:
        """Median activation time after the motion start (None: no motion start known)."""
        latencies = self.motion_latencies_s
        return float(np.median(latencies)) if latencies else None

    def table_cells(self) -> list[str]:
        """Events, hits, precision, recall, F1 and false activations per minute, as the
        tables that show event scores print them."""
        return [
            str(self.n_events),
            str(self.n_detected),
            f"{self.precision:.3f}",
            f"{self.recall:.3f}",
            f"{self.f1:.3f}",
            f"{self.false_per_min:.2f}",
        ]

    def to_dict(self) -> dict:
        return {
            "streams": self.n_streams,
            "duration_s": self.duration_s,
            "events": self.n_events,
            "detected": self.n_detected,
            "missed": self.n_missed,
            "activations": self.n_activations,
            "false_activations": self.n_false,
            "duplicates": self.n_duplicates,
            "invalid_events": self.n_invalid_events,
            "invalid_events_acted_on": self.n_invalid_acted,
            "precision": self.precision,
            "recall": self.recall,
            "f1": self.f1,
            "false_activations_per_min": self.false_per_min,
            "median_latency_s": self.median_latency_s,
            "median_motion_latency_s": self.median_motion_latency_s,
            "per_class_recall": {k: v.recall for k, v in sorted(self.per_class.items())},
            "per_class_events": {k: v.events for k, v in sorted(self.per_class.items())},
            "false_by_gesture": dict(sorted(self.false_by_gesture.items())),
        }


def _events(
    starts: Sequence[float],
    ends: Sequence[float],
    labels: Sequence[str],
    known: Iterable[str] = (),
) -> tuple[np.ndarray, np.ndarray, list[str]]:
    starts = np.asarray(starts, dtype=np.float64).reshape(-1)
    ends = np.asarray(ends, dtype=np.float64).reshape(-1)
    labels = [str(label) for label in np.asarray(labels).reshape(-1)]
    if not len(starts) == len(ends) == len(labels):
        raise ValueError(
            f"events need as many starts, ends and labels; got {len(starts)}, {len(ends)}, "
            f"{len(labels)}"
        )
    if not (np.isfinite(starts).all() and np.isfinite(ends).all()):
        raise ValueError("event times must be finite")
    if (ends < starts).any():
        k = int(np.flatnonzero(ends < starts)[0])
        raise ValueError(f"event {k} ends ({ends[k]:g} s) before it starts ({starts[k]:g} s)")
    names = known_classes(known)
    unknown = sorted({label for label in labels if label not in names})
    if unknown:  # no command can ever match them: scored, they would pass as plain misses
        raise ValueError(
            f"cannot score events labelled {', '.join(map(repr, unknown))}: not gestures "
            f"wovenskin knows ({', '.join(names)})"
        )
    return starts, ends, labels


def _motion_starts(motion_start_s: Sequence[float | None] | None, n: int) -> np.ndarray:
    """``(n,)`` motion starts with NaN where unknown (all NaN for ``None``)."""
    if motion_start_s is None:
        return np.full(n, np.nan)
    values = [np.nan if v is None else v for v in motion_start_s]
    out = np.asarray(values, dtype=np.float64).reshape(-1)
    if len(out) != n:
        raise ValueError(f"{len(out)} motion starts for {n} events")
    if np.isinf(out).any():
        raise ValueError("motion starts must be finite (NaN or None: unknown)")
    return out


def motion_starts(stream: LabelledStream) -> np.ndarray | None:
    """Each event's motion start (s) from a stream's metadata, NaN where unknown.

    Read from ``metadata["events"][i]["phases"]["motion_start_s"]`` as simulated streams
    record it; ``None`` when the metadata holds no such per-event list, or one that does not
    line up with the stream's events (another length, or another label at some position).
    """
    events = (stream.metadata or {}).get("events")
    labels = [str(label) for label in np.asarray(stream.event_labels).reshape(-1)]
    if not isinstance(events, list) or len(events) != len(labels):
        return None
    out = np.full(len(labels), np.nan)
    for i, (event, label) in enumerate(zip(events, labels, strict=True)):
        if not isinstance(event, dict):
            return None
        if "label" in event and str(event["label"]) != label:
            return None
        phases = event.get("phases")
        value = phases.get("motion_start_s") if isinstance(phases, dict) else None
        try:
            value = float(value)
        except (TypeError, ValueError):
            continue
        if math.isfinite(value):
            out[i] = value
    return out if np.isfinite(out).any() else None


def score_commands(
    commands: Iterable[CommandLike],
    event_start_s: Sequence[float],
    event_end_s: Sequence[float],
    event_labels: Sequence[str],
    duration_s: float,
    tolerance_s: float = DETECTION_TOLERANCE_S,
    motion_start_s: Sequence[float | None] | None = None,
    *,
    known: Iterable[str] = (),
) -> EventScores:
    """Score one stream's commands against its labelled events (see the module doc).

    ``motion_start_s`` (one per event, ``None``/NaN where unknown) adds motion latencies;
    ``known``: class names beyond the 15 built-in ones that events may carry (a model's
    custom gestures).
    """
    if not (math.isfinite(duration_s) and duration_s >= 0):
        raise ValueError(f"stream duration must be a non-negative number, got {duration_s}")
    if not (math.isfinite(tolerance_s) and tolerance_s >= 0):
        raise ValueError(f"tolerance must be a non-negative number, got {tolerance_s}")
    starts, ends, labels = _events(event_start_s, event_end_s, event_labels, known)
    motion = _motion_starts(motion_start_s, len(starts))
    activations = [(c.t, c.gesture) for c in changes_only(commands) if c.gesture is not None]
    scores = EventScores(duration_s=float(duration_s), n_activations=len(activations))
    matched = [False] * len(activations)
    detected_windows: list[tuple[float, float, str]] = []
    for k in np.argsort(starts, kind="stable"):
        label, start, stop = labels[k], starts[k], ends[k] + tolerance_s
        if label == INVALID:
            scores.n_invalid_events += 1
            if any(start <= t <= stop for t, _ in activations):
                scores.n_invalid_acted += 1
            continue
        counts = scores.per_class.setdefault(label, ClassCounts())
        counts.events += 1
        scores.n_events += 1
        for j, (t, gesture) in enumerate(activations):
            if not matched[j] and gesture == label and start <= t <= stop:
                matched[j] = True
                counts.detected += 1
                scores.n_detected += 1
                scores.latencies_s.append(float(t - start))
                if not np.isnan(motion[k]):
                    scores.motion_latencies_s.append(float(t - motion[k]))
                detected_windows.append((start, stop, label))
                break
    for j, (t, gesture) in enumerate(activations):
        if matched[j]:
            continue
        if any(g == gesture and a <= t <= b for a, b, g in detected_windows):
            scores.n_duplicates += 1
        else:
            scores.n_false += 1
            scores.false_by_gesture[gesture] = scores.false_by_gesture.get(gesture, 0) + 1
    return scores


def score_stream(
    commands: Iterable[CommandLike],
    stream: LabelledStream,
    tolerance_s: float = DETECTION_TOLERANCE_S,
    *,
    known: Iterable[str] = (),
) -> EventScores:
    """Score commands against a :class:`LabelledStream`'s events; its length from its frames
    (``known``: as :func:`score_commands`).

    Motion latencies are scored where the stream's metadata records the events' motion
    starts (:func:`motion_starts`).
    """
    duration = len(stream.t) / float(stream.sample_rate_hz)
    return score_commands(
        commands,
        stream.event_start_s,
        stream.event_end_s,
        stream.event_labels,
        duration,
        tolerance_s,
        motion_start_s=motion_starts(stream),
        known=known,
    )


def aggregate(scores: Iterable[EventScores]) -> EventScores:
    """Pool the scores of several streams (counts and durations add, latencies pool)."""
    total = EventScores(n_streams=0)
    for s in scores:
        total.n_streams += s.n_streams
        total.n_events += s.n_events
        total.n_detected += s.n_detected
        total.n_activations += s.n_activations
        total.n_false += s.n_false
        total.n_duplicates += s.n_duplicates
        total.n_invalid_events += s.n_invalid_events
        total.n_invalid_acted += s.n_invalid_acted
        total.duration_s += s.duration_s
        total.latencies_s.extend(s.latencies_s)
        total.motion_latencies_s.extend(s.motion_latencies_s)
        for name, counts in s.per_class.items():
            pooled = total.per_class.setdefault(name, ClassCounts())
            pooled.events += counts.events
            pooled.detected += counts.detected
        for name, count in s.false_by_gesture.items():
            total.false_by_gesture[name] = total.false_by_gesture.get(name, 0) + count
    return total


def _ms(latency: float | None) -> str:
    return "-" if latency is None else f"{1000 * latency:.0f}"


def scores_table(rows: Sequence[tuple[str, EventScores]], total: EventScores | None = None):
    """A Rich table: one row per ``(name, scores)`` and a pooled ``total`` row.

    It fits an 80-column console: the figures never wrap, a long stream name folds onto
    more lines of its own column."""
    from rich import box
    from rich.table import Table

    table = Table(
        box=box.SIMPLE_HEAD,
        show_edge=False,
        pad_edge=False,
        collapse_padding=True,
        title="event scores (FA: false activations; latency: median from first contact; "
        "motion: median from the start of the motion)",
    )
    table.add_column("stream", overflow="fold", min_width=8)
    for header in ("events", "hits", "prec", "recall", "F1", "FA/min", "dups"):
        table.add_column(header, justify="right", no_wrap=True)
    for header in ("latency ms", "motion ms"):  # the header wraps after its word
        table.add_column(header, justify="right")
    shown = list(rows) + ([("total", total)] if total is not None else [])
    for name, s in shown:
        table.add_row(
            name,
            *s.table_cells(),
            str(s.n_duplicates),
            _ms(s.median_latency_s),
            _ms(s.median_motion_latency_s),
            style="bold" if name == "total" and total is not None else None,
        )
    return table


def per_class_table(scores: EventScores):
    """A Rich table of per-class recall and of false activations by gesture."""
    from rich.table import Table

    table = Table("class", "events", "detected", "recall", "false activations", title="per class")
    names = sorted(set(scores.per_class) | set(scores.false_by_gesture))
    for name in names:
        counts = scores.per_class.get(name, ClassCounts())
        table.add_row(
            name,
            str(counts.events),
            str(counts.detected),
            f"{counts.recall:.3f}" if counts.events else "-",
            str(scores.false_by_gesture.get(name, 0)),
        )
    return table
