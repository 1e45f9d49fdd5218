"""Gestures of a user's own (issue 23): definitions in the mapping file, the class names a
mapping or model knows, the simulated person's stroke performer, and the session acting on
a custom class a model emits."""

from __future__ import annotations

import io
import json
from collections import Counter

import numpy as np
import pytest
from paths import REPO
from stand_ins import ContactMeans

from wovenskin.control.mapping import ActionMapping, PoseAction, TwistAction
from wovenskin.control.trace import TraceWriter
from wovenskin.custom_gestures import CustomGesture, custom_from_settings, parse_custom_gestures
from wovenskin.errors import ConfigError
from wovenskin.gestures import CLASS_NAMES, check_name, known_classes
from wovenskin.recognition.event_scoring import score_commands
from wovenskin.recording.files import unknown_labels, unknown_labels_message
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.runtime.session import open_session
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.stream import EventScheduler, parse_request, simulate_stream
from wovenskin.skin.layout import SkinLayout

EXAMPLE = REPO / "examples" / "custom_gestures.toml"
HEADER = '[gestures]\nswipe_up = "translate +z"\n'


def example() -> ActionMapping:
    return ActionMapping.load(EXAMPLE)


def contact_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` of each run of True."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    return list(zip(edges[::2], edges[1::2], strict=True))


# -- definitions -----------------------------------------------------------------------------


def test_the_example_mapping_defines_and_maps_two_gestures_beside_the_14() -> None:
    mapping = example()
    assert set(mapping.custom) == {"double_tap", "l_stroke"}
    tap, stroke = mapping.custom["double_tap"], mapping.custom["l_stroke"]
    assert tap.fingers == 1 and tap.strokes == (((0.0, 0.0),), ((0.0, 0.0),))
    assert tap.pause_s == 0.15 and tap.speed_mm_s is None
    assert stroke.strokes == (((0.0, -20.0), (0.0, 15.0), (20.0, 15.0)),)
    assert stroke.prompt == "l stroke: draw an L: down, then right"
    assert isinstance(mapping.actions["double_tap"], PoseAction)
    assert str(mapping.actions["l_stroke"]) == "rotate +z"
    assert mapping.class_names == (*CLASS_NAMES, "double_tap", "l_stroke")
    assert (
        mapping.prompted()[-2:] == ["double_tap", "l_stroke"]
        and "invalid" not in mapping.prompted()
    )
    assert len(mapping.prompted()) == 16
    default = ActionMapping.load()  # the 14 defaults stay as they are
    for name in CLASS_NAMES[:-1]:
        assert str(mapping.actions[name]) == str(default.actions[name])
    assert default.custom == {} and default.class_names == CLASS_NAMES
    assert mapping.resolve("l_stroke") == mapping.actions["l_stroke"]


def test_a_definition_round_trips_through_its_dict() -> None:
    for gesture in example().custom.values():
        assert parse_custom_gestures({gesture.name: gesture.to_dict()})[gesture.name] == gesture
    settings = {"custom_gestures": {g.name: g.to_dict() for g in example().custom.values()}}
    assert custom_from_settings(settings) == example().custom
    assert custom_from_settings({}) == {} and custom_from_settings(None) == {}


@pytest.mark.parametrize(
    ("table", "words"),
    [
        ("[custom_gestures.DoubleTap]\nfingers = 1", ["custom_gestures.DoubleTap", "lowercase"]),
        ("[custom_gestures.push]\nfingers = 1", ["custom_gestures.push", "built-in"]),
        ("[custom_gestures.invalid]\nfingers = 1", ["custom_gestures.invalid", "built-in"]),
        ("[custom_gestures.idle]\nfingers = 1", ["custom_gestures.idle", "reserved"]),
        ("[custom_gestures.tap]\nfingers = 6", ["custom_gestures.tap", "fingers", "1-5"]),
        ("[custom_gestures.tap]\nfingers = 0", ["custom_gestures.tap", "fingers"]),
        ('[custom_gestures.tap]\nfingers = "2"', ["custom_gestures.tap", "fingers"]),
        ("[custom_gestures.tap]\nfingers = true", ["custom_gestures.tap", "fingers"]),
        ("[custom_gestures.tap]\ndescription = 3", ["custom_gestures.tap", "description"]),
        ("[custom_gestures.tap]\nfinger = 1", ["custom_gestures.tap.finger", "unknown key"]),
        ("[custom_gestures.tap]\nstrokes = 5", ["custom_gestures.tap", "strokes"]),
        ("[custom_gestures.tap]\nstrokes = [[]]", ["custom_gestures.tap", "strokes[0]"]),
        (
            "[custom_gestures.tap]\nstrokes = [[[1, 2, 3]]]",
            ["custom_gestures.tap", "strokes[0][0]"],
        ),
        ('[custom_gestures.tap]\nstrokes = [[["a", 2]]]', ["strokes[0][0]"]),
        ("[custom_gestures.tap]\nstrokes = [[[0, 900]]]", ["strokes[0][0]", "200"]),
        ("[custom_gestures.tap]\nstrokes = [[[0, nan]]]", ["strokes[0][0]"]),
        ("[custom_gestures.tap]\nspeed_mm_s = 0", ["custom_gestures.tap", "speed_mm_s"]),
        ("[custom_gestures.tap]\npause_s = -1", ["custom_gestures.tap", "pause_s"]),
        ("[custom_gestures]\ntap = 3", ["custom_gestures.tap", "table"]),
        ("custom_gestures = 3", ["custom_gestures", "table"]),
        ('[gestures]\ntriple_tap = "pose home"', ["gestures.triple_tap", "unknown gesture"]),
    ],
)
def test_a_bad_definition_is_one_line_naming_the_key(table: str, words: list[str]) -> None:
    with pytest.raises(ConfigError) as info:
        ActionMapping.from_text(table, "my.toml")
    message = str(info.value)
    assert "\n" not in message and message.startswith("my.toml: ")
    for word in words:
        assert word in message, message


def test_a_mapped_gesture_needs_its_definition() -> None:
    defined = HEADER + 'tap2 = "pose home"\n[custom_gestures.tap2]\nfingers = 2\n'
    mapping = ActionMapping.from_text(defined)
    assert mapping.custom["tap2"].fingers == 2 and mapping.custom["tap2"].strokes == ()
    assert not mapping.custom["tap2"].performable
    with pytest.raises(ConfigError, match="gestures.tap2: unknown gesture"):
        ActionMapping.from_text(HEADER + 'tap2 = "pose home"\n')
    with pytest.raises(ConfigError, match="'invalid' never starts an action"):
        ActionMapping.from_text('[gestures]\ninvalid = "pose home"\n')


def test_known_class_names_count_custom_gestures() -> None:
    known = known_classes(["double_tap", "swipe_up", "double_tap"])
    assert known == (*CLASS_NAMES, "double_tap")
    assert check_name("double_tap", known) == "double_tap"
    with pytest.raises(ConfigError, match="unknown gesture 'double_tap'"):
        check_name("double_tap")
    labels = ["swipe_up", "double_tap", "double_tap", "wave"]
    assert unknown_labels(labels) == Counter({"double_tap": 2, "wave": 1})
    assert unknown_labels(labels, ["double_tap"]) == Counter({"wave": 1})
    assert "double_tap" in unknown_labels_message("f", Counter({"wave": 1}), ["double_tap"])
    with pytest.raises(ValueError, match="cannot score"):
        score_commands([], [1.0], [1.5], ["double_tap"], 5.0)
    scores = score_commands([], [1.0], [1.5], ["double_tap"], 5.0, known=["double_tap"])
    assert scores.n_events == 1 and scores.n_detected == 0


# -- the simulated person ----------------------------------------------------------------------


def test_the_simulated_person_performs_a_double_tap_as_two_touches() -> None:
    custom = example().custom
    for seed in range(4):
        rng = np.random.default_rng(seed)
        performance = perform("double_tap", Person.sample(rng), rng, custom=custom)
        assert performance.label == "double_tap" and performance.invalid_kind is None
        runs = contact_runs(performance.touching())
        assert len(runs) == 2, runs
        gap_s = (runs[1][0] - runs[0][1]) / performance.sample_rate_hz
        assert 0.08 < gap_s < 0.3  # pause_s = 0.15 (+-15 % per trial), plus the ramps
        for start, end in runs:  # a tap: down briefly, where it landed
            assert (end - start) / performance.sample_rate_hz < 0.35
        assert performance.event_start_s == pytest.approx(runs[0][0] / 200)
        assert performance.event_end_s == pytest.approx(runs[1][1] / 200)


def test_the_simulated_person_draws_an_l_down_then_right() -> None:
    custom = example().custom
    for seed in range(4):
        rng = np.random.default_rng(seed)
        performance = perform("l_stroke", Person.sample(rng), rng, custom=custom)
        (finger,) = performance.contacts
        on = finger.touching
        assert len(contact_runs(on)) == 1
        x, y = finger.x_mm[on], finger.y_mm[on]
        corner = int(np.argmax(y - x))  # the L's corner: low and left
        assert y[corner] - y[0] > 20  # down first (35 mm as written, scaled 0.8-1.2)
        assert abs(x[corner] - x[0]) < 10
        assert x[-1] - x[corner] > 10  # then right
        assert abs(y[-1] - y[corner]) < 8
        layout = SkinLayout()
        assert x.min() >= 0 and x.max() <= layout.width_mm
        assert y.min() >= 0 and y.max() <= layout.height_mm


def test_two_and_five_finger_scripts_use_that_many_fingers() -> None:
    rng = np.random.default_rng(2)
    person = Person.sample(rng)
    for fingers in (2, 3, 5):
        gesture = CustomGesture("zed", fingers, "a Z", [[[-15, -15], [15, -15], [-15, 15]]])
        performance = perform("zed", person, rng, custom={"zed": gesture})
        assert len(performance.fingertips()) == fingers


def test_a_custom_gesture_without_strokes_is_one_line_on_the_sim() -> None:
    custom = {"wave": CustomGesture("wave", 1, "wave at the skin")}
    rng = np.random.default_rng(0)
    with pytest.raises(ConfigError, match="'wave' has no strokes"):
        perform("wave", Person.sample(rng), rng, custom=custom)
    with pytest.raises(ConfigError, match="unknown gesture 'wave'"):
        parse_request("wave")
    assert parse_request("wave", custom) == ("wave", None)


def test_a_simulated_stream_mixes_custom_gestures_in() -> None:
    custom = example().custom
    rng = np.random.default_rng(1)
    scheduler = EventScheduler(
        rng, Person.sample(rng), SkinLayout(), ["double_tap", "l_stroke", "push"], 0.0,
        custom=custom,
    )  # fmt: skip
    labels = [scheduler.next_performance().label for _ in range(6)]
    assert Counter(labels) == Counter({"double_tap": 2, "l_stroke": 2, "push": 2})
    with pytest.raises(ConfigError):  # without the definitions the name is unknown
        simulate_stream(5.0, 1, gestures=["double_tap"])
    stream = simulate_stream(12.0, 1, gestures=["double_tap", "l_stroke"], custom=custom)
    assert set(stream.event_labels) <= {"double_tap", "l_stroke", "invalid"}
    assert {"double_tap", "l_stroke"} <= set(stream.event_labels)
    assert set(stream.metadata["custom_gestures"]) == {"double_tap", "l_stroke"}
    assert "custom_gestures" not in simulate_stream(3.0, 1).metadata


# -- the session acts on a custom class a model emits -----------------------------------------


class CustomMeans:
    """A stand-in model that knows the 15 classes and two custom ones, and calls every
    window with contact ``gesture`` (its meta class names include the custom ones)."""

    class_names = (*CLASS_NAMES, "double_tap", "l_stroke")

    class meta:  # noqa: N801 - the window length, as CheckpointMeta gives it
        window = 30

    def __init__(self, gesture: str) -> None:
        self.gesture = gesture

    def predict_proba(self, windows: np.ndarray) -> np.ndarray:
        out = np.zeros((len(windows), len(self.class_names)), dtype=np.float32)
        out[:, self.class_names.index(self.gesture)] = 1.0
        return out


def test_a_session_acts_on_the_custom_class_with_its_mapped_action(tmp_path) -> None:
    stream = simulate_stream(5.0, seed=3, gestures=["swipe_up"], invalid_fraction=0.0)
    path = tmp_path / "touches.npz"
    write_labelled_stream(path, stream)
    buffer = io.StringIO()
    session = open_session(
        f"replay:{path}", "sim", recognizer=CustomMeans("l_stroke"), fast_replay=True,
        mapping=EXAMPLE, trace=TraceWriter(buffer), poses=tmp_path / "poses.toml",
    )  # fmt: skip
    assert session.state.class_names[-2:] == ("double_tap", "l_stroke")
    result = session.run()
    session.close()
    assert result.errors == 0
    records = [json.loads(line) for line in buffer.getvalue().splitlines()]
    active = [r for r in records if r["gesture"] is not None]
    assert active and {r["gesture"] for r in active} == {"l_stroke"}
    action = example().action_for("l_stroke")
    assert isinstance(action, TwistAction) and action.kind == "rotate"
    first, last = active[0], active[-1]
    turned = abs(float(np.dot(first["quat"], last["quat"])))
    assert turned < 0.99999  # the tool turned (rotate +z) ...
    moved = np.linalg.norm(np.subtract(last["tcp"], first["tcp"]))
    assert moved < 0.003  # ... about its own centre: no translation


def test_a_session_says_when_its_model_does_not_know_a_mapped_gesture(tmp_path) -> None:
    path = tmp_path / "quiet.npz"
    write_labelled_stream(path, simulate_stream(2.0, seed=1, invalid_fraction=1.0))
    messages: list[str] = []
    session = open_session(
        f"replay:{path}", "sim", recognizer=ContactMeans("swipe_up"), fast_replay=True,
        mapping=EXAMPLE, poses=tmp_path / "poses.toml", on_message=messages.append,
    )  # fmt: skip
    session.close()
    (note,) = [m for m in messages if m.startswith("mapping:")]
    assert "'double_tap', 'l_stroke'" in note and "custom-gestures.md" in note
    assert note in session.state.messages
