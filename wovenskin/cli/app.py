"""The ``wovenskin`` command line (Typer + Rich).

Each command is a thin layer over a library function; heavy imports happen inside the
commands so ``wovenskin --help`` stays instant.  Errors a user can cause (a missing file, a
bad option, an unplugged device) end with one red line and exit code 2, never a traceback.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING

import typer
import typer.core
from rich.console import Console
from rich.markup import escape

from wovenskin.errors import ConfigError, DeviceError, WovenskinError
from wovenskin.outputs import CLI_SWITCH, OutputExistsError
from wovenskin.robots.base import RobotError

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID


def _click_class(name: str) -> type[Exception]:
    """Click's exception class ``name`` as this typer uses it (its own copy of click, or
    click itself), found on the public :class:`typer.BadParameter`'s ancestry."""
    return next(c for c in typer.BadParameter.__mro__ if c.__name__ == name)


_UsageError = _click_class("UsageError")
_ClickException = _click_class("ClickException")


def _given(words: list[str], hint: str) -> str:
    """The user's own words for the parameter ``hint`` (``'--port'``): ``--port 99999``."""
    names = [name.strip("'\"") for name in hint.split("/")]
    for k in reversed(range(len(words))):  # the last given counts, as click reads it
        word = words[k]
        for name in names:
            if word == name and k + 1 < len(words):
                return f"{name} {words[k + 1]}"
            if word.startswith(f"{name}="):
                return word.replace("=", " ", 1)
    return names[0] if names else hint


def usage_line(exc: Exception, words: list[str]) -> str:
    """One line for a usage error: the command, the user's own argument, what is wrong
    and where help is (click's own form spreads over four lines and drops the value)."""
    ctx = getattr(exc, "ctx", None)
    command = ctx.command_path if ctx is not None else "wovenskin"
    param = getattr(exc, "param", None)
    hint = getattr(exc, "param_hint", None)
    if hint is None and param is not None:
        hint = param.get_error_hint()
    if isinstance(hint, list | tuple):
        hint = "/".join(hint)
    if hint and type(exc).__name__ != "MissingParameter":
        message = f"{_given(words, hint)}: {exc.message}"
    else:
        message = exc.format_message()
    return " ".join(f"{command}: {message} (see {command} --help)".split())


class _OneLineErrors(typer.core.TyperGroup):
    """The root command: a usage error (a value out of range, an unknown option) is one
    red line naming the user's own argument, exit code 2, as every other error is."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):  # noqa: ANN001, ANN201 - click's signature
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        words = list(sys.argv[1:] if args is None else args)
        try:
            code = super().main(words, prog_name, complete_var, False, **extra)
        except _UsageError as exc:
            if type(exc).__name__ == "NoArgsIsHelpError":  # no arguments: the help
                exc.show()
            else:
                err_console.print(
                    f"[red]error:[/] {escape(usage_line(exc, words))}",
                    soft_wrap=True,
                    highlight=False,
                )
            sys.exit(exc.exit_code)
        except _ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except typer.Abort:
            err_console.print("Aborted!", highlight=False)
            sys.exit(1)
        sys.exit(code if type(code) is int else 0)


HELP_STYLE = None
"""Every command's help is click's plain text (``rich_markup_mode=None``), which rewraps
each paragraph at words to the terminal's width; Rich's option table cut long values such
as ``serial:PORT[?format=...]`` with an ellipsis."""

app = typer.Typer(
    cls=_OneLineErrors,
    help="Gesture control of a robot arm with a woven capacitive tactile skin.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=HELP_STYLE,
)
bench_app = typer.Typer(
    help="Benchmarks: print measured figures and ratios.",
    no_args_is_help=True,
    rich_markup_mode=HELP_STYLE,
)
app.add_typer(bench_app, name="bench")

# Not on a terminal (a pipe, a file, a script) lines are never wrapped at 80 columns: a
# path or a message stays one line that a script can read.
console = Console(soft_wrap=not sys.stdout.isatty())
err_console = Console(stderr=True, soft_wrap=not sys.stderr.isatty())


def _flags_without_type() -> None:
    """Show on/off options as flags in ``--help``: typer 0.2x labels every flag (``--help``,
    ``--version``, ``--overwrite``) ``<bool>``, as if it took a value.  Flags get no type
    column; every other option keeps typer's own."""
    from typer.core import TyperOption

    original = TyperOption.display_type_rich
    if getattr(original, "_wovenskin", False):
        return

    def display_type_rich(self, ctx):  # noqa: ANN001 - typer's signature
        if getattr(self, "is_flag", False):
            return None
        return original(self, ctx)

    display_type_rich._wovenskin = True  # type: ignore[attr-defined]
    TyperOption.display_type_rich = display_type_rich  # type: ignore[method-assign]


_flags_without_type()

SKIN_HELP = "Skin source: sim, serial:PORT[?format=text&order=col-major] or replay:FILE[?speed=2]."


def _version(value: bool) -> None:
    if value:
        from wovenskin import __version__

        console.print(f"wovenskin {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version."
    ),
) -> None:
    """Gesture control of a robot arm with a woven capacitive tactile skin."""


# Operating-system errors a user causes and fixes: a path that is missing, taken, not
# readable or of the wrong kind, a device or host that cannot be reached.  Not bugs.
USER_OS_ERRORS = (
    FileNotFoundError,
    FileExistsError,
    PermissionError,
    IsADirectoryError,
    NotADirectoryError,
    ConnectionError,
    TimeoutError,
)


