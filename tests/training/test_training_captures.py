"""Tests of wovenskin.training.captures: training on labelled captures, capture scoring, LOPO."""

import json
import shutil
import subprocess
import sys
import textwrap
from dataclasses import replace

import numpy as np
import pytest
from paths import REPO

from tests.conftest import SHARED
from wovenskin.errors import ConfigError
from wovenskin.recognition.checkpoint_meta import read_meta
from wovenskin.recording.formats import (
    LabelledCaptures,
    read_labelled_captures,
    write_labelled_captures,
)
from wovenskin.training.capture_eval import evaluate_captures, score_captures
from wovenskin.training.capture_lopo import leave_one_participant_out
from wovenskin.training.capture_prep import (
    CaptureWindowArray,
    capture_windows,
    grid_symmetries,
    prepare_capture,
    prepare_captures,
    resample_frames,
    window_ending,
)
from wovenskin.training.capture_train import internal_validation, train_on_captures
from wovenskin.training.config import CAPTURE_DEFAULTS, CAPTURE_HPARAMS, CaptureConfig, TrainConfig
from wovenskin.training.datasets import CaptureNormalisation

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

HAART = SHARED / "datasets" / "haart" / "haart-train.npz"
REPO = REPO
RATE = 20.0
CLASSES = ["still", "tap", "none"]
TINY = replace(
    CAPTURE_DEFAULTS,
    hparams={"stem_channels": 4, "dim": 8, "n_blocks": 2, "window_norm": False},
    epochs=5,
    batch_size=16,
    lr=5e-3,
    threads=1,
    captures=CaptureConfig(frame_step=2, window_frames=10, eval_stride=5, windows_per_capture=16),
)


def recipe(**changes) -> TrainConfig:
    """TINY with ``changes``, the capture ones (window_frames...) applied to its captures."""
    feed = {k: changes.pop(k) for k in list(changes) if hasattr(TINY.captures, k)}
    return replace(TINY, captures=replace(TINY.captures, **feed), **changes)


