"""How ``adapt`` chooses execution settings: candidates around the base's, cross-fitting."""

from __future__ import annotations

import pytest

from wovenskin.recognition.arbiter import ArbiterSettings
from wovenskin.recognition.event_scoring import EventScores
from wovenskin.training.adapt_arbiter import _best, _departure, candidates, merit


def test_candidates_stay_near_the_base_setting():
    tried = candidates(ArbiterSettings(min_probability=0.83))
    floors = sorted({c["min_probability"] for c in tried})
    assert floors == [0.68, 0.73, 0.78, 0.83, 0.88, 0.93]
    assert {c["keep_probability"] for c in tried} == {None, 0.5}
    # a base without a recommendation is centred on 0.8
    assert min(c["min_probability"] for c in candidates(ArbiterSettings())) == 0.65


def test_merit_charges_false_activations():
    clean = EventScores(n_events=10, n_detected=9, n_activations=9, duration_s=60.0)
    noisy = EventScores(n_events=10, n_detected=10, n_activations=12, n_false=2, duration_s=60.0)
    assert merit(clean) > merit(noisy)  # 2 wrong moves a minute cost more than one miss


def test_best_breaks_ties_by_latency_then_strictness():
    fast = EventScores(n_events=4, n_detected=4, n_activations=4, latencies_s=[0.2] * 4)
    slow = EventScores(n_events=4, n_detected=4, n_activations=4, latencies_s=[0.3] * 4)
    assert _best([(0, slow, 0.0), (1, fast, 0.0)]) == 1
    assert _best([(0, fast, 0.0), (1, fast, 0.0)]) == 1


def test_leaving_the_base_setting_needs_a_clear_gain():
    start = ArbiterSettings(min_probability=0.83)
    same = {"min_probability": 0.83, "keep_probability": None}
    step = {"min_probability": 0.78, "keep_probability": None}
    far = {"min_probability": 0.68, "keep_probability": None}
    assert _departure(same, start) == 0.0
    assert _departure(far, start) == pytest.approx(0.075)
    nine = (EventScores(n_events=10, n_detected=9, n_activations=9), _departure(same, start))
    ten = EventScores(n_events=10, n_detected=10, n_activations=10)
    # one more event of ten found (F1 0.947 -> 1) is worth a step of 0.05, not one of 0.15
    assert _best([(0, *nine), (1, ten, _departure(step, start))]) == 1
    assert _best([(0, *nine), (1, ten, _departure(far, start))]) == 0
    assert _best([(0, ten, 0.0), (1, ten, _departure(step, start))]) == 0  # a tie stays
