"""``wovenskin study ...``: define a study, plan its run order, report it, simulate one.

Register it with ``app.add_typer(study_app, name="study")``.  Each command imports the
study package when it runs (it loads scipy and matplotlib), keeping ``--help`` instant.
"""

from __future__ import annotations

from pathlib import Path

import typer

from wovenskin.cli.app import console, user_errors, warn

study_app = typer.Typer(
    help="User studies: definitions, counterbalanced plans, trial logs, reports (docs/study.md).",
    no_args_is_help=True,
)

DIR = typer.Argument(..., help="The study folder (holds study.toml).")


@study_app.command("init")
@user_errors
def study_init(
    directory: Path = DIR,
    name: str = typer.Option(None, help="The study's name (default: the folder's name)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing study.toml."),
) -> None:
    """Write a commented study.toml template into DIR."""
    from wovenskin.study.definition import init_study

    path = init_study(directory, name, overwrite)
    console.print(f"wrote {path}; add participants with `wovenskin study add-participant`")


@study_app.command("add-participant")
@user_errors
def study_add_participant(
    directory: Path = DIR,
    participant: str = typer.Argument(..., help="Participant id (letters, digits, - and _)."),
    expertise: str = typer.Option(..., help="novice, intermediate or expert."),
    notes: str = typer.Option("", help="Free notes kept with the participant."),
) -> None:
    """Add a participant to DIR/study.toml (run order = order of addition)."""
    from wovenskin.study.definition import add_participant

    study = add_participant(directory, participant, expertise, notes)
    console.print(f"{participant} added; {len(study.participants)} participants in {study.name}")


@study_app.command("plan")
@user_errors
def study_plan_command(directory: Path = DIR) -> None:
    """Print each participant's counterbalanced run order and write DIR/plan.csv."""
    from rich.table import Table

    from wovenskin.study.counterbalance import block_size, write_plan
    from wovenskin.study.definition import load_study

    study = load_study(directory)
    if not study.participants:
        warn("the study has no participants yet: `wovenskin study add-participant`")
    path, steps = write_plan(directory, study)
    table = Table(title=f"{study.name}: run order ({study.trials_per_condition} trials each)")
    table.add_column("participant")
    table.add_column("expertise")
    table.add_column("run order (task: interfaces)")
    for person in study.participants:
        mine = [s for s in steps if s.participant == person.id]
        parts = []
        for task in dict.fromkeys(s.task for s in mine):
            parts.append(f"{task}: " + " > ".join(s.interface for s in mine if s.task == task))
        table.add_row(person.id, person.expertise, "; ".join(parts))
    console.print(table)
    block = block_size(len(study.interfaces), len(study.tasks))
    n = len(study.participants)
    if n % block:
        warn(f"{n} participants: a multiple of {block} balances the orders fully")
    console.print(f"wrote {path}")


@study_app.command("report")
@user_errors
def study_report(
    directory: Path = DIR,
    out: Path = typer.Option(None, help="Report folder (default: DIR/report)."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Replace an existing report."),
) -> None:
    """Tables, paired statistics and plots of DIR's trials: report.md and report.html."""
    from wovenskin.study.report import write_report

    report = write_report(directory, out, overwrite)
    for line in report.warnings:
        warn(line)
    if report.synthetic:
        warn("this study is SYNTHETIC (wovenskin study simulate): nothing in it was measured")
    console.print(f"wrote {report.markdown}, {report.html} and {len(report.images)} PNGs")


@study_app.command("simulate")
@user_errors
def study_simulate(
    directory: Path = typer.Argument(..., help="A new folder for the synthetic study."),
    participants: int = typer.Option(6, min=1, help="Synthetic participants."),
    seed: int = typer.Option(0, help="Random seed (the same seed writes the same study)."),
    trials: int = typer.Option(2, min=1, help="Trials per task and interface."),
    overwrite: bool = typer.Option(False, "--overwrite", help="Write into a non-empty folder."),
) -> None:
    """Write a SYNTHETIC study (labelled so in every file) to demo and test the report."""
    from wovenskin.study.simulate import simulate_study

    study = simulate_study(directory, participants, seed, trials, overwrite)
    console.print(
        f"wrote a SYNTHETIC study to {directory} ({len(study.participants)} participants); "
        f"report it with `wovenskin study report {directory}`"
    )
