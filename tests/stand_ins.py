"""Stand-ins and helpers shared by the tests (not collected as tests)."""

from __future__ import annotations

import time

import numpy as np

from wovenskin.gestures import CLASS_NAMES


class ContactMeans:
    """A stand-in recogniser: every window with contact is ``gesture``, confidently.

    The pipeline runs the model only on windows with contact, so a session driven by it
    acts exactly while fingers touch the skin -- no trained model needed.
    """

    class_names = CLASS_NAMES

    class meta:  # noqa: N801 - the window length, as CheckpointMeta gives it
        window = 30

    def __init__(self, gesture: str) -> None:
        self.gesture = gesture

    def predict_proba(self, windows: np.ndarray) -> np.ndarray:
        out = np.zeros((len(windows), len(CLASS_NAMES)), dtype=np.float32)
        out[:, CLASS_NAMES.index(self.gesture)] = 1.0
        return out


def wait_until(predicate, timeout: float = 20.0) -> bool:
    """Whether ``predicate()`` becomes true within ``timeout`` s (polled every 20 ms): a
    generous upper bound on a live session, so a loaded machine slows a test, never fails it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.02)
    return bool(predicate())  # a last look: the deadline may fall between two polls
