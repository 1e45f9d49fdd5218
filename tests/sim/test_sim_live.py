"""Tests of the live simulated skin source (wovenskin.sim.live).

No test depends on how fast the machine runs: paced sources run on a :class:`_Clock` that
only the test advances, a frame at a time, and the test waits for the producer thread to
render all that is due before it polls or touches (:func:`_frames_for`), so which frames a
touch lands between is fixed by the clock alone.  The one test on the real clock checks
only that frames never run ahead of it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from wovenskin.errors import ConfigError
from wovenskin.runtime.sources import open_source
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.sim.live_touches import Fingertip
from wovenskin.skin.frames import Frame, SourceEvent
from wovenskin.skin.source import MAX_READER_LAG_S, SkinSource

FS = 200.0


def collect(source: SimulatedSkinSource, frames: int, guard_s: float = 20.0) -> list[Frame]:
    """Poll until ``frames`` frames arrived (a generous guard only prevents a hang)."""
    out: list[Frame] = []
    deadline = time.monotonic() + guard_s
    while len(out) < frames and time.monotonic() < deadline:
        out += [item for item in source.poll(0.05) if isinstance(item, Frame)]
    return out


@contextmanager
def _running(source: SimulatedSkinSource) -> Iterator[SimulatedSkinSource]:
    """``source`` started for the ``with`` block and closed after it, however it ends."""
    source.start()
    try:
        yield source
    finally:
        source.close()


class _Clock:
    """A wall clock for ``SimulatedSkinSource(clock=...)`` that moves only when told to."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _settle(source: SimulatedSkinSource) -> None:
    """Wait until ``source``'s producer has rendered all it will before its clock moves
    again: the frames due and the lookahead (the wait's guard only prevents a hang)."""
    guard = time.monotonic() + 20.0
    with source._cond:
        source._cond.notify_all()  # the producer may be waiting out its 20 ms nap
        while source._rendered < source._render_target():
            assert time.monotonic() < guard, "the simulated skin stopped rendering"
            source._cond.wait(0.05)


def _due(source: SimulatedSkinSource) -> list[Frame]:
    """The frames due by ``source``'s clock now, once its producer has settled."""
    _settle(source)
    return [item for item in source.poll(0.0) if isinstance(item, Frame)]


def _frames_for(source: SimulatedSkinSource, clock: _Clock, seconds: float) -> np.ndarray:
    """The frames' values ``source`` delivers while ``clock`` advances ``seconds``, polled
    a frame at a time (:func:`_due`)."""
    frames = []
    for _ in range(int(round(seconds * FS))):
        clock.now += 1.0 / FS
        frames += [f.values for f in _due(source)]
    return np.asarray(frames)


@contextmanager
def _stalled(source: SimulatedSkinSource, clock: _Clock, seconds: float) -> Iterator[None]:
    """For the ``with`` block, ``clock`` moved ``seconds`` on with ``source``'s producer
    stalled (a busy machine: it renders nothing meanwhile), so a touch sent in the block
    finds the rendered stream that much short of the lookahead."""
    with source._cond:  # the producer renders only with the lock
        clock.now += seconds
        yield


# Each sample sent with the producer keeping up, or after it stalled for the last 10 or 40 ms
# (the rendered stream short of the lookahead by as much: a busy machine).
_STALLS = pytest.mark.parametrize("stall_s", [0.0, 0.01, 0.04], ids=["keeping-up", "10ms", "40ms"])


def _virtual_skin(seed: int) -> tuple[SimulatedSkinSource, _Clock]:
    """A resting simulated skin as the dashboard opens it for outside fingertips (30 ms
    lookahead), paced by a clock the test advances."""
    clock = _Clock()
    return SimulatedSkinSource(seed=seed, autonomous=False, lookahead_s=0.03, clock=clock), clock


