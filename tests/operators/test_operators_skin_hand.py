"""The operator's skin: renders on demand, holds a gesture until lifted, same seeds same frames."""

import numpy as np

from wovenskin.operators.skin_hand import BLOCK_FRAMES, OperatorSkin
from wovenskin.skin.frames import Frame


def _frames(skin: OperatorSkin, polls: int) -> np.ndarray:
    out = []
    for _ in range(polls):
        out += [f.values for f in skin.poll() if isinstance(f, Frame)]
    return np.array(out)


def test_frames_come_in_blocks_with_contiguous_times():
    skin = OperatorSkin(1)
    skin.start()
    items = skin.poll()
    frames = [f for f in items if isinstance(f, Frame)]
    assert len(frames) == BLOCK_FRAMES
    more = [f for f in skin.poll() if isinstance(f, Frame)]
    assert [f.seq for f in frames + more] == list(range(2 * BLOCK_FRAMES))
    assert np.allclose(np.diff([f.t for f in frames + more]), 1 / 200)


def test_a_held_gesture_stays_until_lift_then_the_skin_rests():
    skin = OperatorSkin(2)
    skin.start()
    rest = _frames(skin, 10)  # 0.5 s untouched
    performance = skin.touch("swipe_up")
    _frames(skin, int(performance.phases.lift_start_s * 200 / BLOCK_FRAMES) + 2)
    assert skin.holding
    held = _frames(skin, 40)  # 2 s held: the fingers still press
    assert skin.touching and np.abs(held - rest.mean(axis=0)).max() > 5 * rest.std(axis=0).max()
    skin.lift()
    _frames(skin, 10)
    assert not skin.touching
    after = _frames(skin, 10)
    assert np.abs(after - rest.mean(axis=0)).max() < np.abs(held - rest.mean(axis=0)).max() / 5


def test_the_same_seed_and_acts_render_the_same_frames():
    def run() -> np.ndarray:
        skin = OperatorSkin(5)
        skin.start()
        first = _frames(skin, 3)
        skin.touch("swipe_left_2f")
        second = _frames(skin, 30)
        skin.lift()
        return np.concatenate([first, second, _frames(skin, 5)])

    assert np.array_equal(run(), run())
