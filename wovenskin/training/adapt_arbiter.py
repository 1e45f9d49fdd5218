"""Scoring a model on a person's held-out trials and choosing its execution settings.

``wovenskin adapt`` chooses the arbiter's confidence floor (``min_probability``) and its
hysteresis (``keep_probability``) for the adapted model among :func:`candidates`.  The
trials it trained on cannot tell (there every setting looks perfect), so the choice is
made on held-out trials and *cross-fitted* so that the report stays honest:

- the model runs once over every stream (conditioning, streaming windows, the "being
  performed" flag; :func:`record_streams`); each candidate's rules are then replayed on
  those recorded inputs (:func:`replay`), which is exactly what the live pipeline would
  have done under them, at a fraction of the cost;
- the candidate with the best :func:`merit` on held-out half 0 is scored on half 1, and
  the best on half 1 is scored on half 0; pooled, these are the reported "after" figures
  (no trial is scored by a setting chosen on it);
- the setting installed with the model is the best on both halves together;
- "best" charges each candidate :data:`DEPARTURE_COST` for how far it moves from the base
  model's setting, which was chosen on thousands of events: a dozen held-out trials are a
  noisy measure, and without a clear gain the base's setting stays.

:func:`merit` is one number for "better for the person at the skin": event F1 less
:data:`FALSE_ACTIVATION_COST` per false activation a minute, so one wrong move a minute
costs as much as 5 points of F1.  ``adapt`` also uses it to refuse a worse model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from wovenskin.recognition.arbiter import Arbiter, ArbiterSettings, CommandChange
from wovenskin.recognition.event_scoring import EventScores, aggregate
from wovenskin.recognition.pipeline import run_pipeline
from wovenskin.recording.formats import LabelledStream
from wovenskin.training.adapt_data import HELD_OUT, TrialSplit, score_held_out

STEPS: tuple[float, ...] = (-0.15, -0.1, -0.05, 0.0, 0.05, 0.1)
"""How far from the model's own ``min_probability`` the candidates go."""
KEEP_PROBABILITIES: tuple[float | None, ...] = (None, 0.5)


def candidates(start: ArbiterSettings) -> list[dict]:
    """The arbiter settings :func:`choose_arbiter` tries: ``min_probability`` within
    :data:`STEPS` of the base model's (chosen on thousands of events; a handful of held-out
    trials may move it, not replace it), each with and without the hysteresis
    ``keep_probability`` of 0.5."""
    # a base with no recommendation of its own (one trained without a stream evaluation)
    # is centred on 0.8, the middle of what the shipped models have used
    own = start.min_probability if start.min_probability >= 0.5 else 0.8
    floors = sorted({round(min(0.97, max(0.3, own + step)), 3) for step in STEPS})
    return [
        {"min_probability": p, "keep_probability": k}
        for p in floors
        for k in KEEP_PROBABILITIES
        if k is None or k < p
    ]


FALSE_ACTIVATION_COST = 0.05
"""F1 points one false activation per minute costs in :func:`merit`."""

Trials = Sequence[tuple[LabelledStream, TrialSplit]]


def merit(scores: EventScores) -> float:
    """Event F1 less :data:`FALSE_ACTIVATION_COST` x false activations per minute."""
    return scores.f1 - FALSE_ACTIVATION_COST * scores.false_per_min


@dataclass(frozen=True)
class Recorded:
    """The arbiter's inputs over one whole stream (see :attr:`LivePipeline.recorded`)."""

    class_names: tuple[str, ...]
    sample_rate_hz: float
    t: np.ndarray
    touched: np.ndarray
    performing: np.ndarray
    predicted: np.ndarray
    probabilities: np.ndarray


def record_streams(
    recognizer, streams: Trials, on_stream: Callable[[], None] | None = None
) -> list[Recorded]:
    """Run the model once over every stream and keep what its arbiter was fed."""
    out = []
    for stream, _ in streams:
        calls: list = []
        run_pipeline(stream, recognizer, record=calls)
        parts = [np.concatenate([np.asarray(c[i]) for c in calls]) for i in range(5)]
        out.append(Recorded(tuple(recognizer.class_names), float(stream.sample_rate_hz), *parts))
        if on_stream is not None:
            on_stream()
    return out