def _spy_on_tracks(source: SimulatedSkinSource, keep: Callable[[object], object]) -> list:
    """What ``keep`` makes of every contact track ``source``'s skin model renders, in order."""
    kept: list = []
    render = source._model.render

    def spy(contacts=(), n_frames=None, bursts=(), offset=0):
        kept.extend(keep(track) for track in contacts)
        return render(contacts, n_frames, bursts, offset)

    source._model.render = spy
    return kept


def _track_path(track) -> np.ndarray:
    """A rendered contact track as rows of x (mm), y (mm) and force (N)."""
    return np.stack([track.x_mm, track.y_mm, track.force_n], axis=1)


def test_from_options_parses_every_option():
    src = SimulatedSkinSource.from_options(
        {
            "seed": "3",
            "speed": "0",
            "rows": "6",
            "cols": "8",
            "gestures": "swipe_up+push",
            "idle": "0.3-0.6",
            "invalid": "0.1",
        }
    )
    assert (src.info.rows, src.info.cols, src.info.source) == (6, 8, "sim")
    assert src.info.units == "pF" and src.info.sample_rate_hz == FS
    assert src.seed == 3 and src.speed == 0.0
    assert src._scheduler.gestures == ["swipe_up", "push"]
    assert src._scheduler.idle_s == (0.3, 0.6)
    # "sim?gestures=swipe_up,push": a comma separates gestures too.
    listed = open_source("sim?gestures=swipe_up,push")
    assert listed._scheduler.gestures == ["swipe_up", "push"]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"speed": "fast"}, "number"),
        ({"speed": "-1"}, ">= 0"),
        ({"colour": "red"}, "unknown setting 'colour'.*sim options: seed, speed"),
        ({"gestures": "wave"}, "unknown gesture"),
        ({"idle": "a-b"}, "idle"),
        ({"rows": "0"}, "at least one"),
    ],
)
def test_from_options_rejects_bad_options(options, message):
    with pytest.raises(ConfigError, match=message):
        SimulatedSkinSource.from_options(options)


def test_open_source_streams_ordered_frames():
    src = open_source("sim:seed=1,speed=0")
    assert isinstance(src, SkinSource) and isinstance(src, SimulatedSkinSource)
    assert src.poll(0.01) == []  # not started yet
    src.start()
    src.start()  # idempotent
    try:
        first = src.poll(1.0)
        assert isinstance(first[0], SourceEvent) and first[0].kind == "connected"
        frames = [f for f in first if isinstance(f, Frame)] + collect(src, 600)
        seqs = np.array([f.seq for f in frames])
        assert len(frames) >= 600 and np.array_equal(seqs, np.arange(len(frames)))
        assert all(f.t == pytest.approx(f.seq / FS) for f in frames)
        assert frames[0].values.shape == (10, 10) and frames[0].values.dtype == np.float32
        values = np.stack([f.values for f in frames[: int(FS)]]).astype(np.float64)
        assert np.percentile(np.abs(values - np.median(values, axis=0)), 99) < 0.5
        assert all(e.start_s >= 1.0 for e in src.events)
        assert src.stats().good_frames == len(frames) and src.stats().connected
    finally:
        src.close()
        src.close()  # safe twice
    assert not src.stats().connected
    assert src.poll(0.01) == []
    with pytest.raises(RuntimeError, match="closed"):
        src.start()


