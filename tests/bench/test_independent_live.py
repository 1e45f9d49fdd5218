"""The independent generator live: one touch performed, rendered block by block as at once."""

import numpy as np
import pytest

from wovenskin.errors import ConfigError
from wovenskin.independent import (
    LiveRenderer,
    held_fingers,
    perform_touch,
    person_of,
    skin_of,
    touch_frames,
)
from wovenskin.skin.layout import SkinLayout


def _touch(request: str = "swipe_left", seed: int = 3):
    return perform_touch(request, person_of(seed), np.random.default_rng(seed))


def test_a_touch_rendered_in_blocks_is_the_touch_rendered_at_once():
    touch = _touch()
    layout = SkinLayout()
    whole = LiveRenderer(skin_of(3), layout, 200.0, noise_seed=9)
    at_once = whole.render(touch.fingers, touch.n_frames)
    blocks = LiveRenderer(skin_of(3), layout, 200.0, noise_seed=9)
    pieces = [
        blocks.render(
            touch_frames(touch, a, min(a + 10, touch.n_frames)), min(10, touch.n_frames - a)
        )
        for a in range(0, touch.n_frames, 10)
    ]
    assert np.array_equal(np.concatenate(pieces), at_once)
    assert at_once.dtype == np.int32 and blocks.frame == touch.n_frames


def test_held_fingers_rest_as_at_one_frame_and_the_fabric_relaxes_after():
    touch = _touch("push")
    frame = int(touch.phases.lift_start_s * 200) - 1
    held = held_fingers(touch, frame, 5)
    assert [len(f.x) for f in held] == [5]
    assert np.all(held[0].x == touch.fingers[0].x[frame])
    assert np.all(held[0].force == touch.fingers[0].force[frame]) and held[0].force[0] > 0
    renderer = LiveRenderer(skin_of(3), SkinLayout(), 200.0)
    idle = renderer.render(None, 20).astype(float)
    pressed = renderer.render(held_fingers(touch, frame, 40), 40).astype(float)
    after = renderer.render(None, 100).astype(float)
    change = np.abs(pressed[-1] - idle.mean(axis=0)).max()
    assert change > 20 * idle.std(axis=0).max()
    assert np.abs(after[-1] - idle.mean(axis=0)).max() < change / 10


def test_perform_touch_performs_variants_and_refuses_what_it_cannot():
    assert _touch("swipe_up:held=1.0").kind == "held_swipe"
    assert _touch("invalid:palm").label == "invalid"
    for request in ("wave", "idle:3", "swipe_up:wobbly"):
        with pytest.raises(ConfigError) as error:
            _touch(request)
        assert "\n" not in str(error.value)
