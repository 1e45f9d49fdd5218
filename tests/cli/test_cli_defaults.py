"""Every command-line default lives once, in its settings (issue 25, "Settings").

The test walks every registered command (sub-apps too: bench, pose, ros2, study) and
checks each option that stands for a settings field or a module's default constant
(:data:`SETTINGS`, the explicit option -> home mapping): its default is unset (``None``,
falling through to the home) or equal to the home's value; the value its help states as
the default is the home's; and its source (the command's module, or the module a shared
option constant is imported from) never writes that value again as a literal.  An option
that is named like a settings field and defaults to that field's value literally, yet is
not mapped, fails too: map it, or list it in :data:`NOT_SETTINGS` with the reason it is
another setting.
"""

from __future__ import annotations

import ast
import dataclasses
import importlib
import inspect
import re
import textwrap
from collections.abc import Iterator

import pytest
import typer

from wovenskin.cli import app
from wovenskin.control.mapping import MotionSettings
from wovenskin.control.profile import SpeedProfile
from wovenskin.recognition.arbiter import ArbiterSettings
from wovenskin.recognition.pipeline import PipelineSettings
from wovenskin.signal.config import ConditioningConfig
from wovenskin.skin.layout import SkinLayout
from wovenskin.study.definition import StudyDefinition
from wovenskin.training.adapt_settings import AdaptSettings
from wovenskin.training.config import TrainConfig
from wovenskin.training.window_settings import WindowSettings
from wovenskin.ui.record_session import RecordPlan

_TRAIN = ("batch_size", "lr", "seed", "patience", "split_seed", "threads", "epochs")
_TRAIN += ("device", "amp", "resume")
_PIPELINE = {
    "every": (PipelineSettings, "every", 1),
    "dwell_ms": (ArbiterSettings, "dwell_s", 1000),
    "min_probability": (ArbiterSettings, "min_probability", 1),
}

_ONNX_THREADS = ("wovenskin.recognition.onnx_runtime", "ONNX_THREADS", 1)
_DATASETS = "wovenskin.training.datasets"  # the builders' defaults (writer.py, sim.py)
_GESTURES = "wovenskin.bench.gestures"
_RECOGNITION = "wovenskin.bench.recognition"
_STREAMS = "DEFAULT_STREAMS_PER_CONDITION"

