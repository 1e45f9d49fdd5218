"""``wovenskin reproduce``: the paper's evaluation regenerated into one report."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from wovenskin.cli.app import app, console, err_console, require_torch, user_errors


@app.command()
@user_errors
def reproduce(
    out: Path = typer.Option(..., "--out", help="A new folder for the report."),
    quick: bool = typer.Option(
        False, "--quick", help="Small models and few trials: a first look in under 10 minutes."
    ),
    size: str = typer.Option("", hidden=True, help="tiny, quick or full (tests use tiny)."),
    haart: Path = typer.Option(
        None, help="HAART labelled captures (.npz): real human touch, leave-one-participant-out."
    ),
    jobs: int = typer.Option(
        None, min=1, max=256, help="Simulated trials run at once (default: 2)."
    ),
    trials: int = typer.Option(
        None, min=1, max=10000, help="Trials per task and interface (default: 10; --quick: 1)."
    ),
    hands: str = typer.Option(
        None, help="The simulated study's hands (default independent): independent or sim."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace a report in OUT."),
) -> None:
    """Regenerate the paper's evaluation in simulation beside its numbers, and what it lacks:
    recognition (transformer vs BiLSTM, latency, confusion, grouped split, stream events,
    the robustness suite, HAART), Tables I and II from simulated operators with statistics
    and plots.  Writes OUT/report.md, OUT/report.html, PNGs and figures.json."""
    require_torch("reproduce")
    from wovenskin.reproduce.report import reproduce as run

    chosen = size or ("quick" if quick else "full")
    command = "wovenskin " + " ".join(sys.argv[1:]) if sys.argv[1:] else "wovenskin reproduce"
    from wovenskin.study.simulate import StudyInterrupted

    try:
        result = run(
            out, chosen, haart=haart, jobs=jobs, trials=trials, overwrite=overwrite,
            command=command, hands=hands,
            log=lambda text: console.print(text, highlight=False, markup=False),
        )  # fmt: skip
    except StudyInterrupted as stopped:  # Ctrl-C in the simulated study: say what was kept
        err_console.print(f"interrupted: {stopped.message()}; no report written", markup=False)
        raise typer.Exit(130) from None
    console.print(
        f"wrote {result.markdown}, {result.html} and {result.figures} in "
        f"{result.wall_s / 60:.1f} min"
    )