def synthetic_captures(seed: int = 0, people=("p1", "p2", "p3"), per_cell: int = 4):
    """Captures of a 4x4 grid at 20 Hz: a still press, a 2 Hz tap, no touch; every person
    presses with another force (x1, x4, x15) and the contact sits anywhere on the grid."""
    rng = np.random.default_rng(seed)
    n_frames = 80
    t = np.arange(n_frames) / RATE
    frames, labels, groups = [], [], []
    for p, person in enumerate(people):
        force = [1.0, 4.0, 15.0][p % 3] * 40
        for label in range(len(CLASSES)):
            for _ in range(per_cell):
                x = rng.integers(0, 3, size=(n_frames, 4, 4)).astype(np.float64) + 5
                r, c = rng.integers(0, 3, size=2)
                if CLASSES[label] == "still":
                    x[:, r : r + 2, c : c + 2] += force
                elif CLASSES[label] == "tap":
                    on = (np.sin(2 * np.pi * 2.0 * t + rng.uniform(0, 6)) > 0).astype(float)
                    x[:, r : r + 2, c : c + 2] += force * on[:, None, None]
                frames.append(x)
                labels.append(label)
                groups.append(person)
    return LabelledCaptures(
        frames=np.round(np.stack(frames)).astype(np.uint16),
        lengths=np.full(len(labels), n_frames, dtype=np.int64),
        labels=np.array(labels, dtype=np.int64),
        class_names=list(CLASSES),
        groups=np.array(groups),
        sample_rate_hz=RATE,
    )


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny model trained on synthetic captures (shared by the tests that score)."""
    root = tmp_path_factory.mktemp("captures")
    path = root / "train.npz"
    write_labelled_captures(path, synthetic_captures(0))
    events = []
    result = train_on_captures(path, root / "model", replace(TINY, seed=0), progress=events.append)
    return path, root / "model", result, events


# --------------------------------------------------------------------------- preparation


def test_prepare_capture_normalises_then_averages_frame_pairs():
    frames = np.zeros((7, 2, 2))
    frames[:, 1, 1] = np.arange(7) * 10.0
    norm = CaptureNormalisation(reference_scale=10.0, per_capture=False, offset_quantile=0.0)
    out = prepare_capture(frames, norm, frame_step=2)
    assert out.shape == (3, 2, 2) and out.dtype == np.float32  # the odd last frame is dropped
    assert np.allclose(out[:, 1, 1], [0.5, 2.5, 4.5]) and np.all(out[:, 0, 0] == 0)
    assert np.allclose(prepare_capture(frames, norm, 1)[:, 1, 1], np.arange(7))
    assert prepare_capture(frames[:1], norm, 2).shape == (1, 2, 2)  # shorter than a step


def test_window_ending_pads_in_front_like_capture_windows():
    x = np.arange(6, dtype=np.float32).reshape(6, 1, 1)
    assert window_ending(x, 5, 3).ravel().tolist() == [3, 4, 5]
    assert window_ending(x, 1, 4).ravel().tolist() == [0, 0, 0, 1]
    assert np.array_equal(window_ending(x, 5, 8), capture_windows(x, 6, 8, 1)[0])


def test_grid_symmetries_are_the_distinct_flips_and_transposes():
    w = np.arange(2 * 3 * 3, dtype=np.float32).reshape(1, 2, 3, 3)
    views = list(grid_symmetries(w, transpose=True))
    assert len(views) == 8 and np.array_equal(views[0], w)
    assert len({v.tobytes() for v in (np.ascontiguousarray(v) for v in views)}) == 8
    for v in views:  # every view is a rearrangement of the same frame values
        assert np.array_equal(np.sort(v[0, 1].ravel()), np.sort(w[0, 1].ravel()))
    wide = np.zeros((1, 2, 3, 4))
    assert len(list(grid_symmetries(wide, transpose=True))) == 4  # no transpose off-square


def test_capture_window_array_is_random_per_read_and_deterministic():
    rng = np.random.default_rng(1)
    prepared = {0: rng.normal(size=(30, 3, 3)).astype(np.float32), 5: np.ones((4, 3, 3))}
    fixed = [(0, 29), (5, 3)]
    arr = CaptureWindowArray(prepared, 8, [0, 0, 0, 5], fixed, seed=3, symmetries=False)
    assert arr.shape == (6, 8, 3, 3) and len(arr) == 6
    first = arr[np.array([0, 1, 2])]
    assert np.array_equal(first, arr[np.array([0, 1, 2])])  # same read, same windows
    assert not np.array_equal(first[:2], arr[np.array([0, 1, 3])][:2])  # another batch
    windows_of_0 = capture_windows(prepared[0], 30, 8, 1)
    for w in first:  # without symmetries a random window is a slice of its capture
        assert any(np.array_equal(w, c) for c in windows_of_0)
    assert np.array_equal(arr[4], prepared[0][22:30])
    assert np.array_equal(arr[5], capture_windows(prepared[5], 4, 8, 1)[0])  # padded short one
    assert np.array_equal(arr[3][:4], np.zeros((4, 3, 3)))
    with pytest.raises(IndexError):
        arr[np.array([6])]
    other_seed = CaptureWindowArray(prepared, 8, [0, 0, 0, 5], fixed, seed=4)
    assert not np.array_equal(other_seed[np.array([0, 1, 2])], first)


def _views_of(window: np.ndarray) -> list[np.ndarray]:
    return [np.ascontiguousarray(v[0]) for v in grid_symmetries(window[None], transpose=True)]


def test_training_windows_are_drawn_under_all_eight_grid_symmetries():
    x = np.random.default_rng(2).normal(size=(12, 3, 3)).astype(np.float32)
    arr = CaptureWindowArray({0: x}, 12, np.zeros(400, dtype=np.int64), [], seed=1)
    views = _views_of(x)
    drawn = arr[np.arange(400)]
    seen = {next(k for k, v in enumerate(views) if np.array_equal(v, w)) for w in drawn}
    assert seen == set(range(8))  # every window is one view of the capture, and all occur


def test_resample_frames_interpolates_over_the_same_span():
    x = np.arange(5, dtype=np.float32).reshape(5, 1, 1) * 2.0
    assert np.allclose(resample_frames(x, 9).ravel(), np.arange(9))
    assert np.allclose(resample_frames(x, 3).ravel(), [0, 4, 8])
    assert resample_frames(np.ones((4, 2, 3), np.float32), 7).shape == (7, 2, 3)


def test_window_augmentation_gain_noise_and_time_stretch():
    t = np.arange(200, dtype=np.float32)
    x = np.broadcast_to(t[:, None, None], (200, 2, 2)).copy() + 1.0  # a ramp: rate is visible
    n = 300
    plain = CaptureWindowArray({0: x}, 20, np.zeros(n), [], symmetries=False, gain=1.5)
    gains = []
    for w in plain[np.arange(n)]:  # a gain only: a slice of the ramp times one factor
        steps = np.diff(w[:, 0, 0])
        assert np.allclose(steps, steps[0], rtol=1e-4)
        start = round(float(w[0, 0, 0] / steps[0]))
        assert np.allclose(w[:, 0, 0] / steps[0], np.arange(start, start + 20), atol=1e-2)
        assert 1 / 1.5 - 1e-5 <= steps[0] <= 1.5 + 1e-5
        gains.append(steps[0])
    gains = np.array(gains)
    assert gains.min() < 0.8 and gains.max() > 1.25  # spread log-uniformly over [1/1.5, 1.5]
    stretched = CaptureWindowArray({0: x}, 20, np.zeros(n), [], symmetries=False, time_stretch=1.3)
    rates = np.diff(stretched[np.arange(n)][:, :, 0, 0], axis=1).mean(axis=1)
    assert rates.min() >= (19 * 1 / 1.3 - 1) / 19 and rates.max() <= (19 * 1.3 + 1) / 19
    assert rates.min() < 0.85 and rates.max() > 1.15  # slower and faster playback both drawn
    noisy = CaptureWindowArray({0: x}, 20, np.zeros(n), [], symmetries=False, noise=0.1)
    residual = np.concatenate([np.diff(w[:, 0, 0]) - 1 for w in noisy[np.arange(n)]])
    assert 0.1 < residual.std() < 0.2  # the difference of two N(0, 0.1^2) draws: 0.14
    fixed = CaptureWindowArray({0: x}, 20, [0], [(0, 199)], gain=2.0, noise=1.0, time_stretch=2)
    assert np.array_equal(fixed[1], x[180:])  # validation windows are never augmented


def test_internal_validation_holds_out_one_capture_per_person_and_class():
    c = synthetic_captures(0)
    everything = np.arange(len(c.labels))
    train, val = internal_validation(c.labels, c.groups, everything, seed=0)
    assert len(val) == 9 and np.intersect1d(train, val).size == 0
    assert np.array_equal(np.union1d(train, val), everything)
    cells = {(str(c.groups[i]), int(c.labels[i])) for i in val}
    assert len(cells) == 9
    again = internal_validation(c.labels, c.groups, everything, seed=0)
    assert np.array_equal(again[1], val)
    small = np.flatnonzero(c.groups == "p1")[[0, 1, 4, 5]]  # two of each of two classes
    train_s, val_s = internal_validation(c.labels, c.groups, small)
    assert len(val_s) == 2 and len(train_s) == 2  # fallback: one of every class
    with pytest.raises(ValueError, match="too few captures"):
        internal_validation(c.labels, c.groups, small[[0, 2]])


# --------------------------------------------------------------------------- train / evaluate


def test_train_records_what_evaluation_needs(trained):
    path, model_dir, result, events = trained
    meta = read_meta(model_dir)
    assert (model_dir / "model.onnx").is_file() and (model_dir / "model.pt").is_file()
    assert meta.class_names == tuple(CLASSES) and meta.sample_rate_hz == RATE
    assert meta.window == TINY.captures.window_frames and (meta.rows, meta.cols) == (4, 4)
    assert meta.conditioning["frame_step"] == 2
    norm = CaptureNormalisation.from_dict(meta.conditioning["capture_normalisation"])
    assert norm.reference_scale is not None and norm.reference_scale > 0
    info = meta.training_data["captures"]
    assert info["recipe"]["eval_stride"] == TINY.captures.eval_stride
    assert info["n_train_captures"] + info["n_val_captures"] == 36
    assert info["val_groups"] == ["p1", "p2", "p3"]
    assert result.epochs_run >= 1 and 1 <= result.best_epoch <= result.epochs_run
    epochs = [e.epoch for e in events if e.kind == "epoch"]
    assert epochs == list(range(1, result.epochs_run + 1))
    assert any(e.kind == "batch" for e in events)


def test_resume_of_a_finished_run_keeps_its_result(trained, tmp_path):
    path, model_dir, result, _ = trained
    again = tmp_path / "model"
    shutil.copytree(model_dir, again)
    resumed = train_on_captures(path, again, replace(TINY, resume=True))
    assert resumed.best_epoch == result.best_epoch
    assert resumed.best_val_accuracy == result.best_val_accuracy
    with pytest.raises(ValueError, match="cannot resume"):
        train_on_captures(path, again, replace(TINY, lr=1e-3, resume=True))


def test_evaluation_needs_no_torch(trained):
    path, model_dir, _, _ = trained
    script = textwrap.dedent(
        f"""
        import sys
        from wovenskin.training.capture_eval import evaluate_captures
        d = evaluate_captures({str(path)!r}, {str(model_dir)!r}).to_dict()
        print("CAPTURES", d["n_captures"])
        print("TORCH", sorted(m for m in sys.modules if m == "torch" or m.startswith("torch.")))
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr
    assert "CAPTURES 36" in result.stdout and "TORCH []" in result.stdout