SETTINGS: dict[tuple[str, str], tuple[type | str, str, float]] = {
    # (command, option) -> (settings dataclass, field, option units per field unit), or
    # (module, constant, units) where a module constant is the default's one home
    **{("replay", name): field for name, field in _PIPELINE.items()},
    **{("eval-stream", name): field for name, field in _PIPELINE.items()},
    ("bench recognition", "min_probability"): _PIPELINE["min_probability"],
    ("bench gestures", "min_probability"): _PIPELINE["min_probability"],
    **{("train", name): (TrainConfig, name, 1) for name in (*_TRAIN, "model")},
    **{("compare", name): (TrainConfig, name, 1) for name in _TRAIN},
    ("dataset", "recipe"): (WindowSettings, "recipe", 1),
    ("dataset", "rows"): (SkinLayout, "rows", 1),
    ("dataset", "cols"): (SkinLayout, "cols", 1),
    ("simulate", "rows"): (SkinLayout, "rows", 1),
    ("simulate", "cols"): (SkinLayout, "cols", 1),
    ("view", "smoothing_ms"): (ConditioningConfig, "smoothing_s", 1000),
    ("record", "trials"): (RecordPlan, "trials_per_gesture", 1),
    ("record", "invalid_trials"): (RecordPlan, "invalid_trials", 1),
    ("record", "countdown"): (RecordPlan, "countdown_s", 1),
    ("record", "trial_seconds"): (RecordPlan, "trial_s", 1),
    ("record", "seed"): (RecordPlan, "seed", 1),
    ("adapt", "held_out"): (AdaptSettings, "held_out_fraction", 1),
    ("adapt", "epochs"): (AdaptSettings, "epochs", 1),
    ("adapt", "windows"): (AdaptSettings, "user_windows", 1),
    ("adapt", "rehearsal"): (AdaptSettings, "rehearsal_recordings", 1),
    ("adapt", "seed"): (AdaptSettings, "seed", 1),
    ("adapt", "threads"): (AdaptSettings, "threads", 1),
    ("adapt", "force"): (AdaptSettings, "force", 1),
    ("study simulate", "time_limit"): (StudyDefinition, "time_limit_s", 1),
    ("study simulate", "participants"): ("wovenskin.study.simulate", "PARTICIPANTS", 1),
    ("study simulate", "trials"): ("wovenskin.study.simulate", "TRIALS_PER_CONDITION", 1),
    ("study simulate", "task"): ("wovenskin.study.definition", "TASKS", 1),
    ("study simulate", "interface"): ("wovenskin.study.simulate", "INTERFACES", 1),
    ("study simulate", "objects"): ("wovenskin.study.simulate", "OBJECTS", 1),
    ("study simulate", "jobs"): ("wovenskin.study.simulate", "JOBS", 1),
    ("study simulate", "hands"): ("wovenskin.study.simulate", "HANDS", 1),
    ("reproduce", "hands"): ("wovenskin.study.simulate", "HANDS", 1),
    ("study synthetic", "participants"): ("wovenskin.study.synthetic", "PARTICIPANTS", 1),
    ("study synthetic", "trials"): ("wovenskin.study.synthetic", "TRIALS_PER_CONDITION", 1),
    ("run", "ui_rate"): ("wovenskin.ui.dashboard.runner", "UI_RATE_HZ", 1),
    ("bench dashboard", "ui_rate"): ("wovenskin.ui.dashboard.runner", "UI_RATE_HZ", 1),
    ("bench dashboard", "idle_seconds"): ("wovenskin.bench.dashboard", "IDLE_SECONDS", 1),
    ("bench dashboard", "swipes"): ("wovenskin.bench.dashboard", "SWIPES", 1),
    ("view", "fps"): ("wovenskin.ui.view", "FPS", 1),
    **{
        (command, "threads"): _ONNX_THREADS
        for command in ("replay", "eval-stream", "eval", "bench recognition", "bench gestures")
    },
    ("dataset", "recordings"): (_DATASETS, "RECORDINGS", 1),
    ("dataset", "windows"): (_DATASETS, "WINDOWS_PER_RECORDING", 1),
    ("dataset", "invalid_windows"): (_DATASETS, "INVALID_WINDOWS_PER_RECORDING", 1),
    ("dataset", "seconds"): (_DATASETS, "SECONDS_PER_RECORDING", 1),
    ("dataset", "workers"): (_DATASETS, "WORKERS", 1),
    ("dataset", "dtype"): (_DATASETS, "DTYPE", 1),
    ("bench gestures", "streams"): (_GESTURES, "DEFAULT_STREAMS", 1),
    ("bench gestures", "seconds"): (_GESTURES, "DEFAULT_SECONDS", 1),
    ("bench gestures", "seed"): (_GESTURES, "DEFAULT_BASE_SEED", 1),
    ("bench gestures", "flicks"): (_GESTURES, "DEFAULT_FLICKS", 1),
    ("bench gestures", "held"): (_GESTURES, "DEFAULT_HELD", 1),
    ("bench gestures", "hold"): (_GESTURES, "DEFAULT_HOLD_S", 1),
    ("bench gestures", "gain_scale"): (_GESTURES, "DEFAULT_GAIN_SCALE", 1),
    ("bench recognition", "streams_per_condition"): (_RECOGNITION, _STREAMS, 1),
    ("bench recognition", "seconds"): ("wovenskin.bench.conditions", "DEFAULT_SECONDS", 1),
    ("bench recognition", "seed"): (_RECOGNITION, "DEFAULT_BASE_SEED", 1),
    ("compare", "latency_repeats"): ("wovenskin.training.compare", "LATENCY_REPEATS", 1),
}

SETTINGS_CLASSES = (
    TrainConfig, ArbiterSettings, PipelineSettings, ConditioningConfig, SkinLayout,
    WindowSettings, RecordPlan, AdaptSettings, MotionSettings, SpeedProfile, StudyDefinition,
)  # fmt: skip
"""The settings an unmapped option must not repeat literally (by name and value)."""

NOT_SETTINGS = {
    # options named like a settings field whose value is another setting
    ("bench tasks", "seed"): "the task scene's and simulated person's seed",
    ("bench safety", "seed"): "the random postures' seed",
    ("bench dashboard", "seed"): "the seed of the people drawing on the page",
    ("study simulate", "seed"): "the simulated study's seed",
    ("study synthetic", "seed"): "the synthetic study's seed",
    ("dataset", "seed"): "the data set's simulation seed (no settings dataclass holds it)",
    ("fake-device", "seed"): "the simulated person's seed",
}


def commands() -> Iterator[tuple[str, object]]:
    """Every leaf command of the ``wovenskin`` app, named by its path ("bench gestures")."""

    def walk(command, path: tuple[str, ...]) -> Iterator:
        subcommands = getattr(command, "commands", None)
        if subcommands is None:
            yield " ".join(path), command
            return
        for name, sub in subcommands.items():
            yield from walk(sub, (*path, name))

    yield from walk(typer.main.get_command(app), ())


COMMANDS = dict(commands())
OPTIONS = {
    (name, param.name): param
    for name, command in COMMANDS.items()
    for param in command.params
    if param.param_type_name == "option"  # typer 0.29 vendors click: no isinstance
}


def field_default(cls: type, name: str):
    field = cls.__dataclass_fields__[name]
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    return dataclasses.MISSING  # a required field: no default to repeat


def home_default(holder: type | str, name: str):
    """The default at an option's home: a settings dataclass's field, or a module's constant
    (the module is imported here: torch's, only where torch is installed)."""
    if isinstance(holder, str):
        return getattr(pytest.importorskip(holder), name)
    return field_default(holder, name)