def replay(recorded: Recorded, settings: ArbiterSettings) -> list[CommandChange]:
    """The commands an arbiter with ``settings`` gives on recorded inputs."""
    arbiter = Arbiter(recorded.class_names, recorded.sample_rate_hz, settings)
    return arbiter.run(
        recorded.t, recorded.touched, recorded.performing, recorded.predicted,
        recorded.probabilities,
    )  # fmt: skip


def pooled(runs: Sequence[Sequence[CommandChange]], streams: Trials, folds=HELD_OUT) -> EventScores:
    """Event scores of ``runs`` on the trials of ``folds``, pooled over the streams."""
    return aggregate(
        score_held_out(commands, stream, split, folds)
        for commands, (stream, split) in zip(runs, streams, strict=True)
    )


def score_streams(
    recognizer, streams: Trials, arbiter: ArbiterSettings, on_stream=None
) -> EventScores:
    """Pooled held-out event scores of ``recognizer`` under ``arbiter``."""
    recorded = record_streams(recognizer, streams, on_stream)
    return pooled([replay(r, arbiter) for r in recorded], streams)


@dataclass(frozen=True)
class ArbiterChoice:
    """The installed settings, the cross-fitted held-out scores, and every candidate's."""

    settings: ArbiterSettings
    held_out: EventScores
    candidates: list[dict]


def _summary(s: EventScores) -> dict:
    return {"f1": s.f1, "false_activations_per_min": s.false_per_min,
            "median_latency_s": s.median_latency_s, "merit": merit(s)}  # fmt: skip


DEPARTURE_COST = 0.5
"""Merit a candidate gives up per unit of ``min_probability`` it moves from the base's
(0.05 for a step of 0.1), and for turning on the hysteresis (0.01): a handful of
held-out trials must show a clear gain before the base's well-measured setting is left."""


def _departure(candidate: dict, start: ArbiterSettings) -> float:
    moved = abs(candidate["min_probability"] - start.min_probability)
    return DEPARTURE_COST * moved + (0.01 if candidate["keep_probability"] is not None else 0.0)


def _best(options: list[tuple[int, EventScores, float]]) -> int:
    """The candidate with the best merit less its departure cost; ties: the lower median
    latency, then the later (stricter) candidate."""

    def key(option: tuple[int, EventScores, float]):
        index, s, cost = option
        latency = s.median_latency_s
        return (round(merit(s) - cost, 9), -(latency if latency is not None else 9e9), index)

    return max(options, key=key)[0]


def choose_arbiter(
    recognizer,
    streams: Trials,
    start: ArbiterSettings,
    on_stream: Callable[[], None] | None = None,
) -> ArbiterChoice:
    """Choose among :func:`candidates` around ``start`` (the base model's settings, whose
    other rules are kept) by cross-fitting on the held-out halves (module doc)."""
    recorded = record_streams(recognizer, streams, on_stream)
    scores: list[dict[str, EventScores]] = []
    settings = []
    tried = candidates(start)
    for candidate in tried:
        rules = replace(start, **candidate)
        runs = [replay(r, rules) for r in recorded]
        scores.append({
            "half_0": pooled(runs, streams, (0,)),
            "half_1": pooled(runs, streams, (1,)),
            "held_out": pooled(runs, streams),
        })  # fmt: skip
        settings.append(rules)

    costs = [_departure(candidate, start) for candidate in tried]

    def best(part: str) -> int:
        return _best([(i, s[part], costs[i]) for i, s in enumerate(scores)])

    crossed = aggregate([scores[best("half_0")]["half_1"], scores[best("half_1")]["half_0"]])
    table = [
        {**candidate, **{part: _summary(s) for part, s in row.items()}}
        for candidate, row in zip(tried, scores, strict=True)
    ]
    return ArbiterChoice(settings[best("held_out")], crossed, table)