def user_error_message(exc: BaseException) -> str | None:
    """The one-line message for an error a user can cause and fix, or None for a bug.

    A :class:`~wovenskin.errors.WovenskinError` is one by definition; so are the
    :data:`USER_OS_ERRORS`.  An output that exists names ``--overwrite``, the switch each
    writing command has."""
    if isinstance(exc, OutputExistsError):
        text = exc.message(CLI_SWITCH)
    elif isinstance(exc, WovenskinError):
        text = str(exc)
    elif isinstance(exc, USER_OS_ERRORS):
        text = str(exc)
        if exc.filename is not None and exc.strerror:
            text = f"{exc.filename}: {exc.strerror}"
    else:
        return None
    return " ".join(text.split()) or type(exc).__name__


def user_errors(fn):
    """Errors a user can cause (:func:`user_error_message`) end as one red line and exit
    code 2; anything else is a bug and keeps its traceback."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except Exception as exc:
            message = user_error_message(exc)
            if message is None:
                raise
            err_console.print(f"[red]error:[/] {escape(message)}", soft_wrap=True, highlight=False)
            raise typer.Exit(2) from None

    return wrapper


pose_app = typer.Typer(
    help="Named robot poses: the task's initial pose and home.", rich_markup_mode=HELP_STYLE
)
app.add_typer(pose_app, name="pose")


def robot_errors(fn):
    """A robot's error (:class:`~wovenskin.robots.base.RobotError`) is told as coming from
    the robot: ``error: robot: ...``."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except RobotError as exc:
            raise DeviceError(f"robot: {exc}") from None

    return wrapper


def show_bench(result, json_out: bool) -> None:
    """A benchmark's figures: one JSON object, or its Rich table."""
    if json_out:
        import json

        print(json.dumps(result.to_dict()))
    else:
        console.print(result.table())


def counting_bar(
    ui: Console, description: str, total: int | None = None
) -> tuple[Progress, TaskID]:
    """A Rich bar on ``ui`` counting done of ``total`` (description, bar, done/total,
    elapsed and remaining time) and its one task: ``(bar, task)``."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=ui,
    )
    return bar, bar.add_task(description, total=total)


def dataset_progress(ui: Console, description: str) -> tuple[Progress, Callable[[int, int], None]]:
    """A :func:`counting_bar` over recordings and the ``progress(done, total)`` that drives
    it (what the data set builders report): ``(bar, progress)``."""
    bar, task = counting_bar(ui, description)

    def update(done: int, total: int) -> None:
        bar.update(task, completed=done, total=total)

    return bar, update


def warn(message: str) -> None:
    err_console.print(f"[yellow]warning:[/] {escape(message)}", soft_wrap=True, highlight=False)


MODEL_HELP = "Checkpoint directory with model.onnx (default: the shipped model)."

# Options several commands share, defined once (typer reads a default OptionInfo per use).
MODEL = typer.Option(None, help=MODEL_HELP)
THREADS = typer.Option(None, min=1, max=256, help="ONNX Runtime threads for the model (default 1).")
JSON_OUT = typer.Option(False, "--json", help="Print one JSON object.")
MIN_PROBABILITY = typer.Option(
    None,
    min=0.0,
    max=1.0,
    help="Least class probability that counts (default: the model's recommendation).",
)
READER = typer.Option(
    None,
    help="How the model's windows are read: touch (the whole touch so far, fused with the "
    "fingers' tracks) or window (the paper's: each 150 ms window alone); default: the "
    "model's recommendation (touch for the shipped model).",
)
POSES = typer.Option(
    None,
    help="Pose file (default: $WOVENSKIN_HOME/poses.toml, else ~/.config/wovenskin/poses.toml).",
)


def given(**options) -> dict:
    """The options given on the command line (not None); the others are unset and the
    library's defaults, each written once (docs/settings.md), apply."""
    return {key: value for key, value in options.items() if value is not None}


ROBOT_HELP = (
    "Robot: sim (the simulated TM5-900), tm:HOST[:PORT][?listen_port=N&state_port=N] "
    "(Techman, docs/techman.md) or ur:HOST[?model=ur5e] (UR: ur3e, ur5e, ur10e, ur16e); "
    "any kind takes ?safety=degraded to accept an arm without kinematics (docs/safety.md)."
)


def pipeline_settings(
    recognizer,
    every: int | None = None,
    dwell_ms: float | None = None,
    min_probability: float | None = None,
    reader: str | None = None,
):
    """Pipeline settings: each option given, else the model's recommendation, else the
    settings default (:func:`~wovenskin.recognition.pipeline.pipeline_settings_for_model`,
    the one rule ``run``, the dashboard and the benchmarks use too).  ``None``: not given."""
    from wovenskin.recognition.pipeline import pipeline_settings_for_model  # keeps --help fast

    dwell_s = None if dwell_ms is None else dwell_ms / 1000
    return pipeline_settings_for_model(
        recognizer, every, reader, dwell_s=dwell_s, min_probability=min_probability
    )


def require_torch(command: str) -> None:
    """Refuse a training command in one line when PyTorch is not installed."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        from wovenskin.wording import train_extra_hint

        raise ConfigError(f"{command} needs PyTorch, which is not installed: {train_extra_hint()}")