def home_name(holder: type | str, name: str) -> str:
    return f"{holder if isinstance(holder, str) else holder.__name__}.{name}"


def expected(key: tuple[str, str]):
    holder, name, scale = SETTINGS[key]
    value = home_default(holder, name)
    if scale != 1 and isinstance(value, int | float):
        return value * scale
    return value


def test_the_walk_sees_every_command_group() -> None:
    groups = {name.split()[0] for name in COMMANDS if " " in name}
    assert {"bench", "pose", "ros2", "study"} <= groups
    assert {"run", "replay", "eval-stream", "train", "compare", "bench gestures"} <= set(COMMANDS)


def test_every_mapped_option_exists() -> None:
    missing = sorted(key for key in (*SETTINGS, *NOT_SETTINGS) if key not in OPTIONS)
    assert not missing, f"no such option (renamed? update the mapping): {missing}"


@pytest.mark.parametrize("key", sorted(SETTINGS), ids=" --".join)
def test_a_mapped_option_is_unset_or_the_settings_default(key) -> None:
    default = OPTIONS[key].default
    if default is None:
        return
    want = expected(key)
    assert default == pytest.approx(want) if isinstance(want, float) else default == want


def stated_default(help_text: str) -> str | None:
    """The default an option's help states: "(default 64)", "(default 1: ...)", "else 100)"
    or "Default: auto."; None when it states none."""
    for pattern in (r"\(default ([^):;, ]+)", r"else ([^):;, ]+)\)", r"Default: ([^.]+)\."):
        match = re.search(pattern, help_text or "")
        if match:
            return match.group(1)
    return None


def same(stated: str, value) -> bool:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return stated == str(value)
    try:
        return float(stated) == pytest.approx(float(value))
    except ValueError:
        return False


@pytest.mark.parametrize("key", sorted(SETTINGS), ids=" --".join)
def test_the_default_a_help_states_is_the_settings_default(key) -> None:
    stated = stated_default(OPTIONS[key].help)
    if stated is not None:
        assert same(stated, expected(key)), f"--help says {stated}, settings {expected(key)}"


def _module_constants(module) -> dict[str, ast.expr]:
    """The module-level ``NAME = value`` assignments of ``module``, by name."""
    constants = {}
    for node in ast.parse(inspect.getsource(module)).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target = node.targets[0]
            if isinstance(target, ast.Name):
                constants[target.id] = node.value
    return constants


def _option_constants(module) -> dict[str, ast.expr]:
    """The constants a command's signature may name: its module's own and those it imports
    from another wovenskin module (a shared option such as ``cli/app.py``'s ``THREADS``)."""
    constants = {}
    for node in ast.parse(inspect.getsource(module)).body:
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("wovenskin."):
            source = _module_constants(importlib.import_module(node.module))
            for alias in node.names:
                if alias.name in source:
                    constants[alias.asname or alias.name] = source[alias.name]
    return {**constants, **_module_constants(module)}


def _literal_defaults(command) -> dict[str, object]:
    """The options of ``command`` whose source writes a literal default (not None): the
    first argument of ``typer.Option`` in its signature or in the constant the signature
    names (defined in the command's module or imported into it)."""
    function = inspect.unwrap(command.callback)
    constants = _option_constants(inspect.getmodule(function))
    tree = ast.parse(textwrap.dedent(inspect.getsource(function)))
    definition = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef))
    args = definition.args.args
    found = {}
    defaults = definition.args.defaults
    for arg, default in zip(args[len(args) - len(defaults) :], defaults, strict=True):
        if isinstance(default, ast.Name):
            default = constants.get(default.id, default)
        if (
            isinstance(default, ast.Call)
            and getattr(default.func, "attr", getattr(default.func, "id", "")) == "Option"
            and default.args
            and isinstance(default.args[0], ast.Constant)
            and default.args[0].value is not None
        ):
            found[arg.arg] = default.args[0].value
    return found


def test_no_mapped_option_writes_its_settings_default_again() -> None:
    literal = []
    for (name, option), (holder, field, _) in SETTINGS.items():
        value = _literal_defaults(COMMANDS[name]).get(option)
        if value is not None and not isinstance(value, bool):
            literal.append(f"{name} --{option}: {value!r} (from {home_name(holder, field)})")
    assert not literal, "defaults written twice; use None or the settings: " + "; ".join(literal)


def test_no_unmapped_option_repeats_a_settings_default() -> None:
    fields = {}
    for cls in SETTINGS_CLASSES:
        for name in cls.__dataclass_fields__:
            fields.setdefault(name, []).append(cls)
    doubles = []
    for (command, option), param in OPTIONS.items():
        if (command, option) in SETTINGS or (command, option) in NOT_SETTINGS:
            continue
        if param.default is None or isinstance(param.default, bool) or option not in fields:
            continue
        for cls in fields[option]:
            if field_default(cls, option) == param.default:
                doubles.append(f"{command} --{option} = {param.default!r} ({cls.__name__})")
    assert not doubles, "options repeating a settings default: " + "; ".join(doubles)