def test_perform_queues_the_next_gesture_and_the_truth_is_reported():
    src = SimulatedSkinSource(
        seed=2, speed=0, gestures=["swipe_up"], invalid_fraction=0.0, max_batch=4
    )
    with _running(src):
        src.perform("pinch_out_5f")
        labels = set()
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and len(src.events) < 3:
            frames = [f for f in src.poll(0.05) if isinstance(f, Frame)]
            label = src.current_label()
            labels.add(label)
            if frames and label is not None:  # the truth matches the event timeline
                (event,) = [e for e in src.events if e.start_s <= frames[-1].t < e.end_s]
                assert event.label == label
        events = src.events
        assert [e.label for e in events[:3]] == ["pinch_out_5f", "swipe_up", "swipe_up"]
        assert {"pinch_out_5f", "swipe_up", None} <= labels
        with pytest.raises(ValueError, match="unknown gesture"):
            src.perform("wave")
        src.perform("invalid:palm")
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline and len(src.events) < 4:
            src.poll(0.05)
        assert src.events[3].label == "invalid" and src.events[3].invalid_kind == "palm"


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_frames_are_paced_by_the_clock(speed):
    """Frame ``k`` is due ``k / (speed x 200 Hz)`` after the start, stamped with the clock."""
    clock = _Clock()
    src = SimulatedSkinSource(seed=3, speed=speed, clock=clock)
    with _running(src):
        frames: list[Frame] = []
        for k in range(60):
            clock.now = (k + 0.25) / FS  # between frames: no rounding at a frame's edge
            new = _due(src)
            assert len(frames) + len(new) == int((k + 0.25) * speed) + 1  # exactly those due
            assert all(f.t_host == clock.now for f in new)
            frames += new
        assert [f.seq for f in frames] == list(range(len(frames)))


def test_frames_never_run_ahead_of_the_real_clock():
    src = SimulatedSkinSource(seed=3, speed=1.0)
    began = time.monotonic()
    with _running(src):
        frames = collect(src, 60)
        elapsed = time.monotonic() - began
    assert len(frames) >= 60
    assert frames[-1].t <= elapsed  # frame k is handed out k / 200 Hz after the start, not before
    assert all(b.seq == a.seq + 1 for a, b in zip(frames, frames[1:], strict=False))


def test_stop_pauses_and_start_resumes():
    clock = _Clock()
    src = SimulatedSkinSource(seed=4, speed=1.0, clock=clock)
    with _running(src):
        clock.now = 10.5 / FS  # mid-frame: 11 frames due
        _settle(src)
        src.send_command("stop")
        assert len(_due(src)) == 11  # frames due at the stop are still handed out
        clock.now += 0.3
        assert _due(src) == []  # paused: nothing more, however long
        src.send_command("start")
        clock.now += 10 / FS
        assert [f.seq for f in _due(src)] == list(range(11, 21))  # resumed where it paused
        src.send_command("recalibrate")
        with pytest.raises(ValueError, match="unknown skin command"):
            src.send_command("explode")


# -- outside fingertips (the dashboard's virtual skin) ----------------------------------------


def test_outside_fingertips_press_where_they_are_put_and_lift_off():
    source, clock = _virtual_skin(5)
    with _running(source):
        rest = _frames_for(source, clock, 0.4).mean(axis=0)
        source.set_touches({7: Fingertip(x_mm=75.0, y_mm=21.0, force_n=1.5)})  # row 1, col 7
        assert source.touching
        pressed = _frames_for(source, clock, 0.3)[-10:].mean(axis=0) - rest
        assert np.unravel_index(np.argmax(pressed), pressed.shape) == (1, 7)
        source.set_touches({7: Fingertip(x_mm=25.0, y_mm=119.0, force_n=1.5)})  # row 8, col 2
        moved = _frames_for(source, clock, 0.3)[-10:].mean(axis=0) - rest
        assert np.unravel_index(np.argmax(moved), moved.shape) == (8, 2)
        source.set_touches({})
        lifted = _frames_for(source, clock, 0.5)[-10:].mean(axis=0) - rest
        assert not source.touching
        assert lifted.max() < 0.2 * moved.max()
        assert source.current_label() is None  # outside touches are not the person's events


@pytest.mark.parametrize(
    "touches, message",
    [
        ({1: (10.0, 10.0, 1.0)}, "not a Fingertip"),
        ({k: None for k in range(11)}, "at most 10"),
    ],
)
def test_bad_outside_touches_are_refused(touches, message):
    source = SimulatedSkinSource(seed=1, autonomous=False)
    with pytest.raises(ValueError, match=message):
        source.set_touches(touches)


