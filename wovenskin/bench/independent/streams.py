"""Labelled streams of the independent generator (``docs/formats.md``'s labelled stream).

A stream is one drawn :class:`~.people.Person` on one drawn :class:`~.skins.Skin`: at
least 1.2 s without contact (the calibration needs 0.5 s), then touches separated by idle
gaps, then a contact-free tail.  Each event is labelled from its first contact to its
last lift-off (``event_start_s``/``event_end_s``, as every labelled stream); the metadata
(``metadata["events"][i]``) adds its kind (``flick``, ``held_swipe``, ``push_smooth``,
``palm``, ...), its phases in stream seconds (``motion_start_s`` is where the motion
latency of :mod:`wovenskin.recognition.event_scoring` counts from; ``lift_end_s`` is the
last fingertip leaving the skin) and its drawn parameters.

What to perform is a list of *requests*: a class name (``swipe_up``), a swipe's variant
(``swipe_up:flick``, ``swipe_up:held`` for :data:`HELD_S`, ``swipe_up:held=3.5``), a
push's (``push:smooth``, ``push:land_press``), an invalid kind (``invalid:palm``) or an
idle gap (``idle:4``).  :func:`mixed_stream` draws a shuffled mixture of all of them;
:func:`gesture_stream` renders one touch alone.  The same seed gives identical arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from wovenskin.bench.independent.invalid import INVALID_KINDS, perform_invalid
from wovenskin.bench.independent.people import Person
from wovenskin.bench.independent.performers import DIRECTIONS, Trial, perform, push, swipe
from wovenskin.bench.independent.skins import Skin, SkinRenderer
from wovenskin.bench.independent.tracks import Touch
from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURE_NAMES, INVALID
from wovenskin.recording.formats import LabelledStream
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

GENERATOR = "wovenskin.bench.independent"
HELD_S = 2.5
"""How long a held swipe's finger stays still after the motion by default (s)."""
LEAD_S = (1.2, 2.0)
"""Contact-free time before the first touch."""


@dataclass(frozen=True)
class Request:
    """One parsed request: a touch (``name`` and ``variant``) or an idle gap."""

    name: str  # a class name or "idle"
    variant: str | None = None
    value: float | None = None  # a held swipe's hold, an idle gap's length

    @classmethod
    def parse(cls, text: str) -> Request:
        name, _, rest = text.strip().partition(":")
        variant, _, value_text = rest.partition("=")
        value = None
        if name == "idle":
            variant, value_text = None, rest
        if value_text:
            try:
                value = float(value_text)
            except ValueError:
                raise ConfigError(f"bad number in request {text!r}") from None
            if not (np.isfinite(value) and value >= 0):
                raise ConfigError(f"request {text!r} needs a non-negative number")
        if name == "idle":
            if value is None:
                raise ConfigError(f"an idle request needs its length, e.g. idle:2 (got {text!r})")
            return cls(name, None, value)
        if name not in (*GESTURE_NAMES, INVALID):
            raise ConfigError(f"unknown gesture {name!r} in request {text!r}")
        allowed: tuple[str, ...] = ()
        if name in {f"swipe_{d}" for d in DIRECTIONS}:
            allowed = ("flick", "held", "rest")
        elif name == "push":
            allowed = ("smooth", "land_press")
        elif name == INVALID:
            allowed = INVALID_KINDS
        if variant and variant not in allowed:
            known = ", ".join(allowed) or "none"
            raise ConfigError(f"{name} has no variant {variant!r} (known: {known})")
        return cls(name, variant or None, value)


def perform_request(request: Request, trial: Trial, layout: SkinLayout) -> Touch:
    """The touch a (non-idle) request asks for."""
    rng = trial.rng
    if request.name == INVALID:
        kind = request.variant or str(rng.choice(INVALID_KINDS))
        return perform_invalid(kind, trial, layout)
    if request.name.startswith("swipe_") and not request.name.endswith("_2f") and request.variant:
        direction = request.name.removeprefix("swipe_")
        rest = {
            "flick": 0.0,
            "held": HELD_S if request.value is None else request.value,
            "rest": float(rng.uniform(0.2, 1.5)) if request.value is None else request.value,
        }[request.variant]
        kind = {"flick": "flick", "held": "held_swipe", "rest": "swipe_rest"}[request.variant]
        return swipe(trial, layout, direction, rest, kind=kind)
    if request.name == "push" and request.variant:
        return push(trial, layout, smooth=request.variant == "smooth")
    return perform(request.name, trial, layout)


