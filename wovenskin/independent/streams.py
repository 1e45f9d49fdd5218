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
:func:`gesture_stream` renders one touch alone; :func:`perform_touch` performs one request
by a given person, unrendered (a live skin renders it: :mod:`.live`).  The same seed gives
identical arrays.

A user's own gestures (:class:`~wovenskin.custom_gestures.CustomGesture`, passed as
``custom``) are requested by name and performed from their stroke scripts
(:mod:`.strokes`); :func:`mixed_stream` mixes them in ``custom_rounds`` times as often as
each built-in gesture.  Every stream function takes ``person_seed`` / ``skin_seed`` (the
person / skin of the stream of that seed: several streams of the SAME person on the SAME
skin, their touches drawn from ``seed``), and ``gain`` / ``gain_scale`` to fix or scale the
skin's gain (:data:`~.skins.TYPICAL_GAIN`, :data:`~.skins.WEAK_GAIN`: a fifth of a typical
skin's change).  Left at their defaults, none of them changes a stream.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURE_NAMES, INVALID
from wovenskin.independent.invalid import INVALID_KINDS, perform_invalid
from wovenskin.independent.people import Person
from wovenskin.independent.performers import DIRECTIONS, Trial, perform, push, swipe
from wovenskin.independent.skins import Skin, SkinRenderer
from wovenskin.independent.strokes import perform_strokes
from wovenskin.independent.tracks import Touch
from wovenskin.recording.formats import LabelledStream
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

GENERATOR = "wovenskin.independent"
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
    def parse(cls, text: str, custom: Iterable[str] = ()) -> Request:
        """``text`` read; ``custom``: the names of the custom gestures that may be asked for."""
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
        if name not in (*GESTURE_NAMES, INVALID, *custom):
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


def perform_request(
    request: Request,
    trial: Trial,
    layout: SkinLayout,
    custom: Mapping[str, CustomGesture] | None = None,
) -> Touch:
    """The touch a (non-idle) request asks for (a custom gesture: from its strokes)."""
    rng = trial.rng
    if custom and request.name in custom:
        return perform_strokes(custom[request.name], trial, layout)
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


