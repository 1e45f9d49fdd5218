"""The independent operator's skin: conditioned live, held until lifted, same seeds same frames."""

import numpy as np
import pytest

from wovenskin.errors import ConfigError
from wovenskin.independent import person_of, skin_of
from wovenskin.operators.independent_skin import IndependentSkin
from wovenskin.operators.touch_skin import BLOCK_FRAMES
from wovenskin.signal.live_skin import LiveSkin
from wovenskin.skin.frames import Frame


def _frames(skin: IndependentSkin, polls: int) -> np.ndarray:
    out = []
    for _ in range(polls):
        out += [f.values for f in skin.poll() if isinstance(f, Frame)]
    return np.array(out)


def test_frames_come_in_blocks_from_the_generators_person_and_skin():
    skin = IndependentSkin(3)
    assert skin.person == person_of(3) and skin.skin == skin_of(3)
    assert skin.info.source == "independent"
    skin.start()
    frames = [f for f in skin.poll() if isinstance(f, Frame)]
    more = [f for f in skin.poll() if isinstance(f, Frame)]
    assert len(frames) == BLOCK_FRAMES and frames[0].values.shape == skin.layout.shape
    assert [f.seq for f in frames + more] == list(range(2 * BLOCK_FRAMES))
    assert np.allclose(np.diff([f.t for f in frames + more]), 1 / 200)


def test_the_live_pipeline_conditions_a_touch_held_until_lifted():
    source = IndependentSkin(4)
    live = LiveSkin(source)
    live.start()

    def steps(n: int) -> list[bool]:
        touched = []
        for _ in range(n):
            block = live.step()
            if block is not None:
                touched += list(block.cond.touched)
        return touched

    try:
        assert not any(steps(30)) and not live.state.calibrating  # 1.5 s untouched
        touch = source.touch("push")
        steps(int(touch.phases.lift_start_s * 200 / BLOCK_FRAMES) + 2)
        assert source.holding
        assert all(steps(40)) and live.state.contacts  # 2 s held: the finger still presses
        source.lift()
        steps(20)
        assert not source.touching and not any(steps(10))
    finally:
        live.close()


def test_a_held_gesture_rests_until_lift_then_the_skin_rests():
    skin = IndependentSkin(2)
    skin.start()
    rest = _frames(skin, 10)
    touch = skin.touch("swipe_up")
    _frames(skin, int(touch.phases.lift_start_s * 200 / BLOCK_FRAMES) + 2)
    assert skin.holding
    held = _frames(skin, 40)
    change = np.abs(held - rest.mean(axis=0)).max()
    assert skin.touching and change > 5 * rest.std(axis=0).max()
    assert np.abs(held[-1] - held[0]).max() < change / 5  # resting, not moving
    skin.lift()
    _frames(skin, 20)
    assert not skin.touching
    after = _frames(skin, 10)
    assert np.abs(after - rest.mean(axis=0)).max() < change / 5


def test_the_same_seeds_and_acts_render_the_same_frames():
    def run(gesture_seed: int) -> np.ndarray:
        skin = IndependentSkin(5, gesture_seed=gesture_seed)
        skin.start()
        first = _frames(skin, 3)
        skin.touch("circle_cw_2f")
        second = _frames(skin, 30)
        skin.lift()
        return np.concatenate([first, second, _frames(skin, 5)])

    assert np.array_equal(run(7), run(7))
    assert not np.array_equal(run(7), run(8))


def test_what_it_cannot_perform_is_one_config_error_line():
    skin = IndependentSkin(1)
    skin.start()
    for name in ("wave_hello", "idle:2"):
        with pytest.raises(ConfigError, match="cannot perform") as error:
            skin.touch(name)
        assert "\n" not in str(error.value)
    assert not skin.touching and skin.touches == 0
    skin.touch("push")
    with pytest.raises(ConfigError, match="lift it first"):
        skin.touch("push")
