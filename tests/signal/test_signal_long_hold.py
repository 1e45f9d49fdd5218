"""A lift after a long hold releases the skin at once, and nothing is touched after it.

Around a resting hand a mutual-capacitance skin reads *below* its resting level (the
grounded hand shunts the fringe field: ``SkinPhysics.proximity_fraction < 0``), for as
long as the hand rests.  The channels next to the contact are frozen as its neighbours;
after ``stale_contact_s`` the baseline tracker must not take that lowered level for their
baseline, or the moment the hand lifts they read 10-30 noise sds above it: a phantom
contact that keeps the skin touched for seconds and the arm moving, and that makes the
raw-signal lift detector see a finger still holding.  Rendered by the simulator's skin
physics (fabric lag and creep, fringe field, crosstalk, noise, mains, drift).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from wovenskin.signal.baseline import BaselineTracker, dilate_one_channel
from wovenskin.signal.calibration import Calibration
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.contact import ContactTrack
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics

FS = 200
CONFIG = ConditioningConfig()
IDLE = 200  # frames before the hand lands
AFTER = 1000  # frames rendered after the lift (5 s: longer than stale_contact_s)


def _fingertip(n: int, land: int, lift: int, x: float, y: float) -> ContactTrack:
    """A 1.5 N fingertip resting at ``(x, y)`` mm from ``land`` until ``lift`` (5-frame ramps)."""
    t = np.arange(n)
    force = np.clip(np.minimum((t - land + 1) / 5, (lift - t) / 5), 0, 1) * 1.5
    return ContactTrack(np.full(n, x), np.full(n, y), force, 5.5, 4.5, kind="fingertip")


def _long_hold(seed: int, proximity: float, hold_s: float) -> tuple[np.ndarray, int]:
    """Raw frames of two fingertips (a pinch) held ``hold_s`` on a sensitive typical skin
    drawn from ``seed`` with the given fringe-field share, and the first frame after the
    lift."""
    physics = SkinPhysics.sample_typical(np.random.default_rng(seed))
    physics = replace(
        physics,
        proximity_fraction=proximity,
        proximity_sigma_mm=9.5,  # a fringe field reaching the neighbouring channels
        gain_pf=max(physics.gain_pf, 6.0),  # a firm press changes a channel by ~10 %
        glitch_rate_hz=0.0,
    )
    model = SkinModel(physics, seed=seed)
    lift = IDLE + int(hold_s * FS)
    n = lift + AFTER
    fingers = [_fingertip(n, IDLE, lift, 52.0, 48.0), _fingertip(n, IDLE, lift, 76.0, 60.0)]
    return model.render(fingers, n), lift


CASES = [(seed, -0.015) for seed in (1, 2, 3, 4, 11)] + [(11, -0.008), (3, 0.03), (27, 0.05)]
"""Skins (seed, fringe-field share): a grounded hand shunting the field, and two skins
whose fringe field adds to a press as controls."""


@pytest.mark.parametrize(("seed", "proximity"), CASES)
def test_a_lift_after_a_long_hold_releases_the_skin_for_good(seed, proximity):
    raw, lift = _long_hold(seed, proximity, hold_s=7.5)
    for config, within in ((CONFIG, 25), (replace(CONFIG, lift_fraction=0.0), 40)):
        _, out = condition_recording(raw, config)
        assert out.touched[lift - 50 : lift].all()  # the hold was seen to the end
        after = out.touched[lift:]
        assert not after[within:].any(), (
            f"lift_fraction={config.lift_fraction}: touched again "
            f"{int(after[within:].sum())} frames after the lift"
        )
        assert not out.active[lift + within + 20 :].any()  # no phantom contact either


def test_the_fringe_field_around_a_resting_hand_never_lowers_a_baseline():
    # The tracker alone: one channel pressed for twice stale_contact_s, its neighbours
    # held 0.4 % below their resting level by the hand all along, then the hand lifts.
    config = ConditioningConfig(stale_contact_s=1.0, common_drift=False)
    shape = (6, 6)
    calibration = Calibration(
        np.full(shape, 10.0), np.full(shape, 1e-4), np.zeros(shape, bool),
        np.zeros(shape, bool), 100, "test",
    )  # fmt: skip
    tracker = BaselineTracker(calibration, config)
    pressed = np.zeros(shape, bool)
    pressed[3, 3] = True
    neighbours = dilate_one_channel(pressed) & ~pressed
    held = np.where(neighbours, 9.96, np.where(pressed, 10.6, 10.0))
    block = config.block_frames
    for _ in range(2 * config.stale_contact_blocks):
        tracker.accumulate(np.broadcast_to(held, (block, *shape)).copy(),
                           np.broadcast_to(pressed, (block, *shape)))  # fmt: skip
    assert (tracker.baseline[neighbours] == 10.0).all()
    for _ in range(config.hold_blocks + 2):  # lifted: everything at rest again
        tracker.accumulate(np.full((block, *shape), 10.0), np.zeros((block, *shape), bool))
    assert (tracker.baseline[neighbours] == 10.0).all()


@pytest.mark.parametrize(("gain", "seed"), [(0.3, 2), (0.3, 3), (0.1, 1)])
def test_a_thirty_second_hold_on_a_weak_skin_keeps_its_command_until_the_lift(gain, seed):
    """A swipe held still for 30 s on a weak skin (an independent person and skin, the
    response scaled by ``gain``) reads under 1 % above baseline: the stale rule used to end
    it after 5 s.  The finger's wobble tells it from a baseline error, and the command
    lasts until the lift (``max_contact_s``, 60 s, stays the guard)."""
    from wovenskin.independent.streams import gesture_stream
    from wovenskin.recognition.pipeline import (
        load_recognizer,
        pipeline_settings_for_model,
        run_pipeline,
    )

    recognizer = load_recognizer(None, threads=1)
    stream = gesture_stream("swipe_left:held=30", seed, gain_scale=gain)
    commands = run_pipeline(stream, recognizer, pipeline_settings_for_model(recognizer)).commands
    lift = stream.metadata["events"][0]["phases"]["lift_start_s"]
    started = [c for c in commands if c.gesture]
    assert started and started[-1].gesture == "swipe_left", commands
    ended = [c for c in commands if c.gesture is None and c.t > started[-1].t]
    assert ended and ended[0].t >= lift - 0.3, (lift, commands)