@pytest.mark.parametrize("values", [(float("nan"), 1.0, 1.0), (1.0, 1.0, -0.5), (1.0, "a", 1.0)])
def test_a_fingertip_must_be_finite_with_a_nonnegative_force(values):
    with pytest.raises(ValueError):
        Fingertip(*values)


def test_the_lookahead_option_is_checked():
    assert open_source("sim:lookahead=0.05").lookahead_s == 0.05
    with pytest.raises(ConfigError, match="lookahead"):
        open_source("sim:lookahead=0")


def test_timestamped_touches_keep_their_timing_however_bunched_they_arrive():
    source, clock = _virtual_skin(6)
    with _running(source):
        rest = _frames_for(source, clock, 0.4).mean(axis=0)
        # 0.4 s of a finger sliding from row 8 to row 1 (y 119 -> 21 mm), sent all at once
        for k in range(41):
            y = 119.0 - 98.0 * k / 40
            source.set_touches({1: Fingertip(50.0, y, 1.5)}, client_t=100.0 + 0.01 * k)
        frames = _frames_for(source, clock, 0.8) - rest
        source.set_touches({}, client_t=100.5)
        peaks = np.array([np.unravel_index(np.argmax(f), f.shape)[0] for f in frames])
        strong = np.array([f.max() for f in frames]) > 0.3 * frames.max()
        rows = peaks[strong]
        assert rows[0] >= 7 and rows[-1] <= 2  # from low to high on the skin
        first, last = np.flatnonzero(rows <= 6)[0], np.flatnonzero(rows >= 3)[-1]
        assert 40 <= last - first <= 100  # ~0.3 s of frames between rows 6 and 3: not a jump
        assert np.all(np.diff(rows) <= 1)  # it never goes back down


def test_a_touch_time_must_be_finite():
    source = SimulatedSkinSource(seed=1, autonomous=False)
    with pytest.raises(ValueError, match="finite"):
        source.set_touches({1: Fingertip(1.0, 1.0, 1.0)}, client_t=float("nan"))


def test_a_sender_clock_that_jumps_ahead_cannot_hold_back_the_touch():
    source, clock = _virtual_skin(3)
    with _running(source):
        rest = _frames_for(source, clock, 0.3).mean(axis=0)
        source.set_touches({1: Fingertip(50.0, 20.0, 1.5)}, client_t=10.0)
        source.set_touches({1: Fingertip(50.0, 120.0, 1.5)}, client_t=1e6)  # 11 days later
        frames = _frames_for(source, clock, 0.5) - rest
        rows = [np.unravel_index(np.argmax(f), f.shape)[0] for f in frames[-20:]]
        assert min(rows) >= 7  # the finger is where the second sample put it, now


def test_a_lifted_outside_fingertip_goes_at_once():
    source, clock = _virtual_skin(2)
    forces = _spy_on_tracks(source, lambda track: track.force_n)
    with _running(source):
        _frames_for(source, clock, 0.3)
        source.set_touches({1: Fingertip(40.0, 60.0, 1.0)}, client_t=5.0)
        _frames_for(source, clock, 0.2)
        assert source.touching and forces[-1][-1] == 1.0
        pressed = len(forces)
        source.set_touches({}, client_t=5.2)
        frames = 0
        while source.touching and frames < FS:
            _frames_for(source, clock, 1.0 / FS)
            frames += 1
        assert not source.touching
    lifting = np.concatenate(forces[pressed:])
    assert len(lifting) and not lifting.any()  # the force is gone in the next frame rendered
    # ... and the fringe field within 4 x 5 ms more: all within the lookahead (30 ms) of
    # the clock
    assert frames <= 0.03 * FS


