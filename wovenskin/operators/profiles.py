"""Human timing of a simulated operator, novice or expert, with its sources.

Every time an operator spends is drawn per person from the ranges below, so six simulated
participants differ as six people do.  The figures come from the keystroke-level model
(KLM) of Card, Moran and Newell (1980, "The keystroke-level model for user performance
time with interactive systems", CACM 23(7)): K (a keystroke: 0.20 s for a skilled typist,
0.28 s for an average non-secretary, 0.5 s for random letters, 1.2 s for someone unfamiliar
with the keyboard), P (pointing at a target: 1.1 s), H (moving the hand between devices:
0.4 s) and M (mental preparation before an action: 1.35 s); simple visual reaction times
of 0.2-0.3 s (Welford 1980, "Choice reaction time: basic concepts"); the power law of
practice (Newell and Rosenbloom 1981) for the speed-up from trial to trial; gesture
durations from the simulated person of :mod:`wovenskin.sim.person` (docs/gestures.md).
What is our assumption rather than a measured figure is marked so in
:data:`ASSUMPTIONS` and in docs/operators.md.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from wovenskin.errors import ConfigError

EXPERTISE = ("novice", "expert")

# (low, high) per expertise; each person draws once, uniformly (log-uniform for times).
RANGES: dict[str, dict[str, tuple[float, float]]] = {
    # M: mental preparation before each new move (KLM 1.35 s; experts chunk routine moves)
    "think_s": {"novice": (1.1, 1.8), "expert": (0.5, 0.9)},
    # simple visual reaction time: from seeing the goal reached to the release
    "reaction_s": {"novice": (0.25, 0.40), "expert": (0.18, 0.26)},
    # share of its own reaction time a person anticipates (lets go early): novices overshoot
    "anticipation": {"novice": (0.1, 0.5), "expert": (0.7, 1.0)},
    # K: a key press on the study's key map
    "key_s": {"novice": (0.5, 1.2), "expert": (0.2, 0.28)},
    # P: pointing at a pendant button (a touch screen held in the other hand)
    "point_s": {"novice": (1.0, 1.5), "expert": (0.6, 1.1)},
    # H: hand to the skin or to the gripper button and back
    "home_s": {"novice": (0.4, 0.6), "expert": (0.3, 0.4)},
    # chance that a move starts in the wrong direction (a tool-frame key or gesture read
    # as the base frame, a sign mixed up): noticed after a reaction time, then corrected
    "wrong_direction": {"novice": (0.05, 0.15), "expert": (0.0, 0.03)},
    # chance of an extra look (a second M) before a move: hesitation
    "hesitation": {"novice": (0.2, 0.4), "expert": (0.0, 0.1)},
    # exponent of the power law of practice for the thinking time over trials
    "practice": {"novice": (0.15, 0.3), "expert": (0.02, 0.08)},
    # how precisely the operator aims, as a share of the task's tolerance (1: just in)
    "precision": {"novice": (0.6, 0.8), "expert": (0.7, 0.9)},
}
LOG_FIELDS = ("think_s", "reaction_s", "key_s", "point_s", "home_s")
ASSUMPTIONS = {
    "think_s": "experts' shorter M (chunked routine moves) is our assumption; novices KLM's M",
    "anticipation": "our assumption: a person learns to let go before the goal",
    "wrong_direction": "our assumption, tool-frame interfaces only",
    "hesitation": "our assumption",
    "precision": "our assumption",
    "point_s": "KLM's P for novices; an expert's familiar panel shorter (Fitts)",
}


@dataclass(frozen=True)
class OperatorProfile:
    """One simulated person's timing (see the module docstring for each field's source)."""

    name: str
    expertise: str
    think_s: float
    reaction_s: float
    anticipation: float
    key_s: float
    point_s: float
    home_s: float
    wrong_direction: float
    hesitation: float
    practice: float
    precision: float
    seed: int

    def __post_init__(self) -> None:
        if self.expertise not in EXPERTISE:
            raise ConfigError(f"expertise must be novice or expert, got {self.expertise!r}")

    def thinking(self, trial: int) -> float:
        """M on trial ``trial`` (1-based): the power law of practice."""
        return self.think_s * max(1, int(trial)) ** -self.practice

    def to_dict(self) -> dict:
        return asdict(self)


def sample_profile(name: str, expertise: str, seed: int) -> OperatorProfile:
    """A person of ``expertise`` drawn from :data:`RANGES` with ``seed``."""
    if expertise not in EXPERTISE:
        raise ConfigError(f"expertise must be novice or expert, got {expertise!r}")
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x0BE])
    values: dict[str, float] = {}
    for field, by_level in RANGES.items():
        low, high = by_level[expertise]
        if field in LOG_FIELDS:
            values[field] = float(np.exp(rng.uniform(np.log(low), np.log(high))))
        else:
            values[field] = float(rng.uniform(low, high))
    return OperatorProfile(name=name, expertise=expertise, seed=int(seed), **values)
