"""``wovenskin adapt`` from the command line: a model directory, its report, its refusal."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.custom_gestures import CustomGesture
from wovenskin.independent.streams import render_stream
from wovenskin.recording.formats import write_labelled_stream

pytestmark = pytest.mark.slow  # fine-tunes models: a learning test, left out of `make test-fast`

pytest.importorskip("torch")

DOUBLE_TAP = CustomGesture(
    "double_tap", 1, "tap twice with one fingertip", strokes=(((0.0, 0.0),), ((0.0, 0.0),))
)
TINY = ["--epochs", "1", "--windows", "300", "--rehearsal", "1"]


@pytest.fixture(scope="module")
def person(tmp_path_factory):
    """Three trials of four gestures and a few invalid touches by one person on one skin,
    from the independent generator (not the project's simulator)."""
    path = tmp_path_factory.mktemp("person") / "person.npz"
    requests = ["swipe_up:rest", "push:smooth", "circle_cw_2f", "double_tap"] * 3
    requests += ["invalid:palm", "invalid:tap", "invalid:brush"]
    order = np.random.default_rng(3).permutation(len(requests))
    stream = render_stream(
        [requests[i] for i in order], 11, person_seed=5, skin_seed=5, custom=[DOUBLE_TAP]
    )
    write_labelled_stream(path, stream)
    return path


def _invoke(args: list[str]):
    return CliRunner().invoke(app, args, catch_exceptions=False)


def test_adapt_writes_a_model_directory_and_its_report(person, tmp_path):
    out = tmp_path / "mine"
    result = _invoke(["adapt", str(person), "--out", str(out), *TINY, "--force", "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout.strip().splitlines()[-1])
    assert document["accepted"] is True
    assert document["new_classes"] == ["double_tap"]  # a gesture of the person's own
    assert document["classes"][-2:] == ["double_tap", "invalid"]
    for key in ("held_out_before", "held_out_after", "arbiter", "arbiter_candidates"):
        assert document[key] is not None
    assert 0 <= document["held_out_after"]["f1"] <= 1
    assert document["splits"][0]["held_out_trials"] >= 1
    for name in ("model.onnx", "model.pt", "meta.json", "adapt.json"):
        assert (out / name).is_file()
    meta = json.loads((out / "meta.json").read_text())
    assert meta["arbiter"]["min_probability"] == document["arbiter"]["min_probability"]
    assert meta["training_data"]["adaptation"]["inputs"] == [str(person)]
    assert meta["class_names"] == document["classes"]
    assert not (out / ".adapt-work").exists()
    # a model like any other: the pipeline scores a stream with it
    scored = _invoke(["eval-stream", str(person), "--model", str(out), "--json"])
    assert scored.exit_code == 0, scored.output
    # and the directory is not replaced unasked
    again = _invoke(["adapt", str(person), "--out", str(out), *TINY])
    assert again.exit_code == 2 and "--overwrite" in again.output


def test_a_worse_model_is_refused_and_kept_aside(person, tmp_path, monkeypatch):
    """A learning rate 300x too high wrecks the weights: adapt must not install them."""
    from wovenskin.cli import adapt as adapt_command

    original = adapt_command.AdaptSettings

    def wrecking(**kwargs):
        return original(**{**kwargs, "lr": 0.3, "new_class_lr": 0.3})

    monkeypatch.setattr(adapt_command, "AdaptSettings", wrecking)
    out = tmp_path / "worse"
    result = _invoke(["adapt", str(person), "--out", str(out), *TINY])
    assert result.exit_code == 2, result.output
    assert "refused" in result.output or "worse" in result.output
    assert not (out / "model.onnx").exists()
    assert (out / "rejected" / "model.onnx").is_file()
    report = json.loads((out / "adapt.json").read_text())
    assert report["accepted"] is False


def test_bad_inputs_are_one_line(tmp_path):
    missing = _invoke(["adapt", str(tmp_path / "nope.npz"), "--out", str(tmp_path / "o")])
    assert missing.exit_code == 2 and "nope.npz" in missing.output
    assert "Traceback" not in missing.output
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip file at all")
    bad = _invoke(["adapt", str(junk), "--out", str(tmp_path / "o")])
    assert bad.exit_code == 2 and "Traceback" not in bad.output
