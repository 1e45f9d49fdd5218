"""Tests of capture self-training (wovenskin.training.capture_selftrain) and per-group scaling."""

from dataclasses import replace

import numpy as np
import pytest
from test_training_captures import recipe, synthetic_captures

from wovenskin.errors import ConfigError
from wovenskin.recognition.checkpoint_meta import read_meta
from wovenskin.recording.formats import write_labelled_captures
from wovenskin.training.capture_lopo import leave_one_participant_out
from wovenskin.training.capture_prep import prepare_captures
from wovenskin.training.capture_selftrain import ADAPTED_DIR, pseudo_labels
from wovenskin.training.config import CAPTURE_DEFAULTS, CAPTURE_HPARAMS, CaptureConfig, TrainConfig
from wovenskin.training.datasets import CaptureNormalisation


def test_pseudo_labels_keep_the_confident_share_of_every_predicted_class():
    log_p = np.log(
        np.array(
            [
                [0.9, 0.05, 0.05],  # class 0, most confident
                [0.5, 0.4, 0.1],  # class 0, least
                [0.6, 0.3, 0.1],  # class 0
                [0.1, 0.8, 0.1],  # class 1
                [0.2, 0.2, 0.6],  # class 2
                [0.1, 0.1, 0.8],  # class 2, more confident
            ]
        )
    )
    positions, labels = pseudo_labels(log_p, 0.5)
    assert positions.tolist() == [0, 2, 3, 5]  # ceil(0.5 * 3) = 2 of class 0, 1 of 1, 1 of 2
    assert labels.tolist() == [0, 0, 1, 2]
    everything, _ = pseudo_labels(log_p, 1.0)
    assert everything.tolist() == list(range(6))
    with pytest.raises(ValueError, match="fraction"):
        pseudo_labels(log_p, 0.0)


def test_per_group_normalisation_divides_by_the_groups_median_spread():
    c = synthetic_captures(0, per_cell=2)
    norm = CaptureNormalisation(per_group=True).resolved(c)
    spreads = norm.group_spreads(c)
    assert set(spreads) == {"p1", "p2", "p3"}
    assert spreads["p3"] > 5 * spreads["p1"]  # the synthetic people press x1, x4, x15
    prepared = prepare_captures(c, norm, 1)
    for i in (0, 7, 15):
        frames = c.frames[i, : c.lengths[i]]
        offset, _ = norm.offset_and_spread(frames)
        scale = max(spreads[str(c.groups[i])], norm.floor_fraction * norm.reference_scale)
        np.testing.assert_allclose(prepared[i], (frames - offset) / scale, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match="group's spread"):
        norm.apply(c.frames[0])
    with pytest.raises(ConfigError, match="per_group"):
        CaptureNormalisation(per_group=1)  # type: ignore[arg-type]


@pytest.mark.slow  # trains tiny models
def test_self_training_never_reads_the_held_out_labels(tmp_path):
    c = synthetic_captures(0, per_cell=3)
    shuffled = c.labels.copy()
    held = np.flatnonzero(c.groups == "p2")
    shuffled[held] = np.random.default_rng(1).permutation(shuffled[held])
    config: TrainConfig = recipe(epochs=2, self_training_epochs=1)
    results = []
    for name, labels in (("true", c.labels), ("shuffled", shuffled)):
        path = tmp_path / f"{name}.npz"
        write_labelled_captures(path, replace(c, labels=labels))
        results.append(
            leave_one_participant_out(path, tmp_path / name, config, participants=["p2"])
        )
    a, b = (r.folds[0] for r in results)
    assert a.accuracy_before_self_training is not None
    assert (tmp_path / "true" / "fold-p2" / ADAPTED_DIR / "model.onnx").is_file()
    adapted = read_meta(tmp_path / "true" / "fold-p2" / ADAPTED_DIR).training_data["captures"]
    assert "p2" in adapted["train_groups"]  # pseudo-labelled captures of the new person
    # Same predictions whatever the held-out labels are: only the scoring reads them.
    np.testing.assert_allclose(a.evaluation.log_probs, b.evaluation.log_probs, atol=1e-6)
    d = results[0].to_dict()
    assert d["folds"][0]["capture_accuracy_before_self_training"] == (
        a.accuracy_before_self_training
    )


def test_the_default_capture_recipe_is_the_one_measured_on_haart():
    """docs/benchmarks.md's HAART figure (79.1 %, seed 0) was measured with exactly this."""
    d = CAPTURE_DEFAULTS
    assert (d.model, d.epochs, d.lr, d.patience, d.batch_size) == ("tcn", 20, 2e-3, 8, 64)
    assert d.seed == 0
    assert (d.weight_decay, d.label_smoothing, d.warmup_epochs) == (0.01, 0.05, 1.0)
    assert d.captures == CaptureConfig()  # per-capture scaling, no self-training
    assert (d.captures.frame_step, d.captures.window_frames, d.captures.eval_stride) == (2, 54, 14)
    assert (d.captures.windows_per_capture, d.captures.gain, d.captures.noise) == (8, 1.25, 0.01)
    assert d.captures.symmetries and d.captures.self_training_epochs == 0
    assert not d.captures.normalisation.per_group and d.captures.normalisation.per_capture
    assert d.resolved_hparams(CAPTURE_HPARAMS) == {
        "stem_channels": 8, "dim": 32, "window_norm": False,
    }  # fmt: skip