def test_evaluate_scores_new_captures_one_label_each(trained, tmp_path):
    _, model_dir, _, _ = trained
    test_path = tmp_path / "test.npz"
    write_labelled_captures(test_path, synthetic_captures(seed=7, people=("q1", "q2", "q3")))
    evaluation = evaluate_captures(test_path, model_dir)
    d = evaluation.to_dict()
    assert d["n_captures"] == 36 and d["n_windows"] == 36 * 7  # ends 9, 14, ..., 39
    assert d["capture_accuracy"] >= 0.9  # force x1..x15 and any position: learnt anyway
    assert d["window_accuracy"] >= 0.75
    assert d["class_names"] == CLASSES and set(d["per_class"]) == set(CLASSES)
    assert set(d["per_class"]["tap"]) == {"precision", "recall", "f1", "support"}
    assert np.sum(d["confusion"]) == 36 and np.sum(d["window_confusion"]) == 36 * 7
    assert set(d["per_group"]) == {"q1", "q2", "q3"}
    assert d["seen_in_training"] == 0 and d["warnings"] == []
    json.dumps(d)  # JSON-ready


def _transformed(c: LabelledCaptures, transform) -> LabelledCaptures:
    return replace(c, frames=np.ascontiguousarray(transform(c.frames)))


@pytest.mark.parametrize(
    "transform",
    [
        lambda f: np.rot90(f, 1, axes=(2, 3)),  # the sensor mounted a quarter turn round
        lambda f: np.rot90(f, 2, axes=(2, 3)),
        lambda f: f[:, :, ::-1],  # mounted upside down (rows mirrored)
        lambda f: f.transpose(0, 1, 3, 2),
    ],
    ids=["rot90", "rot180", "flip", "transpose"],
)
def test_capture_scores_do_not_change_when_the_sensor_is_rotated_or_flipped(
    trained, tmp_path, transform
):
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer

    _, model_dir, _, _ = trained
    c = synthetic_captures(seed=7, people=("q1",))
    recognizer = OnnxRecognizer(model_dir)
    plain = score_captures(recognizer, c)
    moved = score_captures(recognizer, _transformed(c, transform))
    assert plain.views == moved.views == 8
    assert np.allclose(plain.log_probs, moved.log_probs, atol=1e-4)
    assert np.array_equal(plain.predictions, moved.predictions)
    assert plain.capture_accuracy >= 0.9


