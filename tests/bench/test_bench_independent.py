"""The independent stream generator (wovenskin.independent) and `bench gestures`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from module_graph import import_graph
from typer.testing import CliRunner

from wovenskin.bench.gesture_motion import analyse_ticks
from wovenskin.cli import app
from wovenskin.errors import ConfigError
from wovenskin.gestures import CLASS_NAMES, GESTURE_NAMES, INVALID
from wovenskin.independent import gesture_stream, mixed_stream
from wovenskin.independent.invalid import INVALID_KINDS
from wovenskin.independent.streams import HELD_S, Request, render_stream
from wovenskin.recognition.event_scoring import motion_starts
from wovenskin.recording.formats import read_labelled_stream, write_labelled_stream
from wovenskin.skin.layout import SkinLayout

EVERYTHING = [
    *(f"swipe_{d}:flick" for d in ("up", "down", "right", "left")),
    "swipe_up:held",
    "swipe_left:rest",
    "push:smooth",
    "push:land_press",
    *(name for name in GESTURE_NAMES if name not in ("push",) and "_" in name),
    *(f"invalid:{kind}" for kind in INVALID_KINDS),
    "idle:3",
    "swipe_down:held=1.0",
]


@pytest.fixture(scope="module")
def everything():
    return render_stream(EVERYTHING, seed=7)


def test_no_module_of_the_generator_reaches_the_simulator():
    graph = import_graph()
    mine = [m for m in graph if m.startswith("wovenskin.independent")]
    assert len(mine) >= 7
    seen, todo = set(), list(mine)
    while todo:  # everything the generator imports, directly or through other modules
        module = todo.pop()
        for target in graph[module]:
            if target not in seen:
                seen.add(target)
                todo.append(target)
    reached = sorted(m for m in seen if m == "wovenskin.sim" or m.startswith("wovenskin.sim."))
    assert not reached, f"the independent generator imports the simulator: {reached}"


def test_a_mixed_stream_has_the_labelled_stream_shape():
    stream = mixed_stream(40.0, seed=3)
    frames = stream.frames
    assert frames.shape == (8000, 10, 10) and frames.dtype == np.int32
    assert np.all(np.diff(stream.t) > 0) and stream.sample_rate_hz == 200.0
    n = len(stream.event_labels)
    assert n >= 8 and stream.event_start_s.shape == stream.event_end_s.shape == (n,)
    assert np.all(stream.event_end_s > stream.event_start_s)
    assert np.all(stream.event_start_s[1:] > stream.event_end_s[:-1])  # no overlaps
    assert stream.event_start_s[0] >= 1.2 and stream.event_end_s[-1] <= 40.0 - 2.0
    assert set(stream.event_labels) <= set(CLASS_NAMES)
    assert stream.metadata["generator"] == "wovenskin.independent"


def test_the_same_seed_gives_the_same_stream():
    a, b, c = mixed_stream(20.0, seed=5), mixed_stream(20.0, seed=5), mixed_stream(20.0, seed=6)
    assert np.array_equal(a.frames, b.frames)
    assert np.array_equal(a.event_start_s, b.event_start_s)
    assert a.metadata == b.metadata
    assert not np.array_equal(a.frames, c.frames)


def test_every_gesture_and_kind_is_made(everything):
    labels = set(everything.event_labels)
    assert labels == set(CLASS_NAMES)
    kinds = {e["kind"] for e in everything.metadata["events"]}
    expected = {"flick", "held_swipe", "swipe_rest", "push_smooth", "push_land_press"}
    assert expected | {"swipe_2f", "circle", "pinch_2f", "pinch_5f", *INVALID_KINDS} <= kinds
    fingers = {e["label"]: e["fingers"] for e in everything.metadata["events"]}
    assert fingers["pinch_in_5f"] == 5 and fingers["swipe_up_2f"] == 2
    assert fingers["circle_cw_2f"] == 2 and fingers["swipe_left"] == 1


def test_labels_match_the_contacts_they_describe(everything):
    frames = everything.frames.astype(float)
    base = np.median(frames[:150], axis=0)
    noise = np.std(frames[:150] - base, axis=0).mean()
    change = np.abs(frames - base).max(axis=(1, 2))
    fs = everything.sample_rate_hz
    for e in everything.metadata["events"]:
        i0, i1 = int(e["start_s"] * fs), int(np.ceil(e["end_s"] * fs))
        assert change[i0:i1].max() > 5 * noise, e["kind"]  # something touched the skin
        phases = e["phases"]
        assert phases["landing_s"] == e["start_s"] and phases["lift_end_s"] == e["end_s"]
        if e["label"] != INVALID:
            assert e["start_s"] <= phases["motion_start_s"] < phases["motion_end_s"] <= e["end_s"]
    # The idle request: a 3 s gap before the next touch.
    events = everything.metadata["events"]
    k = next(i for i, e in enumerate(events) if e["kind"] == INVALID_KINDS[-1])
    assert events[k + 1]["start_s"] - events[k]["end_s"] == pytest.approx(3.0, abs=0.01)


def test_flicks_lift_at_once_and_held_swipes_hold(everything):
    kinds = [e["kind"] for e in everything.metadata["events"]]
    assert kinds.count("held_swipe") >= 2 and kinds.count("flick") >= 4
    for e in everything.metadata["events"]:
        p = e["phases"]
        if e["kind"] == "flick":
            assert p["lift_end_s"] - p["motion_end_s"] < 0.12
            assert p["lift_start_s"] <= p["motion_end_s"]
        if e["kind"] == "held_swipe":
            hold = e["params"]["rest_s"]
            assert hold in (HELD_S, 1.0)  # swipe_up:held and swipe_down:held=1.0
            assert p["lift_start_s"] - p["motion_end_s"] == pytest.approx(hold)


def test_push_variants_start_their_press_where_they_say(everything):
    pushes = {e["kind"]: e for e in everything.metadata["events"] if e["label"] == "push"}
    smooth, later = pushes["push_smooth"], pushes["push_land_press"]
    assert smooth["phases"]["motion_start_s"] - smooth["start_s"] < 0.01
    assert later["phases"]["motion_start_s"] - later["start_s"] > 0.1
    assert 0.15 <= smooth["params"]["press_s"] <= 0.4


def test_two_finger_swipes_hold_the_pair_at_any_angle():
    angles = []
    for seed in range(12):
        stream = render_stream(["swipe_right_2f", "swipe_up_2f"], seed=seed)
        angles += [e["params"]["pair_angle_to_motion_deg"] for e in stream.metadata["events"]]
    folded = np.abs(((np.array(angles) + 90.0) % 180.0) - 90.0)  # 0: in line, 90: side by side
    assert folded.min() < 30.0 and folded.max() > 60.0


def test_motion_starts_are_what_event_scoring_reads(everything):
    starts = motion_starts(everything)
    assert starts is not None
    labels = everything.event_labels
    assert np.isnan(starts[labels == INVALID]).all()
    assert np.isfinite(starts[labels != INVALID]).all()


def test_streams_round_trip_through_the_labelled_stream_format(tmp_path):
    stream = gesture_stream("swipe_left:held", seed=2)
    path = tmp_path / "held.npz"
    write_labelled_stream(path, stream)
    back = read_labelled_stream(path)
    assert np.array_equal(back.frames, stream.frames)
    assert list(back.event_labels) == ["swipe_left"]
    assert back.metadata["events"][0]["kind"] == "held_swipe"
    result = CliRunner().invoke(app, ["info", str(path)])
    assert result.exit_code == 0, result.output
    assert "swipe_left" in result.output


def test_other_layouts_work():
    layout = SkinLayout(rows=8, cols=12, row_pitch_mm=12.0, col_pitch_mm=8.0)
    stream = render_stream(["swipe_up:flick", "pinch_out_5f"], seed=1, layout=layout)
    assert stream.frames.shape[1:] == (8, 12)
    assert stream.metadata["layout"]["cols"] == 12


@pytest.mark.parametrize(
    "request_text", ["swipe_up:held=x", "push:flick", "nope", "idle", "invalid:kick"]
)
def test_bad_requests_are_one_line_errors(request_text):
    with pytest.raises(ConfigError):
        Request.parse(request_text)


def test_brake_and_rest_times_from_ticks():
    t = np.arange(0.0, 3.0, 0.005)
    level = np.where(t < 1.0, 0.0, np.where(t < 2.0, 1.0, 0.0))
    fall = (t >= 2.0) & (t < 2.05)
    level[fall] = 1.0 - (t[fall] - 1.995) / 0.055
    speed = 0.05 * level
    speed[(t >= 2.05) & (t < 2.1)] = 0.002  # the arm settling after the command
    position = np.zeros((len(t), 3))
    position[:, 0] = np.cumsum(speed) * 0.005
    travel, brake, rest, still = analyse_ticks(t, level, position, speed, 0 * speed, 1.9)
    assert travel == pytest.approx(1000 * position[-1, 0], rel=1e-6)
    assert brake == pytest.approx(0.1, abs=1e-6)  # the first lower command, at 2.0 s
    assert rest == pytest.approx(0.2, abs=1e-6)  # the first tick below 1 mm/s, at 2.1 s
    assert not still
    none = analyse_ticks(t, 0 * level, 0 * position, 0 * speed, 0 * speed, 1.9)
    assert none[1:] == (None, None, False)


def test_bench_gestures_end_to_end():
    result = CliRunner().invoke(
        app,
        ["bench", "gestures", "--streams", "1", "--seconds", "20", "--flicks", "1",
         "--held", "1", "--hold", "0.5", "--json"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout.strip().splitlines()[-1])
    assert document["streams"] == 1 and document["recognition"]["events"] >= 1
    assert 0.0 <= document["recognition"]["f1"] <= 1.0
    assert set(document["motion"]) == {"flick", "held_swipe"}
    assert [r["kind"] for r in document["motion_runs"]] == ["flick", "held_swipe"]
    assert document["motion"]["held_swipe"]["streams"] == 1


def test_bench_gestures_refuses_bad_options():
    result = CliRunner().invoke(app, ["bench", "gestures", "--flicks", "-1"])
    assert result.exit_code == 2
    assert "--flicks -1: Input should be greater than or equal to 0" in result.output
    result = CliRunner().invoke(app, ["bench", "gestures", "--gain-scale", "0", "--flicks", "0"])
    assert result.exit_code == 2 and "--gain-scale 0: Input should be greater" in result.output


def test_bench_gestures_on_a_weak_skin_scores_weaker_streams():
    """``--gain-scale`` renders the mixed streams' skins that much weaker or stronger."""
    from wovenskin.bench.gestures import run_gestures_benchmark
    from wovenskin.recognition.pipeline import load_recognizer

    recognizer = load_recognizer(None, threads=1)
    weak = run_gestures_benchmark(
        recognizer, streams=1, seconds=20.0, flicks=0, held=0, gain_scale=0.12
    )
    assert weak.gain_scale == 0.12 and weak.to_dict()["gain_scale"] == 0.12
    assert weak.recognition["events"] >= 1


