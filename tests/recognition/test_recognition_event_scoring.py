"""Tests of wovenskin.recognition.event_scoring: matching, duplicates, rates, aggregation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.recognition.arbiter import DWELL, FLICK, LIFT_OFF, CommandChange
from wovenskin.recognition.commandlog import Command
from wovenskin.recognition.event_scoring import (
    aggregate,
    motion_starts,
    per_class_table,
    score_commands,
    score_stream,
    scores_table,
)
from wovenskin.recording.formats import LabelledStream

STARTS = [1.0, 3.0, 5.0, 7.0]
ENDS = [1.5, 3.6, 5.5, 8.0]
LABELS = ["swipe_up", "push", "invalid", "circle_cw_2f"]


def log(*entries: tuple[float, str | None]) -> list[Command]:
    return [Command(t, g) for t, g in entries]


def test_scores_by_hand() -> None:
    commands = log(
        (1.2, "swipe_up"),  # detects swipe_up, latency 0.2
        (1.55, None),
        (1.58, "swipe_up"),  # the same command again inside its window: a duplicate
        (1.59, None),
        (3.2, "swipe_up"),  # wrong class during the push: false
        (3.4, "push"),  # detects push, latency 0.4
        (3.7, None),
        (5.2, "push"),  # during an invalid touch: false
        (5.6, None),
        (9.0, "swipe_up"),  # outside every event: false
    )
    s = score_commands(commands, STARTS, ENDS, LABELS, duration_s=60.0)
    assert (s.n_events, s.n_detected, s.n_missed) == (3, 2, 1)
    assert (s.n_activations, s.n_false, s.n_duplicates) == (6, 3, 1)
    assert (s.n_invalid_events, s.n_invalid_acted) == (1, 1)
    assert s.precision == pytest.approx(2 / 6)
    assert s.recall == pytest.approx(2 / 3)
    assert s.f1 == pytest.approx(2 * 2 / (2 * 2 + 4 + 1))
    assert s.false_per_min == pytest.approx(3.0)
    assert s.latencies_s == pytest.approx([0.2, 0.4])
    assert s.median_latency_s == pytest.approx(0.3)
    assert {k: v.recall for k, v in s.per_class.items()} == {
        "swipe_up": 1.0,
        "push": 1.0,
        "circle_cw_2f": 0.0,
    }
    assert s.false_by_gesture == {"swipe_up": 2, "push": 1}
    d = s.to_dict()
    assert d["f1"] == pytest.approx(4 / 9) and d["per_class_recall"]["circle_cw_2f"] == 0.0


def test_window_edges() -> None:
    def detected(t: float) -> int:
        return score_commands(log((t, "push")), [3.0], [3.6], ["push"], 10.0).n_detected

    assert detected(3.0) == 1  # at first contact
    assert detected(3.7) == 1  # exactly 0.1 s after the last lift-off
    assert detected(3.7001) == 0
    assert detected(2.999) == 0
    wide = score_commands(log((3.9, "push")), [3.0], [3.6], ["push"], 10.0, tolerance_s=0.3)
    assert wide.n_detected == 1


def test_repeated_lines_are_not_new_activations_and_matching_is_one_to_one() -> None:
    commands = log((1.2, "push"), (1.3, "push"), (1.4, None), (2.2, "push"))
    s = score_commands(commands, [1.0, 2.0], [1.5, 2.5], ["push", "push"], 10.0)
    assert (s.n_activations, s.n_detected, s.n_false, s.n_duplicates) == (2, 2, 0, 0)
    # One activation spanning two events detects only the first.
    s = score_commands(log((1.45, "push")), [1.0, 1.5], [1.5, 2.0], ["push", "push"], 10.0)
    assert (s.n_detected, s.n_missed) == (1, 1)


def test_a_flick_detects_its_event_and_a_flick_on_an_invalid_touch_is_false() -> None:
    flick = [CommandChange(1.52, "swipe_up", FLICK), CommandChange(1.52, None, LIFT_OFF)]
    s = score_commands(flick, [1.0], [1.5], ["swipe_up"], 10.0)
    assert (s.n_activations, s.n_detected, s.n_false, s.n_duplicates) == (1, 1, 0, 0)
    s = score_commands(flick, [1.0], [1.5], ["invalid"], 10.0)
    assert (s.n_detected, s.n_false, s.n_invalid_acted) == (0, 1, 1)
    # after a dwell command of the same touch, a second one is a duplicate
    both = [CommandChange(1.2, "swipe_up", DWELL), CommandChange(1.3, None, LIFT_OFF), *flick]
    s = score_commands(both, [1.0], [1.5], ["swipe_up"], 10.0)
    assert (s.n_detected, s.n_duplicates) == (1, 1)


def test_nothing_to_count() -> None:
    s = score_commands([], [], [], [], 30.0)
    assert (s.precision, s.recall, s.f1, s.false_per_min, s.median_latency_s) == (
        1.0,
        1.0,
        1.0,
        0.0,
        None,
    )
    s = score_commands([], [1.0], [2.0], ["push"], 30.0)
    assert (s.precision, s.recall, s.f1) == (1.0, 0.0, 0.0)


def test_bad_events_are_refused() -> None:
    with pytest.raises(ValueError, match="as many starts, ends and labels"):
        score_commands([], [1.0], [2.0, 3.0], ["push"], 10.0)
    with pytest.raises(ValueError, match="ends .* before it starts"):
        score_commands([], [2.0], [1.0], ["push"], 10.0)
    with pytest.raises(ValueError, match="duration"):
        score_commands([], [], [], [], -1.0)


def test_aggregate_pools_counts_and_latencies() -> None:
    a = score_commands(log((1.1, "push"), (1.4, None)), [1.0], [1.5], ["push"], 60.0)
    b = score_commands(
        log((1.3, "push"), (1.6, None), (2.4, "push"), (2.8, None), (9.0, "swipe_up")),
        [1.0, 2.0],
        [1.5, 2.5],
        ["push", "push"],
        60.0,
    )
    total = aggregate([a, b])
    assert (total.n_streams, total.n_events, total.n_detected, total.n_false) == (2, 3, 3, 1)
    assert total.duration_s == 120.0 and total.false_per_min == pytest.approx(0.5)
    # The median of all latencies (0.1, 0.3, 0.4), not the median of medians (0.1, 0.35).
    assert total.median_latency_s == pytest.approx(0.3)
    assert total.per_class["push"].events == 3
    assert scores_table([("a", a), ("b", b)], total).row_count == 3
    assert per_class_table(total).row_count == 2


def stream_with_events(events_metadata) -> LabelledStream:
    """12 s at 200 Hz with a swipe_up at 2 s and an invalid touch at 6 s; ``events_metadata``
    (unless None) is its ``metadata["events"]``."""
    return LabelledStream(
        frames=np.zeros((2400, 2, 2), dtype=np.float32),
        t=np.arange(2400) / 200.0,
        sample_rate_hz=200.0,
        event_start_s=np.array([2.0, 6.0]),
        event_end_s=np.array([2.5, 6.5]),
        event_labels=np.array(["swipe_up", "invalid"]),
        metadata={} if events_metadata is None else {"events": events_metadata},
    )


def test_score_stream_uses_the_stream_events_and_length() -> None:
    stream = stream_with_events(None)
    s = score_stream(log((2.2, "swipe_up"), (2.6, None), (6.1, "push")), stream)
    assert (s.duration_s, s.n_detected, s.n_false, s.n_invalid_acted) == (12.0, 1, 1, 1)
    assert s.false_per_min == pytest.approx(5.0)


def test_motion_latency_from_known_motion_starts() -> None:
    commands = log((1.2, "swipe_up"), (1.55, None), (3.4, "push"), (3.7, None))
    motion = [1.1, 3.05, None, float("nan")]  # unknown for the invalid and the circle
    s = score_commands(commands, STARTS, ENDS, LABELS, 60.0, motion_start_s=motion)
    assert s.latencies_s == pytest.approx([0.2, 0.4])
    assert s.motion_latencies_s == pytest.approx([0.1, 0.35])
    assert s.median_motion_latency_s == pytest.approx(0.225)
    assert s.to_dict()["median_motion_latency_s"] == pytest.approx(0.225)
    # A command issued before the motion starts has a negative motion latency.
    early = score_commands(log((1.05, "push")), [1.0], [1.5], ["push"], 10.0, motion_start_s=[1.2])
    assert early.motion_latencies_s == pytest.approx([-0.15])
    # Unknown motion starts: no motion latency, as before.
    plain = score_commands(commands, STARTS, ENDS, LABELS, 60.0)
    assert plain.motion_latencies_s == [] and plain.median_motion_latency_s is None
    assert plain.to_dict()["median_motion_latency_s"] is None
    with pytest.raises(ValueError, match="3 motion starts for 4 events"):
        score_commands(commands, STARTS, ENDS, LABELS, 60.0, motion_start_s=[1.0, 2.0, 3.0])


def test_aggregate_pools_motion_latencies_and_tables_show_them() -> None:
    a = score_commands(log((1.1, "push")), [1.0], [1.5], ["push"], 60.0, motion_start_s=[1.05])
    b = score_commands(
        log((1.3, "push"), (1.6, None), (2.4, "push")),
        [1.0, 2.0],
        [1.5, 2.5],
        ["push", "push"],
        60.0,
        motion_start_s=[1.1, 2.1],
    )
    c = score_commands(log((1.3, "push")), [1.0], [1.5], ["push"], 60.0)  # motion unknown
    total = aggregate([a, b, c])
    # Pooled (0.05, 0.2, 0.3), not a median of medians (0.05, 0.25).
    assert total.motion_latencies_s == pytest.approx([0.05, 0.2, 0.3])
    assert total.median_motion_latency_s == pytest.approx(0.2)
    table = scores_table([("a", a), ("c", c)], total)
    assert "motion ms" in [str(col.header) for col in table.columns]
    motion_column = next(col for col in table.columns if str(col.header) == "motion ms")
    assert list(motion_column.cells) == ["50", "-", "200"]


def test_score_stream_takes_motion_starts_from_simulated_metadata() -> None:
    events = [
        {"label": "swipe_up", "phases": {"landing_s": 2.0, "motion_start_s": 2.08}},
        {"label": "invalid", "phases": {"landing_s": 6.0, "motion_start_s": 6.0}},
    ]
    stream = stream_with_events(events)
    assert motion_starts(stream) == pytest.approx([2.08, 6.0])
    s = score_stream(log((2.2, "swipe_up"), (2.6, None)), stream)
    assert s.latencies_s == pytest.approx([0.2])
    assert s.median_motion_latency_s == pytest.approx(0.12)
    # Metadata that does not line up with the events is not used.
    for bad in (None, events[:1], [events[1], events[0]], "events"):
        stream = stream_with_events(bad)
        assert motion_starts(stream) is None
        assert score_stream(log((2.2, "swipe_up")), stream).median_motion_latency_s is None
    # An event without phases has an unknown motion start.
    partial = stream_with_events([{"label": "swipe_up"}, events[1]])
    assert np.isnan(motion_starts(partial)[0])
    assert score_stream(log((2.2, "swipe_up")), partial).motion_latencies_s == []


def test_simulated_streams_score_motion_latencies() -> None:
    from wovenskin.sim.stream import simulate_stream

    stream = simulate_stream(8.0, seed=3)
    starts = motion_starts(stream)
    assert starts is not None and len(starts) == len(stream.event_labels) >= 1
    assert np.all(starts >= stream.event_start_s - 1e-9) and np.all(starts <= stream.event_end_s)
    perfect = [
        Command(float(end), label)
        for end, label in zip(stream.event_end_s, stream.event_labels, strict=True)
        if label != "invalid"
    ]
    s = score_stream(perfect, stream)
    valid = stream.event_labels != "invalid"
    expected = (stream.event_end_s - starts)[valid]
    assert s.motion_latencies_s == pytest.approx(expected.tolist())


classes = st.sampled_from(["swipe_up", "push", "invalid"])


@settings(max_examples=150, deadline=None)
@given(
    events=st.lists(st.tuples(st.floats(0.1, 2.0), st.floats(0.05, 1.5), classes), max_size=8),
    commands=st.lists(
        st.tuples(st.floats(0.0, 1.0), st.sampled_from(["swipe_up", "push", None])), max_size=20
    ),
)
def test_counts_are_consistent(events, commands) -> None:
    starts, ends, labels, t = [], [], [], 0.0
    for gap, length, label in events:
        t += gap
        starts.append(t)
        ends.append(t + length)
        labels.append(label)
        t += length
    times = np.cumsum([c[0] for c in commands]).tolist()
    log_entries = [Command(ti, g) for ti, (_, g) in zip(times, commands, strict=True)]
    s = score_commands(log_entries, starts, ends, labels, duration_s=t + 1.0)
    assert s.n_detected + s.n_false + s.n_duplicates == s.n_activations
    assert 0 <= s.n_detected <= min(s.n_events, s.n_activations)
    assert s.n_events == sum(lab != "invalid" for lab in labels)
    assert sum(c.detected for c in s.per_class.values()) == s.n_detected
    assert all(0.0 <= x <= 1.0 for x in (s.precision, s.recall, s.f1))
    assert all(lat >= 0 for lat in s.latencies_s) and len(s.latencies_s) == s.n_detected
    # A perfect log (each valid event's class just after its start, none after its end)
    # detects everything with no false activation.
    perfect = []
    for a, b, lab in zip(starts, ends, labels, strict=True):
        if lab != "invalid":
            perfect += [Command(a + 0.01, lab), Command(b, None)]
    p = score_commands(perfect, starts, ends, labels, duration_s=t + 1.0)
    assert (p.recall, p.precision, p.n_false) == (1.0, 1.0, 0)