def test_symmetric_training_makes_single_views_nearly_agree(trained):
    """Each view on its own already gives (nearly) the same class: training drew them all."""
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer

    _, model_dir, _, _ = trained
    c = synthetic_captures(seed=7, people=("q1",))
    recognizer = OnnxRecognizer(model_dir)
    stored = read_meta(model_dir).conditioning["capture_normalisation"]
    prepared = prepare_captures(c, CaptureNormalisation.from_dict(stored), TINY.captures.frame_step)
    batch = np.stack(
        [window_ending(x, len(x) - 1, TINY.captures.window_frames) for x in prepared.values()]
    )
    per_view = np.stack(
        [recognizer.predict_proba(np.ascontiguousarray(v)) for v in grid_symmetries(batch, True)]
    )
    agreement = (per_view.argmax(axis=2) == per_view[0].argmax(axis=1)).mean()
    assert agreement >= 0.9
    assert np.abs(per_view - per_view.mean(axis=0)).max() < 0.5


def test_evaluating_training_captures_is_flagged(trained):
    path, model_dir, result, events = trained
    d = evaluate_captures(path, model_dir).to_dict()
    n_train = read_meta(model_dir).training_data["captures"]["n_train_captures"]
    assert d["seen_in_training"] == n_train and "used to train" in d["warnings"][0]