def test_bench_gestures_keeps_streams_only_in_a_new_folder(tmp_path):
    (tmp_path / "old.npz").write_bytes(b"")
    result = CliRunner().invoke(
        app, ["bench", "gestures", "--save-streams", str(tmp_path), "--streams", "0"]
    )
    assert result.exit_code == 2 and "not an empty folder" in result.output
    out = tmp_path / "kept"
    result = CliRunner().invoke(
        app,
        ["bench", "gestures", "--save-streams", str(out), "--streams", "0", "--flicks", "1",
         "--held", "0", "--json"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert [p.name for p in out.iterdir()] == ["flick-23000.npz"]


def test_fidgets_are_what_they_say():
    """A rub reverses along its line, a scribble bends, a slide has three fingertips and
    a rest four, and none of them is labelled a gesture."""
    from wovenskin.independent.invalid import perform_invalid
    from wovenskin.independent.people import Person
    from wovenskin.independent.performers import Trial
    from wovenskin.skin.layout import SkinLayout

    layout = SkinLayout()
    for seed in range(5):
        rng = np.random.default_rng(seed)
        trial = Trial(Person.draw(rng), rng, 200.0)
        rub = perform_invalid("rub", trial, layout)
        (finger,) = rub.fingers
        on = finger.contact()
        x, y = finger.x[on] - finger.x[on][0], finger.y[on] - finger.y[on][0]
        heading = np.arctan2(y[np.argmax(np.hypot(x, y))], x[np.argmax(np.hypot(x, y))])
        along = x * np.cos(heading) + y * np.sin(heading)
        assert (np.maximum.accumulate(along) - along).max() > 3.0  # it came back
        scribble = perform_invalid("scribble", trial, layout)
        (finger,) = scribble.fingers
        on = finger.contact()
        step = np.hypot(np.diff(finger.x[on]), np.diff(finger.y[on]))
        assert (
            np.hypot(finger.x[on][-1] - finger.x[on][0], finger.y[on][-1] - finger.y[on][0])
            < step.sum()
        )
        assert len(perform_invalid("slide3", trial, layout).fingers) == 3
        assert len(perform_invalid("rest4", trial, layout).fingers) == 4
        for kind in ("rub", "scribble", "slide3", "rest4"):
            assert perform_invalid(kind, trial, layout).label == INVALID
