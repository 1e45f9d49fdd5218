"""Every default lives once, past the command line (issue 25, "Settings").

``test_cli_defaults.py`` holds each option to its home; this file holds the library to
the same homes: the functions an unset option falls through to name the home's constant
instead of writing its value again, the ``study.toml`` template states the study's
defaults, and an unset option really reaches the library unset (the effective default
is the home's).
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re

import pytest
import typer
from cli_helpers import invoke

from wovenskin.study.definition import TEMPLATE, StudyDefinition, init_study, load_study

_DATASET_COUNTS = ("windows_per_recording", "invalid_windows_per_recording", "workers", "dtype")

LIBRARY_DEFAULTS = {
    # (module, function or class) -> the parameters (fields) whose default names its home
    ("wovenskin.study.definition", "StudyDefinition"): ("time_limit_s",),
    ("wovenskin.study.simulate", "simulate_study"): (
        "participants",
        "trials",
        "time_limit_s",
        "hands",
    ),  # fmt: skip
    ("wovenskin.study.simulate", "run_trial"): ("hands",),
    ("wovenskin.study.simulate", "_Job"): ("hands",),
    ("wovenskin.study.simulate", "estimate_wall_s"): ("time_limit_s",),
    ("wovenskin.study.synthetic", "synthetic_study"): ("participants", "trials"),
    ("wovenskin.reproduce.study", "StudyConfig"): ("time_limit_s", "hands"),
    ("wovenskin.ui.dashboard.runner", "DashboardRunner.__init__"): ("ui_rate_hz",),
    ("wovenskin.bench.dashboard", "run_dashboard_benchmark"): ("ui_rate_hz",),
    ("wovenskin.ui.view", "run_view"): ("fps",),
    ("wovenskin.recognition.onnx_runtime", "OnnxRecognizer.__init__"): ("threads",),
    ("wovenskin.training.report", "evaluate_on_dataset"): ("threads",),
    ("wovenskin.training.capture_eval", "evaluate_captures"): ("threads",),
    ("wovenskin.training.datasets.sim", "generate_sim_dataset"): (
        "n_recordings",
        "seconds_per_recording",
        *_DATASET_COUNTS,
    ),  # fmt: skip
    ("wovenskin.training.datasets.streams", "build_dataset_from_streams"): _DATASET_COUNTS,
    ("wovenskin.training.datasets.captures", "build_dataset_from_captures"): ("dtype",),
    ("wovenskin.training.runs", "ensure_dataset"): ("workers",),
    ("wovenskin.bench.gestures", "run_gestures_benchmark"): (
        "streams",
        "seconds",
        "seed",
        "flicks",
        "held",
        "hold_s",
    ),  # fmt: skip
    ("wovenskin.bench.gestures", "GesturesBenchResult"): ("hold_s",),
    ("wovenskin.bench.recognition", "run_recognition_benchmark"): (
        "streams_per_condition",
        "seconds",
        "base_seed",
    ),  # fmt: skip
    ("wovenskin.training.compare", "compare_models"): ("latency_repeats",),
}


def _definition(module_name: str, qualname: str) -> ast.AST:
    tree: ast.AST = ast.parse(inspect.getsource(importlib.import_module(module_name)))
    for part in qualname.split("."):
        tree = next(
            node
            for node in ast.iter_child_nodes(tree)
            if isinstance(node, ast.FunctionDef | ast.ClassDef) and node.name == part
        )
    return tree


def _written_defaults(node: ast.AST) -> dict[str, ast.expr]:
    """A function's parameter defaults, or a class's field defaults, as written."""
    if isinstance(node, ast.ClassDef):
        return {
            item.target.id: item.value
            for item in node.body
            if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name) and item.value
        }
    args = node.args
    positional = args.posonlyargs + args.args
    found = dict(zip([a.arg for a in positional[len(positional) - len(args.defaults) :]],
                     args.defaults, strict=True))  # fmt: skip
    found.update({a.arg: d for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True) if d})
    return found


@pytest.mark.parametrize("key", sorted(LIBRARY_DEFAULTS), ids=":".join)
def test_the_library_names_each_default_s_home(key) -> None:
    module_name, qualname = key
    if module_name == "wovenskin.training.compare":
        pytest.importorskip("torch")
    written = _written_defaults(_definition(module_name, qualname))
    literal = [
        f"{name} = {ast.unparse(written[name])}"
        for name in LIBRARY_DEFAULTS[key]
        if isinstance(written[name], ast.Constant)
    ]
    assert not literal, f"{qualname} writes a default again; name its home: {literal}"


def test_the_study_template_states_the_study_s_defaults(tmp_path) -> None:
    for key in ("trials_per_condition", "time_limit_s"):
        assert not re.search(rf"^{key} = [0-9]", TEMPLATE, re.MULTILINE), f"{key} written twice"
    study = load_study(init_study(tmp_path).parent)
    defaults = StudyDefinition(name="any")
    assert study.trials_per_condition == defaults.trials_per_condition
    assert study.time_limit_s == defaults.time_limit_s


# ------------------------------------------------------------ an unset option stays unset


def _recording(calls: list, result=None):
    """A stand-in for a library function: records its call, then ends the command (or
    returns ``result``)."""

    def stand_in(*args, **kwargs):
        calls.append((args, kwargs))
        if result is None:
            raise typer.Exit(0)
        return result

    return stand_in


def _parameters(function) -> dict:
    return {name: p.default for name, p in inspect.signature(function).parameters.items()}


def test_study_simulate_and_synthetic_fall_through_to_their_modules(monkeypatch, tmp_path):
    from wovenskin.study import definition, simulate, synthetic

    parameters = _parameters(simulate.simulate_study)
    calls: list = []
    monkeypatch.setattr(simulate, "simulate_study", _recording(calls))
    assert invoke("study", "simulate", tmp_path / "sim").exit_code == 0
    args, kwargs = calls.pop()
    assert args[1:4] == (simulate.PARTICIPANTS, 0, simulate.TRIALS_PER_CONDITION)
    assert kwargs["time_limit_s"] == definition.TIME_LIMIT_S
    assert parameters["participants"] == simulate.PARTICIPANTS
    assert kwargs["hands"] == simulate.HANDS == parameters["hands"]
    assert parameters["time_limit_s"] == StudyDefinition(name="any").time_limit_s

    study = StudyDefinition(name="stand-in")
    monkeypatch.setattr(synthetic, "synthetic_study", _recording(calls, study))
    assert invoke("study", "synthetic", tmp_path / "syn").exit_code == 0
    args, _ = calls.pop()
    assert args[1:4] == (synthetic.PARTICIPANTS, 0, synthetic.TRIALS_PER_CONDITION)


def test_dataset_passes_only_the_options_given(monkeypatch, tmp_path):
    from wovenskin.training import datasets
    from wovenskin.training.datasets import sim

    calls: list = []
    monkeypatch.setattr(datasets, "generate_sim_dataset", _recording(calls))
    assert invoke("dataset", "--out", tmp_path / "ds").exit_code == 0
    _, kwargs = calls.pop()
    unset = {"n_recordings", "seconds_per_recording", *_DATASET_COUNTS}
    assert not unset & set(kwargs), "an unset option must fall through to the builder"
    assert invoke("dataset", "--out", tmp_path / "ds", "--workers", 1).exit_code == 0
    assert calls.pop()[1]["workers"] == 1
    builder = _parameters(sim.generate_sim_dataset)
    assert builder["n_recordings"] == datasets.RECORDINGS
    assert builder["workers"] == datasets.WORKERS
    assert builder["dtype"] == datasets.DTYPE


def test_the_benches_and_the_view_fall_through(monkeypatch):
    from wovenskin.bench import gestures, recognition
    from wovenskin.recognition import pipeline
    from wovenskin.ui import view

    class Recognizer:
        meta = None

    loaded: list = []
    monkeypatch.setattr(
        pipeline, "load_recognizer", lambda *a, **k: loaded.append(k) or Recognizer()
    )
    seconds = _parameters(recognition.run_recognition_benchmark)["seconds"]
    calls: list = []
    monkeypatch.setattr(gestures, "run_gestures_benchmark", _recording(calls))
    assert invoke("bench", "gestures").exit_code == 0
    args, kwargs = calls.pop()
    assert len(args) == 2 and not {"streams", "seconds", "seed", "flicks", "held", "hold_s"} & set(
        kwargs
    )
    assert loaded.pop() == {"threads": None}  # load_recognizer: None -> ONNX_THREADS

    monkeypatch.setattr(recognition, "run_recognition_benchmark", _recording(calls))
    assert invoke("bench", "recognition").exit_code == 0
    args, _ = calls.pop()
    assert args[3:6] == (
        recognition.DEFAULT_STREAMS_PER_CONDITION,
        seconds,
        recognition.DEFAULT_BASE_SEED,
    )

    monkeypatch.setattr(view, "run_view", _recording(calls))
    assert invoke("view").exit_code == 0
    assert calls.pop()[1]["fps"] == view.FPS


def test_an_unset_thread_count_is_the_recogniser_s():
    from wovenskin.recognition.onnx_runtime import ONNX_THREADS
    from wovenskin.recognition.pipeline import load_recognizer

    assert load_recognizer().threads == ONNX_THREADS
    assert load_recognizer(threads=2).threads == 2


def test_the_dashboard_s_page_rate_lives_in_its_runner():
    from wovenskin.bench.dashboard import run_dashboard_benchmark
    from wovenskin.ui.dashboard.runner import UI_RATE_HZ, DashboardRunner

    runner = DashboardRunner(lambda *a, **k: None, "sim", "sim")
    assert runner.ui_rate_hz == UI_RATE_HZ
    assert _parameters(run_dashboard_benchmark)["ui_rate_hz"] == UI_RATE_HZ
