"""Tests of wovenskin.recognition.arbiter: the execution rules and the "being performed" flag."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.recognition.arbiter import (
    DWELL,
    ERRATIC,
    FLICK,
    LIFT_OFF,
    NOTHING,
    PREEMPT,
    Arbiter,
    ArbiterSettings,
    PerformingDetector,
    PerformingSettings,
    recognised_classes,
    touch_features,
)
from wovenskin.signal import ConditioningConfig, condition_recording
from wovenskin.sim.stream import simulate_stream

CLASSES = ("swipe_up", "swipe_right", "push", "invalid")
RATE = 200.0
DWELL_FRAMES = 20  # 0.1 s at 200 Hz


def one_hot(name: str, p: float = 0.9) -> np.ndarray:
    row = np.full(len(CLASSES), (1 - p) / (len(CLASSES) - 1), dtype=np.float32)
    row[CLASSES.index(name)] = p
    return row


def run_sequence(
    labels: list[str | None],
    touched: list[bool] | None = None,
    performing: list[bool] | None = None,
    arbiter_settings: ArbiterSettings | None = None,
    probability: float = 0.9,
):
    """Feed one prediction per frame (``None``: no prediction on that frame)."""
    n = len(labels)
    touched = [True] * n if touched is None else touched
    performing = [True] * n if performing is None else performing
    predicted = np.array([lab is not None for lab in labels])
    probabilities = np.stack(
        [one_hot(lab or "invalid", probability if lab else 0.9) for lab in labels]
    )
    arbiter = Arbiter(CLASSES, RATE, arbiter_settings)
    t = np.arange(n) / RATE
    return arbiter, arbiter.run(t, touched, performing, predicted, probabilities)


def test_a_gesture_acts_after_exactly_the_dwell() -> None:
    # Recognised at frames 0..19: 19 frames later than its first recognition, not enough.
    arbiter, changes = run_sequence(["swipe_up"] * DWELL_FRAMES)
    assert changes == [] and arbiter.active is None and arbiter.candidate == "swipe_up"
    _, changes = run_sequence(["swipe_up"] * (DWELL_FRAMES + 1))
    assert [(c.t, c.gesture, c.reason) for c in changes] == [
        (DWELL_FRAMES / RATE, "swipe_up", DWELL)
    ]


def test_an_interrupted_recognition_restarts_the_dwell() -> None:
    labels = ["swipe_up"] * 15 + ["invalid"] + ["swipe_up"] * 20
    assert run_sequence(labels)[1] == []
    labels = ["swipe_up"] * 15 + ["swipe_right"] + ["swipe_up"] * 21
    changes = run_sequence(labels)[1]
    assert [(round(c.t * RATE), c.gesture) for c in changes] == [(36, "swipe_up")]


def test_dwell_setting_is_honoured() -> None:
    dwell = ArbiterSettings(dwell_s=0.05)
    changes = run_sequence(["push"] * 11, arbiter_settings=dwell)[1]
    assert [round(c.t * RATE) for c in changes] == [10]


def test_min_probability_must_be_reached() -> None:
    strict = ArbiterSettings(min_probability=0.8)
    assert run_sequence(["push"] * 40, arbiter_settings=strict, probability=0.7)[1] == []
    changes = run_sequence(["push"] * 40, arbiter_settings=strict, probability=0.85)[1]
    assert [c.gesture for c in changes] == ["push"]


def test_invalid_and_no_contact_never_act() -> None:
    assert run_sequence(["invalid"] * 100)[1] == []
    assert run_sequence(["swipe_up"] * 100, touched=[False] * 100)[1] == []


def test_lift_off_ends_at_once_and_a_new_touch_starts_fresh() -> None:
    labels = ["swipe_up"] * 30 + ["swipe_up"] * 2 + ["swipe_up"] * 15
    touched = [True] * 30 + [False] * 2 + [True] * 15
    changes = run_sequence(labels, touched)[1]
    assert [(round(c.t * RATE), c.gesture, c.reason) for c in changes] == [
        (20, "swipe_up", DWELL),
        (30, None, LIFT_OFF),
    ]  # 15 frames of the new touch are not enough: its dwell starts at the new touch


def test_a_resting_finger_keeps_the_command_and_never_becomes_push() -> None:
    swipe = ["swipe_right"] * 40
    rest = ["push"] * 400  # the windows look like a push while the finger rests
    labels = swipe + rest
    performing = [True] * 40 + [False] * 400
    arbiter, changes = run_sequence(labels, performing=performing)
    assert [c.gesture for c in changes] == ["swipe_right"]
    assert arbiter.active == "swipe_right"
    # Brief blips of "performing" (a twitch) shorter than the dwell never switch either.
    blips = ([True] * 3 + [False] * 5) * 50
    arbiter, changes = run_sequence(labels, performing=[True] * 40 + blips)
    assert [c.gesture for c in changes] == ["swipe_right"]


def test_preemption_needs_the_dwell_while_being_performed() -> None:
    labels = ["swipe_right"] * 40 + ["push"] * 60
    performing = [True] * 40 + [False] * 30 + [True] * 30
    changes = run_sequence(labels, performing=performing)[1]
    # push has been recognised since frame 40 but performed only since frame 70.
    assert [(round(c.t * RATE), c.gesture, c.reason) for c in changes] == [
        (20, "swipe_right", DWELL),
        (90, "push", PREEMPT),
    ]
    # While performed, a different gesture preempts after its own dwell.
    changes = run_sequence(["swipe_right"] * 40 + ["swipe_up"] * 30)[1]
    assert [(round(c.t * RATE), c.gesture, c.reason) for c in changes[1:]] == [
        (60, "swipe_up", PREEMPT)
    ]


def test_invalid_or_the_same_gesture_never_end_a_command() -> None:
    labels = ["swipe_up"] * 25 + ["invalid"] * 100 + ["swipe_up"] * 50
    arbiter, changes = run_sequence(labels)
    assert [c.gesture for c in changes] == ["swipe_up"] and arbiter.active == "swipe_up"


def test_predictions_every_k_frames() -> None:
    labels = [("push" if i % 5 == 0 else None) for i in range(40)]
    changes = run_sequence(labels)[1]
    assert [round(c.t * RATE) for c in changes] == [20]  # predictions at 0, 5, ..., 20
    labels = [("push" if i % 7 == 0 else None) for i in range(40)]
    assert [round(c.t * RATE) for c in run_sequence(labels)[1]] == [21]


def test_step_matches_run_and_validates() -> None:
    rng = np.random.default_rng(0)
    n = 600
    idx = rng.integers(0, len(CLASSES), n // 25).repeat(25)
    probabilities = np.eye(len(CLASSES), dtype=np.float32)[idx]
    touched = rng.random(n) > 0.03
    performing = rng.random(n) > 0.3
    predicted = rng.random(n) > 0.2
    t = np.arange(n) / RATE
    whole = Arbiter(CLASSES, RATE).run(t, touched, performing, predicted, probabilities)
    stepper = Arbiter(CLASSES, RATE)
    stepped = [
        change
        for i in range(n)
        for change in stepper.step(
            t[i], touched[i], performing[i], probabilities[i] if predicted[i] else None
        )
    ]
    assert stepped == whole
    assert len(whole) > 3
    with pytest.raises(ValueError, match="expected 4 class probabilities, got 3"):
        stepper.step(0.0, True, True, np.ones(3))
    with pytest.raises(ValueError, match=r"probabilities must be shaped \(2, 4\)"):
        Arbiter(CLASSES, RATE).run(
            t[:2], touched[:2], performing[:2], predicted[:2], np.ones((2, 5))
        )


def test_recognised_classes() -> None:
    p = np.array([[0.1, 0.7, 0.1, 0.1], [0.1, 0.1, 0.1, 0.7], [0.3, 0.2, 0.2, 0.3]])
    assert recognised_classes(p, CLASSES, 0.0).tolist() == [1, NOTHING, 0]
    assert recognised_classes(p, CLASSES, 0.5).tolist() == [1, NOTHING, NOTHING]


def test_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="dwell_s"):
        ArbiterSettings(dwell_s=0)
    with pytest.raises(ValueError, match="min_probability"):
        ArbiterSettings(min_probability=1.5)
    with pytest.raises(ValueError, match="min_pressure_change"):
        PerformingSettings(min_pressure_change=0)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        Arbiter(CLASSES, 0.0)


frames_strategy = st.lists(
    st.tuples(
        st.booleans() | st.just(True),  # touched (mostly)
        st.booleans(),  # performing
        st.sampled_from([None, *CLASSES]),  # prediction
    ),
    min_size=1,
    max_size=300,
)


def run_start(labels, touched, i: int, g: str) -> int | None:
    """First frame of the unbroken run of predictions of ``g`` (on a touched skin) up to ``i``."""
    start, j = None, i
    while j >= 0 and touched[j] and labels[j] in (None, g):
        if labels[j] == g:
            start = j
        j -= 1
    return start


@settings(max_examples=150, deadline=None)
@given(frames=frames_strategy, dwell=st.integers(1, 30))
def test_rules_hold_for_any_sequence(frames, dwell: int) -> None:
    touched = [f[0] for f in frames]
    performing = [f[1] for f in frames]
    labels = [f[2] for f in frames]
    arbiter_settings = ArbiterSettings(dwell_s=dwell / RATE, max_switches=None, start_within_s=None)
    _, changes = run_sequence(labels, touched, performing, arbiter_settings)
    at = {round(c.t * RATE): c for c in changes}
    assert len(at) == len(changes)  # at most one change per frame
    active = None
    for i in range(len(frames)):
        change = at.get(i)
        if not touched[i]:
            # Lift-off ends the command on this very frame; nothing starts without contact.
            assert (change is not None) == (active is not None)
            if change is not None:
                assert change.gesture is None and change.reason == LIFT_OFF
            active = None
            continue
        g = labels[i]
        if active is None and g not in (None, "invalid"):
            start = run_start(labels, touched, i, g)
            if i - start >= dwell:  # the dwell is met: it must act now (and not before)
                assert change is not None and change.gesture == g
        if change is None:
            continue
        assert change.gesture is not None and change.gesture != "invalid"
        assert change.gesture == g != active  # decided on a frame that predicts it
        start = run_start(labels, touched, i, g)
        assert i - start >= dwell
        if active is None:
            assert change.reason == DWELL
        else:
            assert change.reason == PREEMPT
            assert all(performing[i - dwell : i + 1])  # performed through its whole dwell
        active = g


def test_a_touch_that_keeps_switching_is_erratic_and_acts_no_more() -> None:
    d = DWELL_FRAMES + 1
    wandering = ["swipe_up"] * d + ["swipe_right"] * d + ["push"] * d + ["swipe_up"] * d
    arbiter, changes = run_sequence(wandering)
    assert [(c.gesture, c.reason) for c in changes] == [
        ("swipe_up", DWELL),
        ("swipe_right", PREEMPT),
        (None, ERRATIC),  # the second switch: a hand wandering, not a gesture
    ]
    assert changes[2].t == (3 * d - 1) / RATE and arbiter.suppressed
    # Nothing acts until every finger lifts; then a new touch starts fresh.
    lifted = wandering + [None] * 3 + ["push"] * d
    touched = [True] * len(wandering) + [False] * 3 + [True] * d
    arbiter, changes = run_sequence(lifted, touched)
    assert [c.reason for c in changes] == [DWELL, PREEMPT, ERRATIC, DWELL]
    assert changes[-1].gesture == "push" and not arbiter.suppressed
    # max_switches=None allows any number; 0 ends the command at the first switch.
    _, free = run_sequence(wandering, arbiter_settings=ArbiterSettings(max_switches=None))
    assert [c.reason for c in free] == [DWELL, PREEMPT, PREEMPT, PREEMPT]
    _, strict = run_sequence(wandering, arbiter_settings=ArbiterSettings(max_switches=0))
    assert [c.reason for c in strict] == [DWELL, ERRATIC]
    with pytest.raises(ValueError, match="max_switches"):
        ArbiterSettings(max_switches=-1)


def test_fingers_that_have_rested_start_nothing() -> None:
    d = DWELL_FRAMES + 1
    # Still fingers (never performed) recognised as push for longer than the dwell: nothing.
    arbiter, changes = run_sequence(["push"] * (3 * d), performing=[False] * (3 * d))
    assert changes == [] and arbiter.active is None
    # Performed until 0.15 s before the dwell is met: within the 0.2 s grace, it acts.
    late = [True] * 10 + [False] * (d - 10 + 30)
    _, changes = run_sequence(["push"] * len(late), performing=late)
    assert [c.reason for c in changes] == [DWELL]
    # Performed, then rested 0.3 s before push is recognised: nothing, unless the
    # condition is switched off.
    rested = [True] * 5 + [False] * (60 + 2 * d)
    labels = ["invalid"] * 65 + ["push"] * (2 * d)
    _, changes = run_sequence(labels, performing=rested)
    assert changes == []
    off = ArbiterSettings(start_within_s=None)
    _, changes = run_sequence(labels, performing=rested, arbiter_settings=off)
    assert [c.reason for c in changes] == [DWELL]
    with pytest.raises(ValueError, match="start_within_s"):
        ArbiterSettings(start_within_s=-0.1)


# ------------------------------------------------------------------- being performed

ROWS, COLS = 10, 10


def blob_frames(rows_mm, cols_mm, amplitude, width_mm=8.0, noise=0.0, seed=0):
    """Frames of Gaussian fingertips; ``rows_mm``/``cols_mm``/``amplitude`` are (N, F)."""
    rng = np.random.default_rng(seed)
    rr = (np.arange(ROWS) * 14.0)[None, :, None, None]
    cc = (np.arange(COLS) * 10.0)[None, None, :, None]
    r = np.asarray(rows_mm, float)[:, None, None, :]
    c = np.asarray(cols_mm, float)[:, None, None, :]
    a = np.asarray(amplitude, float)[:, None, None, :]
    signal = (a * np.exp(-((rr - r) ** 2 + (cc - c) ** 2) / (2 * width_mm**2))).sum(axis=3)
    signal = signal + rng.normal(0.0, noise, signal.shape)
    active = signal > 0.02
    return signal.astype(np.float32), active


def performing_of(signal, active, chunks=None):
    detector = PerformingDetector(RATE)
    if chunks is None:
        return detector.update(signal, active)
    out, start = [], 0
    for size in chunks:
        out.append(detector.update(signal[start : start + size], active[start : start + size]))
        start += size
    return np.concatenate(out)


def test_touch_features_centroid_and_spread() -> None:
    signal, active = blob_frames([[42.0, 42.0]], [[30.0, 70.0]], [[0.2, 0.2]])
    total, row, col, spread = touch_features(signal, active)[0]
    assert total > 0
    assert row == pytest.approx(42.0, abs=0.5) and col == pytest.approx(50.0, abs=0.5)
    assert spread == pytest.approx(20.0, abs=3.0)
    empty = touch_features(np.zeros((1, ROWS, COLS)), np.zeros((1, ROWS, COLS), bool))
    assert empty.tolist() == [[0.0, 0.0, 0.0, 0.0]]


def test_moving_pinching_and_pressing_fingers_are_performing() -> None:
    n = 120
    still = np.full((n, 1), 60.0)
    swipe_cols = np.linspace(20, 80, n)[:, None]  # 60 mm in 0.6 s: 100 mm/s
    signal, active = blob_frames(still, swipe_cols, np.full((n, 1), 0.2), noise=0.002)
    assert performing_of(signal, active)[25:].all()
    gap = np.linspace(60, 15, n)  # two fingers converge symmetrically: centroid fixed
    signal, active = blob_frames(
        np.full((n, 2), 60.0), np.stack([50 - gap / 2, 50 + gap / 2], 1), np.full((n, 2), 0.2)
    )
    assert performing_of(signal, active)[25:].all()
    press = np.geomspace(0.05, 0.4, n)[:, None]  # a push: pressure grows 41 % per 0.1 s
    signal, active = blob_frames(still, np.full((n, 1), 50.0), press, noise=0.002)
    assert performing_of(signal, active)[25:].all()


def test_resting_fingers_are_not_performing() -> None:
    n = 300
    signal, active = blob_frames(
        np.full((n, 2), 60.0), np.tile([40.0, 60.0], (n, 1)), np.full((n, 2), 0.2), noise=0.003
    )
    flags = performing_of(signal, active)
    assert flags[:20].all()  # the landing (nothing touched 0.1 s before) is a change
    assert not flags[20:].any()
    # A weak edge channel flickering in and out of the active set changes nothing.
    flicker = active.copy()
    flicker[::7, 4, 7] = ~flicker[::7, 4, 7]
    assert not performing_of(signal, flicker)[20:].any()


@settings(max_examples=25, deadline=None)
@given(cuts=st.lists(st.integers(1, 60), min_size=1, max_size=12))
def test_performing_does_not_depend_on_chunking(cuts: list[int]) -> None:
    n = 200
    cols = np.concatenate([np.full(80, 30.0), np.linspace(30, 80, 60), np.full(60, 80.0)])
    signal, active = blob_frames(np.full((n, 1), 70.0), cols[:, None], np.full((n, 1), 0.2))
    chunks, total = [], 0
    for c in cuts:
        if total + c >= n:
            break
        chunks.append(c)
        total += c
    chunks.append(n - total)
    np.testing.assert_array_equal(
        performing_of(signal, active, chunks), performing_of(signal, active)
    )


def test_resting_phases_of_simulated_gestures_never_look_performed() -> None:
    # A skin of typical response (the drawn skin with the default gain): on the dullest,
    # noisiest skins the simulator draws, a light touch sits at the contact threshold and
    # flickers on and off -- a change of pressure by definition; how recognition copes
    # there is measured by `wovenskin bench recognition` (response_x0.1, skin_noisy).
    from dataclasses import replace

    from wovenskin.sim.skin_physics import SkinPhysics

    physics = replace(SkinPhysics.sample(np.random.default_rng(12)), gain_pf=4.0, c0_pf=20.0)
    stream = simulate_stream(30.0, seed=12, invalid_fraction=0.0, physics=physics)
    _, cond = condition_recording(stream.frames, ConditioningConfig())
    flags = PerformingDetector(RATE).update(cond.signal, cond.active)
    t = stream.t
    checked_rest = checked_motion = 0
    for event in stream.metadata["events"]:
        phases = event["phases"]
        rest = (t >= phases["rest_start_s"] + 0.25) & (t < phases["lift_start_s"]) & cond.touched
        if rest.sum() > DWELL_FRAMES:
            runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], flags[rest], [0]]))))[::2]
            assert runs.max(initial=0) < DWELL_FRAMES, event["label"]
            checked_rest += 1
        motion = (t >= phases["motion_start_s"]) & (t < phases["motion_end_s"])
        if event["label"] != "push" and motion.any():
            assert flags[motion].mean() > 0.5, event["label"]
            checked_motion += 1
    assert checked_rest >= 3 and checked_motion >= 5


# -- flicks -----------------------------------------------------------------------------------
FLICKS = ArbiterSettings(flick_s=0.05, flick_probability=0.9, flick_gap_s=0.05, flick_after_s=0.3)
FLICK_FRAMES = 10  # 0.05 s at 200 Hz


def flick_sequence(labels, gap_after=0, lead=None, settings=FLICKS, probability=0.95, **kw):
    """``lead`` untouched frames, a touch with ``labels``, ``gap_after`` untouched frames."""
    lead = lead or []
    labels = lead + labels + [None] * (gap_after + 1)
    touched = [False] * len(lead) + [True] * (len(labels) - len(lead) - gap_after - 1)
    touched += [False] * (gap_after + 1)
    return run_sequence(labels, touched, arbiter_settings=settings, probability=probability, **kw)


def test_a_touch_recognised_briefly_then_lifted_is_a_flick() -> None:
    labels = [None] * 5 + ["swipe_right"] * (FLICK_FRAMES + 1) + [None] * 3
    arbiter, changes = flick_sequence(labels)
    lift = len(labels) / RATE
    assert [(c.t, c.gesture, c.reason) for c in changes] == [
        (lift, "swipe_right", FLICK),
        (lift, None, LIFT_OFF),
    ]
    assert arbiter.active is None
    # one frame short of the streak, or too long a gap before the lift: nothing
    assert flick_sequence([None] * 5 + ["swipe_right"] * FLICK_FRAMES)[1] == []
    assert flick_sequence(["swipe_right"] * (FLICK_FRAMES + 1) + ["invalid"] * 10)[1] == []
    # trailing predictions of nothing within the gap keep it; another gesture breaks it
    kept = flick_sequence(["swipe_right"] * (FLICK_FRAMES + 1) + ["invalid"] * 9)[1]
    assert [c.reason for c in kept] == [FLICK, LIFT_OFF]
    broken = ["swipe_right"] * 8 + ["swipe_up"] + ["swipe_right"] * 8
    assert flick_sequence(broken)[1] == []


def test_a_flick_needs_its_own_probability_and_no_command_in_the_touch() -> None:
    labels = ["push"] * (FLICK_FRAMES + 5)
    assert flick_sequence(labels, probability=0.88)[1] == []  # under flick_probability
    assert [c.reason for c in flick_sequence(labels, probability=0.92)[1]] == [FLICK, LIFT_OFF]
    # a command that started in the touch ends at the lift as before
    changes = flick_sequence(["push"] * (DWELL_FRAMES + 5))[1]
    assert [c.reason for c in changes] == [DWELL, LIFT_OFF]
    # switched off
    off = ArbiterSettings(flick_s=None)
    assert flick_sequence(labels, settings=off)[1] == []


def test_resting_fingers_and_a_touch_right_after_a_command_never_flick() -> None:
    labels = ["push"] * (FLICK_FRAMES + 5)
    # not performed within start_within_s (0.2 s) of the streak: no flick
    assert flick_sequence(labels, performing=[False] * (len(labels) + 1))[1] == []
    # a command ended 0.1 s before the touch began: the touch is its continuation
    lead = ["push"] * (DWELL_FRAMES + 2)
    labels_all = lead + [None] * 20 + labels
    touched = [True] * len(lead) + [False] * 20 + [True] * len(labels) + [False]
    changes = run_sequence(labels_all + [None], touched, arbiter_settings=FLICKS, probability=0.95)[
        1
    ]
    assert [c.reason for c in changes] == [DWELL, LIFT_OFF]
    # 0.3 s later it is a new touch
    gap = 60
    labels_all = lead + [None] * gap + labels
    touched = [True] * len(lead) + [False] * gap + [True] * len(labels) + [False]
    changes = run_sequence(labels_all + [None], touched, arbiter_settings=FLICKS, probability=0.95)[
        1
    ]
    assert [c.reason for c in changes] == [DWELL, LIFT_OFF, FLICK, LIFT_OFF]


def test_flick_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="flick_s must be None or a number >= 0"):
        ArbiterSettings(flick_s=-1.0)
    with pytest.raises(ValueError, match="flick_probability must be None or lie in"):
        ArbiterSettings(flick_probability=1.5)
    with pytest.raises(ValueError, match="flick_after_s must be a number >= 0"):
        ArbiterSettings(flick_after_s=float("nan"))


def test_keep_probability_keeps_a_confident_candidate_through_weaker_predictions() -> None:
    # recognised confidently once, then only at 0.7: under min_probability 0.85 the dwell
    # never completes, with keep_probability 0.6 the candidate stays and acts
    n = DWELL_FRAMES + 1
    predicted = np.ones(n, dtype=bool)
    probabilities = np.stack([one_hot("swipe_up", 0.9)] + [one_hot("swipe_up", 0.7)] * (n - 1))
    t = np.arange(n) / RATE
    on = np.ones(n, dtype=bool)
    strict = ArbiterSettings(min_probability=0.85)
    assert Arbiter(CLASSES, RATE, strict).run(t, on, on, predicted, probabilities) == []
    kept = ArbiterSettings(min_probability=0.85, keep_probability=0.6)
    changes = Arbiter(CLASSES, RATE, kept).run(t, on, on, predicted, probabilities)
    assert [(round(c.t * RATE), c.gesture, c.reason) for c in changes] == [
        (DWELL_FRAMES, "swipe_up", DWELL)
    ]
    # a weak start never becomes the candidate, and another gesture still replaces it
    weak = np.stack([one_hot("swipe_up", 0.7)] * n)
    assert Arbiter(CLASSES, RATE, kept).run(t, on, on, predicted, weak) == []
    other = probabilities.copy()
    other[10] = one_hot("swipe_right", 0.9)
    assert Arbiter(CLASSES, RATE, kept).run(t, on, on, predicted, other) == []
    with pytest.raises(ValueError, match="keep_probability must be None or lie in"):
        ArbiterSettings(keep_probability=-0.1)