def perform_touch(
    request: str,
    person: Person,
    rng: np.random.Generator,
    *,
    layout: SkinLayout | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    custom: Mapping[str, CustomGesture] | Sequence[CustomGesture] | None = None,
) -> Touch:
    """One touch of ``request`` (a class name, a variant, ``invalid``, a custom gesture's
    name) by ``person``, its draws from ``rng``; what it cannot perform: one ConfigError."""
    definitions = _custom_table(custom)
    name = request.strip().partition(":")[0]
    if name not in (*GESTURE_NAMES, INVALID, *definitions):
        raise ConfigError(
            f"the independent generator cannot perform {request!r}: name a gesture class of "
            "docs/gestures.md, 'invalid' or a custom gesture it was given"
        )
    parsed = Request.parse(request, definitions)
    layout = layout if layout is not None else SkinLayout()
    return perform_request(parsed, Trial(person, rng, sample_rate_hz), layout, definitions)


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
    person_seed: int | None = None,
    skin_seed: int | None = None,
    gain: float | None = None,
    gain_scale: float = 1.0,
    custom: Mapping[str, CustomGesture] | Sequence[CustomGesture] | None = None,
) -> LabelledStream:
    """Render ``requests`` in order on one drawn person and skin.

    Consecutive touches are ``idle_s`` apart (last lift-off to next first contact) unless
    an ``idle:S`` request sets the gap.  ``seconds`` caps the stream: touches that would not
    end ``tail_s`` before it are left out and the rest is padded contact-free; ``None``
    makes the stream as long as its touches plus ``tail_s``.

    ``person_seed`` / ``skin_seed``: use the person / skin that the stream of that seed
    draws (:func:`person_of`, :func:`skin_of`) instead of this seed's; the touches, their
    order and the sensor noise still come from ``seed``.  ``gain`` fixes the skin's gain
    (relative change of a firmly covered channel), ``gain_scale`` multiplies it.
    ``custom``: custom gestures that requests may name.
    """
    layout = layout if layout is not None else SkinLayout()
    if sample_rate_hz <= 0:
        raise ConfigError(f"sample rate must be positive, got {sample_rate_hz}")
    if seconds is not None and not (np.isfinite(seconds) and seconds > 0):
        raise ConfigError(f"stream length must be positive, got {seconds}")
    definitions = _custom_table(custom)
    parsed = [Request.parse(r, definitions) for r in requests]
    rng = np.random.default_rng(seed)
    person, skin = Person.draw(rng), Skin.draw(rng)  # drawn always: the touches stay seed's
    if person_seed is not None:
        person = person_of(person_seed)
    if skin_seed is not None:
        skin = skin_of(skin_seed)
    skin = _with_gain(skin, gain, gain_scale)
    # The same skin in streams of other seeds: its channel maps, its own noise per stream.
    noise_seed = seed if skin_seed is not None and skin_seed != seed else None
    renderer = SkinRenderer(skin, layout, sample_rate_hz, noise_seed=noise_seed)
    fs = sample_rate_hz
    placed: list[tuple[int, Touch, np.ndarray]] = []
    cursor = int(round(rng.uniform(*LEAD_S) * fs))  # the next first contact
    gap: float | None = None
    limit = None if seconds is None else int(round((seconds - tail_s) * fs))
    for request in parsed:
        if request.name == "idle":
            gap = (gap or 0.0) + float(request.value or 0.0)
            continue
        touch = perform_request(request, Trial(person, rng, fs), layout, definitions)
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
    # Only what was asked for: a default stream's metadata stays as it was.
    choices = {"person_seed": person_seed, "skin_seed": skin_seed, "gain": gain}
    metadata.update({k: v for k, v in choices.items() if v is not None})
    if gain_scale != 1.0:
        metadata["gain_scale"] = float(gain_scale)
    if definitions:
        metadata["custom_gestures"] = {n: g.to_dict() for n, g in definitions.items()}
    return LabelledStream(
        frames=renderer.raw(change, t),
        t=t,
        sample_rate_hz=float(fs),
        event_start_s=np.array([e["start_s"] for e in events], dtype=np.float64),
        event_end_s=np.array([e["end_s"] for e in events], dtype=np.float64),
        event_labels=np.array([e["label"] for e in events], dtype=str),
        metadata=metadata,
    )


def mixed_requests(
    rng: np.random.Generator,
    n: int,
    invalid_fraction: float = 0.2,
    custom: Sequence[str] = (),
    custom_rounds: float = 1.0,
) -> list[str]:
    """``n`` requests: the 14 gestures in shuffled rounds (swipes as flicks, swipes with a
    rest or held swipes; smooth or land-then-press pushes), invalid touches of every kind at
    ``invalid_fraction`` and an occasional long idle gap (3-8 s).

    Each ``custom`` gesture joins every round ``custom_rounds`` times on average (1: as
    often as each built-in gesture; 0.5: every other round; 2: twice a round)."""
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
            deck = list(rng.permutation(_round(rng, custom, custom_rounds)))
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
    person_seed: int | None = None,
    skin_seed: int | None = None,
    gain: float | None = None,
    gain_scale: float = 1.0,
    custom: Mapping[str, CustomGesture] | Sequence[CustomGesture] | None = None,
    custom_rounds: float = 1.0,
) -> LabelledStream:
    """``seconds`` of everything: gestures of all 14 classes in all variants, invalid
    touches and idle gaps, on one drawn person and skin; ``custom`` gestures mixed in
    ``custom_rounds`` times as often as each built-in one (:func:`mixed_requests`).  The
    person, skin and gain options are :func:`render_stream`'s."""
    if not 0.0 <= invalid_fraction <= 1.0:
        raise ConfigError(f"invalid_fraction must lie in [0, 1], got {invalid_fraction}")
    if not (np.isfinite(custom_rounds) and custom_rounds >= 0):
        raise ConfigError(f"custom_rounds must be a non-negative number, got {custom_rounds}")
    definitions = _custom_table(custom)
    rng = np.random.default_rng([seed, 1])
    requests = mixed_requests(
        rng, max(1, int(seconds)), invalid_fraction, list(definitions), custom_rounds
    )
    extra = {"stream": "mixed", "invalid_fraction": invalid_fraction}
    if definitions:
        extra["custom_rounds"] = float(custom_rounds)
    return render_stream(
        requests, seed, layout=layout, sample_rate_hz=sample_rate_hz, idle_s=idle_s,
        seconds=seconds, extra_metadata=extra, person_seed=person_seed, skin_seed=skin_seed,
        gain=gain, gain_scale=gain_scale, custom=definitions,
    )  # fmt: skip