def test_evaluate_refuses_files_and_models_that_do_not_match(trained, tmp_path):
    _, model_dir, _, _ = trained
    c = synthetic_captures(1, people=("q1",), per_cell=1)
    write_labelled_captures(tmp_path / "names.npz", replace(c, class_names=["a", "b", "c"]))
    with pytest.raises(ValueError, match=r"names.npz has classes a, b, c; model .* still"):
        evaluate_captures(tmp_path / "names.npz", model_dir)
    write_labelled_captures(tmp_path / "rate.npz", replace(c, sample_rate_hz=54.0))
    with pytest.raises(ValueError, match="sampled at 54 Hz; model .* expects 20 Hz"):
        evaluate_captures(tmp_path / "rate.npz", model_dir)
    with pytest.raises(FileNotFoundError, match="no such captures file"):
        evaluate_captures(tmp_path / "missing.npz", model_dir)
    streaming = tmp_path / "streaming-model"
    shutil.copytree(model_dir, streaming)
    meta = json.loads((streaming / "meta.json").read_text())
    meta["conditioning"] = {"smoothing_ms": 30.0}
    (streaming / "meta.json").write_text(json.dumps(meta))
    write_labelled_captures(tmp_path / "ok.npz", c)
    with pytest.raises(ValueError, match="not trained on labelled captures"):
        evaluate_captures(tmp_path / "ok.npz", streaming)


def test_val_groups_hold_out_whole_participants(tmp_path):
    path = tmp_path / "c.npz"
    write_labelled_captures(path, synthetic_captures(0, per_cell=2))
    config = recipe(epochs=1)
    train_on_captures(path, tmp_path / "m", config, val_groups=["p2"])
    info = read_meta(tmp_path / "m").training_data["captures"]
    assert info["val_groups"] == ["p2"] and info["train_groups"] == ["p1", "p3"]
    assert info["n_val_captures"] == 6
    with pytest.raises(ValueError, match="validation group.* p9 not in the file"):
        train_on_captures(path, tmp_path / "n", config, val_groups=["p9"])
    with pytest.raises(ValueError, match="every capture would be validation"):
        train_on_captures(path, tmp_path / "n", config, val_groups=["p1", "p2", "p3"])


