"""Tests of window data sets: generation, storage, reading back and splits."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import SHARED
from wovenskin.gestures import CLASS_NAMES, INVALID
from wovenskin.outputs import OutputExistsError
from wovenskin.recording.formats import (
    LabelledCaptures,
    read_labelled_stream,
    write_labelled_captures,
    write_labelled_stream,
)
from wovenskin.recording.native import recording_from_labelled_stream, write_recording
from wovenskin.sim.person import Person
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.sim.stream import simulate_stream
from wovenskin.training.datasets import (
    GROUP_KEYS,
    CaptureNormalisation,
    DatasetError,
    WindowDataset,
    build_dataset_from_captures,
    build_dataset_from_streams,
    generate_sim_dataset,
    grouped_split,
    leave_one_group_out,
    open_dataset,
    random_split,
    shared_groups,
    sim_person_name,
    sim_skin_name,
    stream_identity,
)
from wovenskin.training.datasets.streams import motion_end_s
from wovenskin.training.window_settings import SOURCE_CODES, SOURCE_NAMES

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

TINY = dict(
    n_recordings=3,
    windows_per_recording=42,
    invalid_windows_per_recording=14,
    seconds_per_recording=20.0,
    seed=11,
)
HAART = SHARED / "datasets" / "haart" / "haart-train.npz"


def files_of(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


@pytest.fixture(scope="module")
def sim_sets(tmp_path_factory):
    """The same tiny simulated set made by one process and by two, plus progress reports."""
    root = tmp_path_factory.mktemp("sim")
    reports: dict[int, list[tuple[int, int]]] = {1: [], 2: []}
    for workers in (1, 2):
        generate_sim_dataset(
            root / f"w{workers}",
            workers=workers,
            progress=lambda done, total, w=workers: reports[w].append((done, total)),
            **TINY,
        )
    return root, reports


@pytest.fixture(scope="module")
def sim_set(sim_sets) -> WindowDataset:
    return open_dataset(sim_sets[0] / "w2")


# ---------------------------------------------------------------------------- generation


def test_one_or_two_workers_write_byte_identical_sets(sim_sets):
    root, reports = sim_sets
    one, two = files_of(root / "w1"), files_of(root / "w2")
    assert one.keys() == two.keys()
    assert {"windows.npy", "labels.npy", "meta.json", "groups.json"} <= one.keys()
    assert all(one[name] == two[name] for name in one), "files differ between 1 and 2 workers"
    for workers in (1, 2):
        assert reports[workers][0] == (0, 3) and reports[workers][-1] == (3, 3)
        assert [d for d, _ in reports[workers]] == [0, 1, 2, 3]
    assert not any(p.name.startswith(".") for p in root.iterdir()), "partial directory left"


def test_sim_set_contents(sim_set):
    ds = sim_set
    n = 3 * (42 + 14)
    assert len(ds) == n and ds.windows.shape == (n, 30, 10, 10)
    assert isinstance(ds.windows, np.memmap) and ds.windows.dtype == np.float16
    assert ds.labels.dtype == np.int16 and ds.source.dtype == np.int8
    assert ds.class_names == list(CLASS_NAMES)
    assert (ds.rows, ds.cols, ds.window_frames, ds.sample_rate_hz) == (10, 10, 30, 200.0)
    assert ds.conditioning is not None and ds.conditioning.sample_rate_hz == 200.0
    counts = ds.class_counts()
    assert counts[INVALID] == 3 * 14 and sum(counts.values()) == n
    assert ds.meta["class_counts"] == counts
    for r, info in enumerate(ds.recordings):  # balanced over the gestures each one performed
        per_class = np.bincount(ds.labels[ds.recording == r], minlength=len(CLASS_NAMES))
        performed = {CLASS_NAMES.index(name) for name in info["events"] if name != INVALID}
        windowed = np.flatnonzero(per_class[:-1])
        assert set(windowed.tolist()) <= performed and 2 * len(windowed) >= len(performed)
        assert np.ptp(per_class[windowed]) <= 1
    assert ds.meta["seed"] == 11 and ds.meta["wovenskin_version"]
    assert ds.meta["generation"]["n_recordings"] == 3
    assert ds.meta["source_names"] == list(SOURCE_NAMES)
    assert np.all(np.isfinite(np.asarray(ds.windows, dtype=np.float32)))
    # every window has its recording's groups; recordings are contiguous blocks
    assert ds.recording.tolist() == np.repeat(np.arange(3), 56).tolist()
    assert (
        len(ds.recordings) == 3 and ds.recordings[0]["recording"] == ds.group_names["recording"][0]
    )


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked workers: Linux only")
def test_two_workers_run_from_a_script_without_a_main_guard(tmp_path):
    script = tmp_path / "make.py"
    script.write_text(
        "from wovenskin.training.datasets import generate_sim_dataset\n"
        f"ds = generate_sim_dataset({str(tmp_path / 'ds')!r}, n_recordings=2, workers=2,\n"
        "    windows_per_recording=14, invalid_windows_per_recording=2, seconds_per_recording=8)\n"
        "print(len(ds))\n"
    )
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "32"


def test_each_simulated_recording_has_its_own_person_and_skin(sim_set):
    ds = sim_set
    assert ds.unique_per_recording("person") and ds.unique_per_recording("skin")
    assert ds.meta["unique_per_recording"] == {"person": True, "skin": True}
    for info in ds.recordings:
        person = Person.from_dict(info["person_traits"])
        skin = SkinPhysics.from_dict(info["skin_physics"])
        assert info["person"] == sim_person_name(person)
        assert info["skin"] == sim_skin_name(skin)
    assert len(set(ds.group_names["person"])) == len(set(ds.group_names["skin"])) == 3


def test_a_smaller_set_is_a_prefix_of_a_larger_one(tmp_path, sim_set):
    small = generate_sim_dataset(tmp_path / "one", workers=1, **{**TINY, "n_recordings": 1})
    block = len(small)
    assert np.array_equal(np.asarray(small.windows), np.asarray(sim_set.windows[:block]))
    assert np.array_equal(small.labels, sim_set.labels[:block])


def test_generation_refuses_to_overwrite_and_cleans_up(tmp_path, sim_sets):
    root, _ = sim_sets
    # every writer refuses an existing output the same way (wovenskin.outputs)
    with pytest.raises(OutputExistsError, match="already holds a data set"):
        generate_sim_dataset(root / "w1", **TINY)
    stranger = tmp_path / "notes"
    stranger.mkdir()
    (stranger / "todo.txt").write_text("keep me")
    with pytest.raises(DatasetError, match="not a window data set"):
        generate_sim_dataset(stranger, **TINY)
    with pytest.raises(DatasetError, match="n_recordings"):
        generate_sim_dataset(tmp_path / "none", **{**TINY, "n_recordings": 0})
    with pytest.raises(DatasetError, match="float16 or float32"):
        generate_sim_dataset(tmp_path / "f64", dtype="float64", **TINY)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes"]


def test_overwrite_replaces_a_data_set(tmp_path):
    args = {**TINY, "n_recordings": 1, "windows_per_recording": 14, "seconds_per_recording": 12}
    generate_sim_dataset(tmp_path / "ds", workers=1, **args)
    again = generate_sim_dataset(
        tmp_path / "ds", workers=1, overwrite=True, dtype="float32", **{**args, "seed": 12}
    )
    assert again.windows.dtype == np.float32 and again.meta["seed"] == 12


# ---------------------------------------------------------------------------- reading


def test_open_dataset_rejects_damaged_sets(tmp_path, sim_sets):
    root, _ = sim_sets
    with pytest.raises(DatasetError, match="no such data set"):
        open_dataset(tmp_path / "missing")

    def damaged(name: str, change) -> Path:
        target = tmp_path / name
        target.mkdir()
        for file, data in files_of(root / "w1").items():
            (target / file).write_bytes(data)
        change(target)
        return target

    cases = {
        "missing windows.npy": lambda d: (d / "windows.npy").unlink(),
        "meta.json does not describe": lambda d: (d / "meta.json").write_text("[]"),
        "cannot read meta.json": lambda d: (d / "meta.json").write_text("{"),
        "labels.npy must be integers of shape": lambda d: np.save(
            d / "labels.npy", np.zeros(3, np.int16)
        ),
        "person.npy holds ids outside": lambda d: np.save(
            d / "person.npy", np.full(168, 7, np.int32)
        ),
        "windows.npy is corrupt": lambda d: (d / "windows.npy").write_bytes(b"garbage"),
        "groups.json must map": lambda d: (d / "groups.json").write_text('{"person": []}'),
    }
    for i, (message, change) in enumerate(cases.items()):
        with pytest.raises(DatasetError, match=message):
            open_dataset(damaged(f"case{i}", change))
    meta = json.loads((root / "w1" / "meta.json").read_text())
    meta["rows"] = 12
    with pytest.raises(DatasetError, match="meta.json says"):
        open_dataset(damaged("rows", lambda d: (d / "meta.json").write_text(json.dumps(meta))))


# ---------------------------------------------------------------------------- streams


@pytest.fixture(scope="module")
def stream_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("streams")
    a = simulate_stream(16.0, 1)
    b = simulate_stream(16.0, 2)
    write_labelled_stream(root / "a.npz", a)
    write_recording(root / "b.wsrec", recording_from_labelled_stream(b))
    return root, a, b


def test_build_from_streams_and_recordings(tmp_path, stream_files):
    root, a, _ = stream_files
    paths = [root / "a.npz", root / "b.wsrec"]
    ds = build_dataset_from_streams(
        tmp_path / "ds", paths, windows_per_recording=28, invalid_windows_per_recording=7, workers=1
    )
    assert len(ds) == 70 and ds.meta["kind"] == "streams"
    assert ds.meta["sample_rate_hz"] == 200.0
    assert ds.group_names["recording"] == ["00000-a.npz", "00001-b.wsrec"]
    person, skin = stream_identity(read_labelled_stream(root / "a.npz"))
    assert person == sim_person_name(Person.from_dict(a.metadata["person"]))
    assert skin == sim_skin_name(SkinPhysics.from_dict(a.metadata["physics"]))
    assert ds.group_names["person"] == [person, "unknown"]  # the .wsrec names no participant
    # the simulator's motion end survives the file and bounds the informative span
    motion_end = motion_end_s(read_labelled_stream(root / "a.npz"))
    is_gesture = a.event_labels != INVALID
    assert np.all(np.isfinite(motion_end[is_gesture])) and np.all(np.isnan(motion_end[~is_gesture]))
    # (a flick lifts off while still moving: its motion may end a few frames after lift-off)
    assert np.all(motion_end[is_gesture] <= a.event_end_s[is_gesture] + 0.05)
    assert ds.recordings[0]["dropped_events"] == []
    named = build_dataset_from_streams(
        tmp_path / "named", paths, windows_per_recording=14, invalid_windows_per_recording=0,
        persons=["ann", "bob"], skins=["s1", "s1"], workers=2,
    )  # fmt: skip
    assert named.group_names["person"] == ["ann", "bob"] and named.group_names["skin"] == ["s1"]
    assert named.class_counts()[INVALID] == 0


def test_build_from_streams_reports_bad_input(tmp_path, stream_files):
    root, a, _ = stream_files
    with pytest.raises(DatasetError, match="no such file"):
        build_dataset_from_streams(tmp_path / "x", [root / "missing.npz"])
    renamed = simulate_stream(8.0, 3)
    renamed.event_labels = np.array(["wave"] * len(renamed.event_labels))
    write_labelled_stream(tmp_path / "wave.npz", renamed)
    with pytest.raises(DatasetError, match="'wave' are not known classes"):
        build_dataset_from_streams(tmp_path / "y", [tmp_path / "wave.npz"], workers=1)
    slow = simulate_stream(8.0, 4, sample_rate_hz=100.0)
    write_labelled_stream(tmp_path / "slow.npz", slow)
    with pytest.raises(DatasetError, match="slow.npz: the stream runs at 100 Hz"):
        build_dataset_from_streams(tmp_path / "z", [root / "a.npz", tmp_path / "slow.npz"])
    with pytest.raises(DatasetError, match="one name per recording"):
        build_dataset_from_streams(tmp_path / "w", [root / "a.npz"], persons=["a", "b"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["slow.npz", "wave.npz"]


# ---------------------------------------------------------------------------- captures


def write_captures(path: Path) -> LabelledCaptures:
    """Four tiny captures of two people: a strong press, a weak press and two no-touch."""
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 3, size=(4, 50, 3, 4)).astype(np.int64) + 10
    frames[0, :, 1, 1] += 400  # a sustained press: one channel all along
    frames[1, 10:30, 2, 2] += 40
    captures = LabelledCaptures(
        frames=frames,
        lengths=np.array([50, 40, 50, 12]),
        labels=np.array([0, 0, 1, 1]),
        class_names=["press", "none"],
        groups=np.array(["p1", "p2", "p1", "p2"]),
        sample_rate_hz=54.0,
        metadata={"cover": np.array(["fur", "fur", "silk", "silk"])},
    )
    write_labelled_captures(path, captures)
    return captures


def test_build_from_captures(tmp_path):
    captures = write_captures(tmp_path / "caps.npz")
    ds = build_dataset_from_captures(tmp_path / "ds", tmp_path / "caps.npz", window_frames=20)
    ends_per_capture = [4, 3, 4, 1]  # stride 10: ends 19, 29, 39, 49 | 19, 29, 39 | ... | 11
    assert len(ds) == sum(ends_per_capture) and ds.windows.shape[1:] == (20, 3, 4)
    assert ds.class_names == ["press", "none"] and ds.sample_rate_hz == 54.0
    assert ds.meta["conditioning"] is None and ds.meta["kind"] == "captures"
    assert ds.group_names["person"] == ["p1", "p2"] and ds.group_names["skin"] == ["caps"]
    assert ds.recording.tolist() == np.repeat(np.arange(4), ends_per_capture).tolist()
    assert ds.labels.tolist() == np.repeat(captures.labels, ends_per_capture).tolist()
    assert ds.person.tolist() == np.repeat([0, 1, 0, 1], ends_per_capture).tolist()
    assert np.all(ds.source == SOURCE_CODES["capture"])
    assert [r["cover"] for r in ds.recordings] == ["fur", "fur", "silk", "silk"]
    w = np.asarray(ds.windows, dtype=np.float32)
    press = w[ds.recording == 0]
    assert np.allclose(press[:, :, 1, 1], 400 / 399.0, atol=0.02)  # the press keeps its signal
    short = w[ds.recording == 3][0]
    assert np.all(short[:8] == 0)  # 12 frames padded to 20 in front
    norm = CaptureNormalisation.from_dict(ds.meta["normalisation"])
    assert norm.reference_scale is not None and norm.reference_scale > 0
    assert np.abs(w[ds.labels == 1]).max() < 0.5  # no-touch is not blown up by the floor


def test_capture_normalisation():
    frames = np.zeros((100, 2, 2))
    frames[:, 0, 0] = 5.0  # offset
    frames[:, 1, 1] = np.linspace(5, 105, 100)
    frames[:, 0, 1] = 5.0
    frames[:, 1, 0] = 5.0
    norm = CaptureNormalisation(reference_scale=50.0)
    out = norm.apply(frames)
    offset, spread = norm.offset_and_spread(frames)
    assert offset == 5.0 and out.dtype == np.float32
    assert np.isclose(out[-1, 1, 1], 100 / spread)
    floored = CaptureNormalisation(reference_scale=1000.0, floor_fraction=0.5).apply(frames)
    assert np.isclose(floored[-1, 1, 1], 100 / 500.0)
    absolute = CaptureNormalisation(reference_scale=20.0, per_capture=False).apply(frames)
    assert np.isclose(absolute[-1, 1, 1], 5.0)
    with pytest.raises(ValueError, match="resolve the reference scale"):
        CaptureNormalisation().apply(frames)
    with pytest.raises(ValueError, match="offset_quantile < scale_quantile"):
        CaptureNormalisation(offset_quantile=0.9, scale_quantile=0.5)
    with pytest.raises(ValueError, match="bad capture normalisation: unknown setting"):
        CaptureNormalisation.from_dict({"gain": 2})


def test_bad_capture_files_give_one_line_errors(tmp_path):
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match="junk.npz: not a wovenskin data file"):  # as everywhere
        build_dataset_from_captures(tmp_path / "ds", tmp_path / "junk.npz")
    write_captures(tmp_path / "caps.npz")
    with pytest.raises(DatasetError, match="stride"):
        build_dataset_from_captures(tmp_path / "ds", tmp_path / "caps.npz", stride=0)


@pytest.mark.skipif(not HAART.exists(), reason="HAART captures not available")
def test_haart_leave_one_participant_out(tmp_path):
    ds = build_dataset_from_captures(tmp_path / "haart", HAART, stride=60)
    assert ds.sample_rate_hz == 54.0 and len(ds.class_names) == 7
    assert len(ds.group_names["recording"]) == 588
    folds = list(leave_one_group_out(ds))
    assert [f.name for f in folds] == [f"person={p}" for p in sorted(ds.group_names["person"])]
    assert len(folds) == 7
    for fold in folds:
        assert (
            shared_groups(ds, fold, "person") == [] and shared_groups(ds, fold, "recording") == []
        )
        assert len(fold.train) + len(fold.val) == len(ds)


# ---------------------------------------------------------------------------- splits


def synthetic_set(recording, person, skin) -> WindowDataset:
    """An in-memory set with the given per-window group ids (windows are not used)."""
    n = len(recording)
    ids = {
        k: np.asarray(v, dtype=np.int32)
        for k, v in zip(GROUP_KEYS, (recording, person, skin), strict=True)
    }
    return WindowDataset(
        windows=np.zeros((n, 1, 1, 1), np.float32),
        labels=np.zeros(n, np.int16),
        recording=ids["recording"],
        person=ids["person"],
        skin=ids["skin"],
        source=np.zeros(n, np.int8),
        group_names={k: [f"{k}{i}" for i in range(int(ids[k].max()) + 1)] for k in GROUP_KEYS},
        meta={"class_names": ["a"]},
    )


def test_random_split_is_the_papers_85_15(sim_set):
    split = random_split(sim_set, 0.15, seed=3)
    assert len(split.val) == round(0.15 * len(sim_set))
    assert np.union1d(split.train, split.val).tolist() == list(range(len(sim_set)))
    assert np.intersect1d(split.train, split.val).size == 0
    assert np.array_equal(split.val, random_split(sim_set, 0.15, seed=3).val)
    assert not np.array_equal(split.val, random_split(sim_set, 0.15, seed=4).val)
    with pytest.raises(DatasetError, match="val_fraction"):
        random_split(sim_set, 1.0)


def test_grouped_split_keeps_recordings_people_and_skins_apart(sim_set):
    split = grouped_split(sim_set, val_fraction=0.3, seed=0)
    for key in GROUP_KEYS:
        assert shared_groups(sim_set, split, key) == []
        assert split.held_out[key]
    assert len(split.held_out["recording"]) == 1  # the closest share to 30 % of 3 recordings
    # simulated: one person and one skin per recording, so splitting by recording alone is
    # the same split and also keeps people and skins apart
    by_recording = grouped_split(sim_set, val_fraction=0.3, seed=0, by=("recording",))
    assert np.array_equal(by_recording.val, split.val)
    assert shared_groups(sim_set, by_recording, "person") == []
    assert shared_groups(sim_set, by_recording, "skin") == []


def test_grouped_split_follows_shared_people_and_skins():
    # recordings 0 and 1 share a person; 1 and 2 share a skin; 3 and 4 stand alone
    recording = np.repeat(np.arange(5), 10)
    person = np.repeat([0, 0, 1, 2, 3], 10)
    skin = np.repeat([0, 1, 1, 2, 3], 10)
    ds = synthetic_set(recording, person, skin)
    for seed in range(6):
        split = grouped_split(ds, val_fraction=0.5, seed=seed)
        val_recordings = set(np.unique(recording[split.val]).tolist())
        assert {0, 1, 2} <= val_recordings or not val_recordings & {0, 1, 2}
        for key in GROUP_KEYS:
            assert shared_groups(ds, split, key) == []
    # grouping by recording alone lets a person appear on both sides somewhere
    leaks = [
        shared_groups(ds, grouped_split(ds, 0.4, seed=s, by=("recording",)), "person")
        for s in range(20)
    ]
    assert any(leaks)
    with pytest.raises(DatasetError, match="one component"):
        grouped_split(synthetic_set(recording, np.zeros(50), skin))
    with pytest.raises(DatasetError, match="unknown group key"):
        grouped_split(ds, by=("hand",))


def test_leave_one_group_out():
    ds = synthetic_set(np.arange(6), [0, 0, 1, 1, 2, 2], np.zeros(6))
    folds = list(leave_one_group_out(ds, "person"))
    assert [f.name for f in folds] == ["person=person0", "person=person1", "person=person2"]
    assert [f.val.tolist() for f in folds] == [[0, 1], [2, 3], [4, 5]]
    assert folds[1].train.tolist() == [0, 1, 4, 5] and folds[1].held_out["person"] == ["person1"]
    with pytest.raises(DatasetError, match="at least 2 skin groups"):
        list(leave_one_group_out(ds, "skin"))