def render_stream(
    requests: Sequence[str],
    seed: int,
    *,
    layout: SkinLayout | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    idle_s: tuple[float, float] = (0.4, 3.0),
    tail_s: float = 2.0,
    seconds: float | None = None,
    extra_metadata: dict | None = None,
) -> LabelledStream:
    """Render ``requests`` in order on one drawn person and skin.

    Consecutive touches are ``idle_s`` apart (last lift-off to next first contact) unless
    an ``idle:S`` request sets the gap.  ``seconds`` caps the stream: touches that would not
    end ``tail_s`` before it are left out and the rest is padded contact-free; ``None``
    makes the stream as long as its touches plus ``tail_s``.
    """
    layout = layout if layout is not None else SkinLayout()
    if sample_rate_hz <= 0:
        raise ConfigError(f"sample rate must be positive, got {sample_rate_hz}")
    if seconds is not None and not (np.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"stream length must be positive, got {seconds}")
    parsed = [Request.parse(r) for r in requests]
    rng = np.random.default_rng(seed)
    person, skin = Person.draw(rng), Skin.draw(rng)
    renderer = SkinRenderer(skin, layout, sample_rate_hz)
    fs = sample_rate_hz
    placed: list[tuple[int, Touch, np.ndarray]] = []
    cursor = int(round(rng.uniform(*LEAD_S) * fs))  # the next first contact
    gap: float | None = None
    limit = None if seconds is None else int(round((seconds - tail_s) * fs))
    for request in parsed:
        if request.name == "idle":
            gap = (gap or 0.0) + float(request.value or 0.0)
            continue
        touch = perform_request(request, Trial(person, rng, fs), layout)
        first, end = touch.contact_span()
        if gap is not None and placed:
            cursor = placed[-1][0] + placed[-1][1].contact_span()[1] + int(round(gap * fs))
        offset = cursor - first
        if limit is not None and offset + end > limit:
            break
        placed.append((offset, touch, renderer.response(touch.fingers)))
        cursor = offset + end + int(round(rng.uniform(*idle_s) * fs))
        gap = None
    if seconds is not None:
        total = int(round(seconds * fs))
    else:
        last = max((o + len(r) for o, _, r in placed), default=0)
        total = max(last, max((o + t.contact_span()[1] for o, t, _ in placed), default=0))
        total = max(total + int(round(tail_s * fs)), int(round(LEAD_S[1] * fs)))
    change = np.zeros((total, *layout.shape))
    for offset, _, response in placed:
        n = min(len(response), total - offset)
        change[offset : offset + n] += response[:n]
    t = np.arange(total, dtype=np.float64) / fs
    events = []
    for offset, touch, _ in placed:
        phases = touch.phases.shifted(offset / fs)
        events.append(
            {
                "label": touch.label,
                "kind": touch.kind,
                "invalid_kind": touch.kind if touch.label == INVALID else None,
                "start_s": phases.landing_s,
                "end_s": phases.lift_end_s,
                "fingers": len(touch.fingers),
                "phases": phases.to_dict(),
                "params": touch.params,
            }
        )
    metadata = {
        "generator": GENERATOR,
        "seed": int(seed),
        "layout": layout.to_dict(),
        "skin": skin.to_dict(),
        "dead_channels": renderer.dead,
        "person": person.to_dict(),
        "requests": list(requests),
        "events": events,
        **(extra_metadata or {}),
    }
    return LabelledStream(
        frames=renderer.raw(change, t),
        t=t,
        sample_rate_hz=float(fs),
        event_start_s=np.array([e["start_s"] for e in events], dtype=np.float64),
        event_end_s=np.array([e["end_s"] for e in events], dtype=np.float64),
        event_labels=np.array([e["label"] for e in events], dtype=str),
        metadata=metadata,
    )


def mixed_requests(rng: np.random.Generator, n: int, invalid_fraction: float = 0.2) -> list[str]:
    """``n`` requests: the 14 gestures in shuffled rounds (swipes as flicks, swipes with a
    rest or held swipes; smooth or land-then-press pushes), invalid touches of every kind at
    ``invalid_fraction`` and an occasional long idle gap (3-8 s)."""
    out: list[str] = []
    deck: list[str] = []
    kinds: list[str] = []
    for _ in range(n):
        if rng.random() < 0.08:
            out.append(f"idle:{rng.uniform(3.0, 8.0):.2f}")
        if rng.random() < invalid_fraction:
            if not kinds:
                kinds = list(rng.permutation(INVALID_KINDS))
            out.append(f"invalid:{kinds.pop()}")
            continue
        if not deck:
            deck = list(rng.permutation(GESTURE_NAMES))
        name = str(deck.pop())
        if name in {f"swipe_{d}" for d in DIRECTIONS}:
            name += ":" + str(rng.choice(["flick", "flick", "rest", "rest", "held"]))
        elif name == "push":
            name += ":" + str(rng.choice(["smooth", "land_press"]))
        out.append(name)
    return out


def mixed_stream(
    seconds: float = 120.0,
    seed: int = 0,
    *,
    layout: SkinLayout | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    invalid_fraction: float = 0.2,
    idle_s: tuple[float, float] = (0.4, 3.0),
) -> LabelledStream:
    """``seconds`` of everything: gestures of all 14 classes in all variants, invalid
    touches and idle gaps, on one drawn person and skin."""
    if not 0.0 <= invalid_fraction <= 1.0:
        raise ConfigError(f"invalid_fraction must lie in [0, 1], got {invalid_fraction}")
    rng = np.random.default_rng([seed, 1])
    requests = mixed_requests(rng, max(1, int(seconds)), invalid_fraction)
    return render_stream(
        requests, seed, layout=layout, sample_rate_hz=sample_rate_hz, idle_s=idle_s,
        seconds=seconds, extra_metadata={"stream": "mixed", "invalid_fraction": invalid_fraction},
    )  # fmt: skip


def gesture_stream(
    request: str,
    seed: int,
    *,
    layout: SkinLayout | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    tail_s: float = 3.0,
) -> LabelledStream:
    """One touch alone (e.g. ``swipe_left:flick``, ``swipe_up:held``) after a contact-free
    lead, then ``tail_s`` without contact (time for the arm to come to rest)."""
    return render_stream(
        [request], seed, layout=layout, sample_rate_hz=sample_rate_hz, tail_s=tail_s,
        extra_metadata={"stream": "single"},
    )  # fmt: skip