@_STALLS
def test_sparse_samples_are_reconstructed_as_a_path_not_jumps(stall_s):
    """A busy page sends a stroke as a few samples, each arriving after the fingertip has
    already reached the previous one: the fingertip must still slide frame by frame at the
    drawn speed (a 10-20 mm jump between two frames looks like two fingers)."""
    source, clock = _virtual_skin(6)
    rendered = _spy_on_tracks(source, _track_path)
    with _running(source):
        _frames_for(source, clock, 0.2)
        for k in range(6):  # 0.4 s from y 119 to 21 mm in 6 samples, 80 ms apart, sent live
            _frames_for(source, clock, 0.08 - stall_s)
            with _stalled(source, clock, stall_s):
                source.set_touches({1: Fingertip(50.0, 119.0 - 98.0 * k / 5, 1.5)}, clock())
        _frames_for(source, clock, 0.08)
        source.set_touches({}, clock())
        _frames_for(source, clock, 0.5)
    path = np.concatenate(rendered)
    y = path[path[:, 2] > 0.5, 1]  # frames in firm contact
    assert y[0] > 110 and y[-1] < 30
    steps = np.abs(np.diff(y))
    assert steps.max() < 3.0, f"the fingertip jumped {steps.max():.1f} mm in one frame"
    moving = np.count_nonzero(steps > 0.05)
    assert 50 <= moving <= 110  # ~0.4 s of sliding at 200 frames/s: the drawn speed


@_STALLS
def test_sparse_samples_on_a_circle_follow_the_circle_not_its_chords(stall_s):
    """A busy page sends a circle as a few samples 60 degrees apart: between them the
    fingertip must follow the curve through the last three samples (the chords of a
    hexagon cut 2.7 mm inside a 20 mm circle and read as two-finger swipes)."""
    source, clock = _virtual_skin(6)
    rendered = _spy_on_tracks(source, _track_path)
    with _running(source):
        _frames_for(source, clock, 0.2)
        for k in range(9):  # 480 degrees of a 20 mm circle in 9 samples, 80 ms apart, live
            angle = np.radians(60.0 * k)
            tip = Fingertip(50.0 + 20.0 * np.cos(angle), 70.0 + 20.0 * np.sin(angle), 1.5)
            _frames_for(source, clock, 0.08 - stall_s)
            with _stalled(source, clock, stall_s):
                source.set_touches({1: tip}, clock())
        _frames_for(source, clock, 0.38)
        source.set_touches({}, clock())
        _frames_for(source, clock, 0.3)
    path = np.concatenate(rendered)
    path = path[path[:, 2] > 0.5]  # frames in firm contact
    dx, dy = path[:, 0] - 50.0, path[:, 1] - 70.0
    turned = np.degrees(np.unwrap(np.arctan2(dy, dx)))
    assert turned[-1] == pytest.approx(480.0, abs=1.0)
    radius = np.hypot(dx, dy)[turned > 121.0]  # from the third sample on
    assert len(radius) >= 40
    assert radius.min() > 19.0, f"cut {20.0 - radius.min():.1f} mm inside the circle"
    assert radius.max() < 20.5
    steps = np.hypot(np.diff(path[:, 0]), np.diff(path[:, 1]))
    assert steps.max() < 3.0  # still frame by frame, no jumps


@_STALLS
def test_sparse_samples_on_a_line_stay_on_the_line(stall_s):
    """Three or more collinear sparse samples give a straight stroke, not a curve."""
    source, clock = _virtual_skin(6)
    rendered = _spy_on_tracks(source, _track_path)
    with _running(source):
        _frames_for(source, clock, 0.2)
        for d in (0.0, 5.0, 20.0, 30.0, 55.0, 60.0):  # uneven steps along one line
            _frames_for(source, clock, 0.08 - stall_s)
            with _stalled(source, clock, stall_s):
                source.set_touches({1: Fingertip(20.0 + 0.6 * d, 30.0 + 0.8 * d, 1.5)}, clock())
        _frames_for(source, clock, 0.08)
        source.set_touches({}, clock())
        _frames_for(source, clock, 0.3)
    path = np.concatenate(rendered)
    path = path[path[:, 2] > 0.5]
    off_line = np.abs(0.8 * (path[:, 0] - 20.0) - 0.6 * (path[:, 1] - 30.0))
    assert off_line.max() < 1e-6
    along = 0.6 * (path[:, 0] - 20.0) + 0.8 * (path[:, 1] - 30.0)
    assert np.all(np.diff(along) >= -1e-9)  # onward only, no overshoot and back
    # the last frame that presses is the one before the fingertip reaches the last sample,
    # where it lifts: a lift-off plays at once
    assert along[-1] == pytest.approx(60.0, abs=0.5)


