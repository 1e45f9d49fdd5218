"""``wovenskin adapt``: fine-tune the recogniser to one person's recordings (needs PyTorch)."""

from __future__ import annotations

import json
from pathlib import Path

import typer
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)

from wovenskin.cli.app import app, console, err_console, require_torch, user_errors
from wovenskin.errors import ConfigError
from wovenskin.io import to_jsonable
from wovenskin.outputs import check_writable
from wovenskin.training.adapt_settings import AdaptSettings

DEFAULTS = AdaptSettings()


@app.command()
@user_errors
def adapt(
    recordings: list[Path] = typer.Argument(
        ..., help="Labelled streams (.npz) or guided recordings (.wsrec) of one person on one skin."
    ),
    out: Path = typer.Option(..., help="Directory of the adapted model (and adapt.json)."),
    base: Path = typer.Option(None, help="Model to start from (default: the shipped model)."),
    mapping: Path = typer.Option(
        None,
        help="The mapping file you will run with: warns about gestures it defines that were "
        "not recorded, and recorded ones it gives no action.",
    ),
    held_out: float = typer.Option(
        DEFAULTS.held_out_fraction,
        min=0.01,
        max=0.99,
        help="Share of the trials held out to score both models.",
    ),
    epochs: int = typer.Option(DEFAULTS.epochs, min=1, max=100000, help="Fine-tuning epochs."),
    windows: int = typer.Option(
        DEFAULTS.user_windows, min=1, max=10000000, help="Gesture windows cut from the recordings."
    ),
    rehearsal: int = typer.Option(
        DEFAULTS.rehearsal_recordings,
        min=0,
        max=100000,
        help="Simulated other people mixed into training so the model does not forget "
        "them (0: none).",
    ),
    seed: int = typer.Option(
        DEFAULTS.seed,
        min=0,
        max=2**32 - 1,
        help="Seed of the split, the rehearsal people and training.",
    ),
    threads: int = typer.Option(
        DEFAULTS.threads, min=1, max=256, help="Torch and ONNX Runtime threads."
    ),
    force: bool = typer.Option(
        False, help="Install the adapted model even if it scores worse than the base."
    ),
    overwrite: bool = typer.Option(False, help="Replace a model already in --out."),
    json_out: bool = typer.Option(False, "--json", help="Print the report as one JSON object."),
) -> None:
    """Adapt the recogniser to a person and skin: before/after on held-out trials, per class.

    The adapted model is a model directory like any other (run/replay/eval-stream
    --model OUT, the dashboard).  It is installed in OUT only when it scores at least as
    well as the base on the held-out trials; otherwise it is kept in OUT/rejected and the
    command exits with code 2.
    """
    require_torch("wovenskin adapt")
    from wovenskin.training.adapt import AdaptRefused, adapt_model

    out_has_model = (out / "meta.json").is_file() or (out / "adapt.json").is_file()
    if out_has_model and not overwrite:
        raise ConfigError(f"{out} already holds an adapted model; give --overwrite to replace it")
    check_writable(out, folder=True)  # refused now, not after the adapting
    settings = AdaptSettings(
        held_out_fraction=held_out, seed=seed, threads=threads, force=force, epochs=epochs,
        user_windows=windows, rehearsal_recordings=rehearsal,
    )  # fmt: skip
    if mapping is not None:
        _check_mapping(mapping, recordings)
    ui = err_console if json_out else console
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[note]}"),
        TimeElapsedColumn(),
        console=ui,
        transient=True,
    )
    tasks: dict[str, int] = {}

    def show(event) -> None:
        if event.stage not in tasks:
            tasks[event.stage] = bar.add_task(event.stage, total=max(1, event.total), note="")
        bar.update(tasks[event.stage], completed=event.done, total=max(1, event.total),
                   note=event.note)  # fmt: skip

    try:
        with bar:
            report = adapt_model(recordings, out, base, settings, show)
    except AdaptRefused as refused:
        _print_report(refused.report, ui, json_out)
        raise
    _print_report(report, ui, json_out)


def _print_report(report, ui, json_out: bool) -> None:
    """The report as tables and a verdict line (or as one JSON object on stdout)."""
    if json_out:
        print(json.dumps(to_jsonable(report.to_dict())))
        return
    ui.print(report.table())
    ui.print(report.class_table())
    ui.print(escape(report.verdict()), highlight=False, soft_wrap=True)


def _check_mapping(path: Path, recordings: list[Path]) -> None:
    """Warn about the mapping's gestures with no trials and trials it gives no action."""
    from wovenskin.cli.app import warn
    from wovenskin.control.mapping import ActionMapping
    from wovenskin.gestures import INVALID
    from wovenskin.recognition.pipeline import load_stream

    actions = ActionMapping.load(path)
    recorded = {str(x) for p in recordings for x in load_stream(p).event_labels}
    for name in sorted(set(actions.custom) - recorded):
        warn(
            f"{path} defines {name!r} but no recording has a trial of it: the model will "
            "not know it"
        )
    unmapped = sorted(recorded - set(actions.gestures) - {INVALID})
    if unmapped:
        warn(f"{path} gives no action to {', '.join(unmapped)}: recognised, they will do nothing")
