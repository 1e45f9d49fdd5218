"""Labelled simulated streams: a simulated person using a simulated skin for a while.

Owns :class:`EventScheduler` (what the person does next: the gestures cycled evenly in a
shuffled order, invalid touches at a given rate, idle gaps, and explicit requests, a
user's custom gestures among them where given) and
:func:`simulate_stream`, which renders a whole :class:`~wovenskin.recording.formats.LabelledStream`:
at least one contact-free second, then gestures, invalid touches and idle gaps, labelled
with each event's first contact and last lift-off.  The same seed gives identical arrays.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURE_NAMES, INVALID, check_name, known_classes
from wovenskin.recording.formats import LabelledStream
from wovenskin.sim.invalid import INVALID_KINDS
from wovenskin.sim.motion import LEAD_S, Performance
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

INITIAL_IDLE_S = (1.2, 1.7)
"""Contact-free time before the first event's first contact (>= 1 s, plus hover)."""


def parse_request(
    request: str, custom: Mapping[str, CustomGesture] | None = None
) -> tuple[str, str | None]:
    """``"swipe_up"`` -> ``("swipe_up", None)``; ``"invalid:palm"`` -> ``("invalid", "palm")``;
    the names of ``custom`` gestures are known too."""
    name, _, kind = request.strip().partition(":")
    check_name(name, known_classes(custom or ()))
    if kind and name != INVALID:
        raise ConfigError(f"only 'invalid' takes a sub-kind, got {request!r}")
    if kind and kind not in INVALID_KINDS:
        raise ConfigError(f"unknown invalid kind {kind!r}; known: {', '.join(INVALID_KINDS)}")
    return name, kind or None


class EventScheduler:
    """Chooses the simulated person's next performance and the idle gap before it."""

    def __init__(
        self,
        rng: np.random.Generator,
        person: Person,
        layout: SkinLayout,
        gestures: Sequence[str] | None = None,
        invalid_fraction: float = 0.25,
        idle_s: tuple[float, float] = (0.3, 1.5),
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        custom: Mapping[str, CustomGesture] | None = None,
    ) -> None:
        """``custom``: a user's gestures the person can perform (from their strokes)."""
        self.custom: dict[str, CustomGesture] = dict(custom or {})
        gestures = list(GESTURE_NAMES if gestures is None else gestures)
        for g in gestures:
            parse_request(g, self.custom)
        if not 0.0 <= invalid_fraction <= 1.0:
            raise ConfigError(f"invalid_fraction must lie in [0, 1], got {invalid_fraction}")
        low, high = (float(v) for v in idle_s)
        if not 0.0 <= low <= high:
            raise ConfigError(f"idle_s must be (low, high) with 0 <= low <= high, got {idle_s}")
        if not gestures and invalid_fraction < 1.0:
            raise ConfigError("no gestures to perform: give gestures or set invalid_fraction=1")
        self.rng = rng
        self.person = person
        self.layout = layout
        self.gestures = gestures
        self.invalid_fraction = invalid_fraction
        self.idle_s = (low, high)
        self.sample_rate_hz = sample_rate_hz
        self._deck: list[str] = []

    def idle_gap_s(self) -> float:
        """Time from one event's last lift-off to the next event's first contact."""
        return max(float(self.rng.uniform(*self.idle_s)), 2 * LEAD_S)

    def next_request(self) -> str:
        """The next event name: ``invalid`` at the configured rate, else the next gesture."""
        if not self.gestures or self.rng.random() < self.invalid_fraction:
            return INVALID
        if not self._deck:
            self._deck = list(self.rng.permutation(self.gestures))
        return str(self._deck.pop())

    def next_performance(self, request: str | None = None) -> Performance:
        """Perform ``request`` (a class name or ``invalid:KIND``) or the next scheduled event."""
        name, kind = parse_request(
            request if request is not None else self.next_request(), self.custom
        )
        return perform(
            name,
            self.person,
            self.rng,
            self.layout,
            invalid_kind=kind,
            sample_rate_hz=self.sample_rate_hz,
            custom=self.custom,
        )