def gesture_stream(
    request: str,
    seed: int,
    *,
    layout: SkinLayout | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    tail_s: float = 3.0,
    person_seed: int | None = None,
    skin_seed: int | None = None,
    gain: float | None = None,
    gain_scale: float = 1.0,
    custom: Mapping[str, CustomGesture] | Sequence[CustomGesture] | None = None,
) -> LabelledStream:
    """One touch alone (e.g. ``swipe_left:flick``, ``swipe_up:held``, a custom gesture's
    name) after a contact-free lead, then ``tail_s`` without contact (time for the arm to
    come to rest).  The person, skin, gain and custom options are :func:`render_stream`'s."""
    return render_stream(
        [request], seed, layout=layout, sample_rate_hz=sample_rate_hz, tail_s=tail_s,
        extra_metadata={"stream": "single"}, person_seed=person_seed, skin_seed=skin_seed,
        gain=gain, gain_scale=gain_scale, custom=custom,
    )  # fmt: skip


def person_of(seed: int) -> Person:
    """The person the stream of ``seed`` draws (its first draw)."""
    return Person.draw(np.random.default_rng(seed))


def skin_of(seed: int) -> Skin:
    """The skin the stream of ``seed`` draws (its second draw, after the person)."""
    rng = np.random.default_rng(seed)
    Person.draw(rng)
    return Skin.draw(rng)


def _with_gain(skin: Skin, gain: float | None, gain_scale: float) -> Skin:
    """``skin`` with its gain fixed to ``gain`` (if given), then times ``gain_scale``."""
    for name, value in (("gain", gain), ("gain_scale", gain_scale)):
        if value is not None and not (np.isfinite(value) and 0 < value <= 10):
            raise ConfigError(f"{name} must be a number in (0, 10], got {value!r}")
    if gain is None and gain_scale == 1.0:
        return skin
    return replace(skin, gain=float(skin.gain if gain is None else gain) * float(gain_scale))


def _custom_table(
    custom: Mapping[str, CustomGesture] | Sequence[CustomGesture] | None,
) -> dict[str, CustomGesture]:
    """``{name: definition}`` from a mapping or a sequence of definitions."""
    if not custom:
        return {}
    items = custom.values() if isinstance(custom, Mapping) else custom
    table: dict[str, CustomGesture] = {}
    for gesture in items:
        if not isinstance(gesture, CustomGesture):
            raise ConfigError(f"custom gestures must be CustomGesture objects, got {gesture!r}")
        table[gesture.name] = gesture
    return table


def _round(rng: np.random.Generator, custom: Sequence[str], rounds: float) -> list[str]:
    """One shuffled round's gestures: the 14, and each custom one ``rounds`` times on
    average (no random draw at all without custom gestures: default streams stay as they
    were)."""
    names = list(GESTURE_NAMES)
    if not custom:
        return names
    whole, part = int(rounds), rounds - int(rounds)
    for name in custom:
        extra = 1 if part > 0 and rng.random() < part else 0
        names += [name] * (whole + extra)
    return names