def test_leave_one_participant_out(tmp_path):
    path = tmp_path / "c.npz"
    write_labelled_captures(path, synthetic_captures(0, per_cell=3))
    seen = []
    result = leave_one_participant_out(
        path, tmp_path / "lopo", recipe(epochs=2), on_fold=seen.append
    )
    assert [f.participant for f in result.folds] == ["p1", "p2", "p3"]
    assert [f.index for f in seen] == [1, 2, 3] and all(f.folds == 3 for f in seen)
    for fold in result.folds:
        assert fold.evaluation.captures.n == 9
        assert set(fold.evaluation.groups.tolist()) == {fold.participant}
        assert fold.evaluation.seen_in_training == 0  # the held-out person was never trained on
        train_groups = read_meta(fold.checkpoint_dir).training_data["captures"]["train_groups"]
        assert fold.participant not in train_groups
    d = json.loads((tmp_path / "lopo" / "lopo.json").read_text())
    assert d["n_captures"] == 27 and len(d["folds"]) == 3
    hits = sum(f.evaluation.capture_accuracy * 9 for f in result.folds)
    assert d["capture_accuracy"] == pytest.approx(hits / 27)
    assert d["mean_fold_capture_accuracy"] == pytest.approx(hits / 27)
    only = leave_one_participant_out(path, tmp_path / "one", recipe(epochs=1), participants=["p2"])
    assert [f.participant for f in only.folds] == ["p2"]
    with pytest.raises(ValueError, match="participant.* p7 not in"):
        leave_one_participant_out(path, tmp_path / "x", TINY, participants=["p7"])


def test_capture_settings_reject_bad_values_in_one_line():
    for settings, message in (
        ({"captures": {"window_frames": 0}}, "captures.window_frames: Input should be greater"),
        ({"lr": 0.0}, "lr: Input should be greater than 0"),
        ({"captures": {"time_stretch": 0.9}}, "captures.time_stretch"),
        ({"captures": {"gain": float("nan")}}, "captures.gain"),
        ({"captures": {"noise": -0.1}}, "captures.noise"),
        ({"label_smoothing": 1.0}, "label_smoothing"),
        ({"captures": {"frame_stride": 2}}, "unknown setting 'captures.frame_stride'"),
    ):
        with pytest.raises(ConfigError, match=message) as error:
            TrainConfig.from_dict(settings)
        assert "\n" not in str(error.value)
    with pytest.raises(ConfigError, match="captures.window_frames"):
        train_on_captures("unused.npz", "unused", recipe(window_frames=0))
    assert CAPTURE_DEFAULTS.resolved_hparams(CAPTURE_HPARAMS)["dim"] == 32
    assert CAPTURE_DEFAULTS.with_model("bilstm").resolved_hparams(CAPTURE_HPARAMS) == {}


# --------------------------------------------------------------------------- real data


@pytest.mark.skipif(not HAART.exists(), reason="HAART captures not available")
def test_haart_two_participants_train_and_score(tmp_path):
    c = read_labelled_captures(HAART)
    keep = np.flatnonzero(np.isin(c.groups, ["p3", "p4"]))[::4]  # 42 captures, all classes
    subset = LabelledCaptures(
        c.frames[keep, :216], np.minimum(c.lengths[keep], 216), c.labels[keep],
        c.class_names, c.groups[keep], c.sample_rate_hz,
    )  # fmt: skip
    path = tmp_path / "haart-small.npz"
    write_labelled_captures(path, subset)
    prepared = prepare_captures(subset, CaptureNormalisation().resolved(subset), 2)
    assert prepared[0].shape == (108, 10, 10)
    train_on_captures(path, tmp_path / "m", recipe(window_frames=54, eval_stride=27, epochs=1))
    d = evaluate_captures(path, tmp_path / "m").to_dict()
    assert d["n_captures"] == len(keep) and d["n_windows"] == 3 * len(keep)
    assert d["class_names"] == list(c.class_names)
    assert np.sum(d["confusion"]) == len(keep)