@dataclass
class StreamEvent:
    """One labelled event on a stream's clock."""

    label: str
    invalid_kind: str | None
    start_s: float  # first contact (or start of a noise burst)
    end_s: float  # last lift-off

    def to_dict(self) -> dict:
        return {
            "label": self.label,
            "invalid_kind": self.invalid_kind,
            "start_s": self.start_s,
            "end_s": self.end_s,
        }


def simulate_stream(
    seconds: float,
    seed: int,
    layout: SkinLayout | None = None,
    physics: SkinPhysics | None = None,
    person: Person | None = None,
    gestures: Sequence[str] | None = None,
    invalid_fraction: float = 0.25,
    idle_s: tuple[float, float] = (0.3, 1.5),
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    custom: Mapping[str, CustomGesture] | None = None,
) -> LabelledStream:
    """A labelled stream of ``seconds`` of a simulated person using a simulated skin.

    ``physics`` and ``person`` are drawn from ``seed`` when ``None``.  Events that would
    not end before the stream does are left out (the stream ends contact-free).
    ``custom``: a user's gestures that ``gestures`` may name (performed from their strokes).
    """
    if not np.isfinite(seconds) or seconds <= 0:
        raise ConfigError(f"stream length must be positive, got {seconds}")
    if sample_rate_hz <= 0:
        raise ConfigError(f"sample rate must be positive, got {sample_rate_hz}")
    layout = layout if layout is not None else SkinLayout()
    rng = np.random.default_rng(seed)
    physics = physics if physics is not None else SkinPhysics.sample(rng)
    person = person if person is not None else Person.sample(rng)
    model = SkinModel(physics, layout, seed=int(rng.integers(2**31)), sample_rate_hz=sample_rate_hz)
    scheduler = EventScheduler(
        rng, person, layout, gestures, invalid_fraction, idle_s, sample_rate_hz, custom
    )
    fs = sample_rate_hz
    total = int(round(seconds * fs))
    chunks: list[np.ndarray] = []
    events: list[StreamEvent] = []
    details: list[dict] = []
    cursor = 0
    next_contact = int(round(rng.uniform(*INITIAL_IDLE_S) * fs))
    while True:
        performance = scheduler.next_performance()
        landing = int(round(performance.event_start_s * fs))
        start = max(next_contact - landing, cursor)
        if start + performance.n_frames > total:
            break
        chunks.append(model.render_idle(start - cursor))
        chunks.append(model.render(performance.contacts, performance.n_frames, performance.bursts))
        offset = start / fs
        event = StreamEvent(
            performance.label,
            performance.invalid_kind,
            offset + performance.event_start_s,
            offset + performance.event_end_s,
        )
        events.append(event)
        info = performance.summary()
        info["phases"] = performance.phases.shifted(offset).to_dict()
        details.append({**event.to_dict(), **info})
        cursor = start + performance.n_frames
        next_contact = int(round(event.end_s * fs + scheduler.idle_gap_s() * fs))
    chunks.append(model.render_idle(total - cursor))
    frames = np.concatenate(chunks, axis=0)
    metadata = {
        "generator": "wovenskin.sim",
        "seed": int(seed),
        "layout": layout.to_dict(),
        "physics": physics.to_dict(),
        "person": person.to_dict(),
        "gestures": list(scheduler.gestures),
        "invalid_fraction": invalid_fraction,
        "idle_s": list(scheduler.idle_s),
        "invalid_kinds": [e.invalid_kind for e in events],
        "events": details,
    }
    if custom:
        metadata["custom_gestures"] = {name: g.to_dict() for name, g in custom.items()}
    return LabelledStream(
        frames=frames,
        t=np.arange(total, dtype=np.float64) / fs,
        sample_rate_hz=float(fs),
        event_start_s=np.array([e.start_s for e in events], dtype=np.float64),
        event_end_s=np.array([e.end_s for e in events], dtype=np.float64),
        event_labels=np.array([e.label for e in events], dtype=str),
        metadata=metadata,
    )