def test_performances_are_rendered_in_short_pieces():
    """A whole performance rendered at once took up to 130 ms (longer under load), more
    than the dashboard's 30 ms lookahead plus the 100 ms skin watchdog: the reader starved
    and the arm stopped.  Every render call now covers at most 50 ms of frames."""
    source = SimulatedSkinSource(seed=4, speed=0, idle_s=(0.05, 0.1), lookahead_s=0.25)
    sizes: list[int] = []
    render = source._model.render

    def spy(contacts=(), n_frames=None, bursts=(), offset=0):
        frames = render(contacts, n_frames, bursts, offset)
        sizes.append(len(frames))
        return frames

    source._model.render = spy
    with _running(source):
        collect(source, 2000)
        assert len(source.events) >= 3  # the person performed
    assert max(sizes) <= int(0.05 * FS)


@_STALLS
def test_a_sparse_press_rises_smoothly_between_its_samples(stall_s):
    """A busy page sends a mouse's rising press (push) as a few samples 100 ms apart: the
    fingertip's force must rise along the way, not in 20 ms steps."""
    source, clock = _virtual_skin(6)
    rendered = _spy_on_tracks(source, lambda track: track.force_n)
    with _running(source):
        _frames_for(source, clock, 0.2)
        source.set_touches({1: Fingertip(50.0, 70.0, 1.0)}, clock())
        _frames_for(source, clock, 0.3)
        for k in range(1, 5):  # 1 N -> 4 N in 4 steps, 100 ms apart, sent live
            _frames_for(source, clock, 0.1 - stall_s)
            with _stalled(source, clock, stall_s):
                source.set_touches({1: Fingertip(50.0, 70.0, 1.0 + 0.75 * k)}, clock())
        _frames_for(source, clock, 0.4)
        source.set_touches({}, clock())
        _frames_for(source, clock, 0.3)
    force = np.concatenate(rendered)
    first, last = np.flatnonzero(force > 1.02)[0], np.flatnonzero(force > 3.98)[0]
    rising = force[first - 1 : last + 1]
    assert np.all(np.diff(rising) >= -1e-9)  # it only rises ...
    assert np.diff(rising).max() < 0.1  # ... ~0.04 N per frame, never a 0.75 N step
    assert len(rising) >= 50  # over ~0.3-0.4 s of frames


def test_a_reader_that_falls_behind_slows_the_simulated_world():
    """A starved reader gets at most MAX_READER_LAG_S of frames at once: the stream clock
    is held back instead (no seconds-old touches acted on in one burst)."""
    source, clock = _virtual_skin(4)
    with _running(source):
        clock.now = 9.5 / FS  # mid-frame: 10 frames due
        assert len(_due(source)) == 10
        clock.now += 1.0  # the reader is busy elsewhere for a second
        burst = _due(source)
        assert len(burst) == MAX_READER_LAG_S * FS
        assert source.slowed_s == pytest.approx(1.0 - MAX_READER_LAG_S, abs=1.0 / FS)
        slowed, frames = source.slowed_s, []
        for _ in range(40):  # the reader keeps up again: so does the stream, held back
            clock.now += 1.0 / FS
            frames += _due(source)
        assert len(frames) == 40 and source.slowed_s == slowed
        seqs = [f.seq for f in burst + frames]
        assert seqs == list(range(10, 10 + len(seqs)))  # nothing skipped
