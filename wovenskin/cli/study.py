"""``wovenskin study ...``: define a study, plan its run order, report it, simulate one.

Register it with ``app.add_typer(study_app, name="study")``.  Each command imports the
study package when it runs (it loads scipy and matplotlib), keeping ``--help`` instant.
"""

from __future__ import annotations

from pathlib import Path

import typer

from wovenskin.cli.app import HELP_STYLE, MODEL, SKIN_HELP, console, robot_errors, user_errors, warn
from wovenskin.wording import quantity

study_app = typer.Typer(
    help="User studies: definitions, counterbalanced plans, trial logs, reports (docs/study.md).",
    no_args_is_help=True,
    rich_markup_mode=HELP_STYLE,
)

DIR = typer.Argument(..., help="The study folder (holds study.toml).")
HANDS_OPTION = typer.Option(
    None,
    help="Whose people and skins touch the skin (default independent): independent "
    "(wovenskin.independent, strangers to the model) or sim (wovenskin.sim, the simulator "
    "the model was trained on).",
)


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
    people = quantity(len(study.participants), "participant")
    console.print(f"{participant} added; {people} in {study.name}")


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
    each = quantity(study.trials_per_condition, "trial")
    table = Table(title=f"{study.name}: run order ({each} each)")
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
        warn(f"{quantity(n, 'participant')}: a multiple of {block} balances the orders fully")
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
        warn("this study is SYNTHETIC (wovenskin study synthetic): nothing in it was measured")
    console.print(
        f"wrote {report.markdown}, {report.html} and {quantity(len(report.images), 'PNG')}"
    )


@study_app.command("simulate")
@user_errors
def study_simulate(
    directory: Path = typer.Argument(..., help="A new folder for the simulated study."),
    participants: int = typer.Option(
        None, min=1, max=1000, help="Simulated operators: novice, expert, ... (default 6)."
    ),
    trials: int = typer.Option(
        None, min=1, max=10000, help="Trials per task and interface (default 2; the paper ran 10)."
    ),
    seed: int = typer.Option(
        0, min=0, max=2**32 - 1, help="Random seed (the same seed runs the same study)."
    ),
    task: list[str] = typer.Option(
        None, help="Tasks, the option repeated (default: pick_place and pour)."
    ),
    interface: list[str] = typer.Option(
        None, help="Interfaces, the option repeated (default: skin, keyboard and pendant)."
    ),
    objects: str = typer.Option(
        None, help="pick_place: 'one' object a trial (the paper's, the default) or 'all'."
    ),
    time_limit: float = typer.Option(
        None,
        min=0.1,
        max=86400.0,
        help="Seconds a trial may run from its first command (default 300).",
    ),
    model: Path = MODEL,
    jobs: int = typer.Option(
        None, min=1, max=256, help="Trials run at once, in worker processes (default 1)."
    ),
    hands: str = HANDS_OPTION,
    overwrite: bool = typer.Option(False, "--overwrite", help="Write into a non-empty folder."),
) -> None:
    """Run a whole study with SIMULATED operators (novices and experts with human timing)
    on the simulated arm and skin, headless and as fast as this computer runs; report it
    with `wovenskin study report DIR`.  Ctrl-C stops it and keeps the finished trials."""
    import time

    from rich.markup import escape
    from rich.progress import Progress

    from wovenskin.cli.app import err_console
    from wovenskin.errors import ConfigError
    from wovenskin.study.definition import TASKS, TIME_LIMIT_S
    from wovenskin.study.simulate import (
        HANDS,
        INTERFACES,
        JOBS,
        OBJECTS,
        PARTICIPANTS,
        TRIALS_PER_CONDITION,
        StudyInterrupted,
        check_hands,
        estimate_wall_s,
        simulate_study,
    )
    from wovenskin.wording import duration

    participants = PARTICIPANTS if participants is None else participants
    trials = TRIALS_PER_CONDITION if trials is None else trials
    time_limit = TIME_LIMIT_S if time_limit is None else time_limit
    task = task or list(TASKS)
    interface = interface or list(INTERFACES)
    objects = OBJECTS if objects is None else objects
    jobs = JOBS if jobs is None else jobs
    hands = check_hands(HANDS if hands is None else hands)
    for name in task:  # refused before anything is estimated or written
        if name not in TASKS:
            raise ConfigError(f"--task {name!r}: a study task is one of {', '.join(TASKS)}")
    for name in interface:
        if name not in INTERFACES:
            raise ConfigError(
                f"--interface {name!r}: simulated operators use {', '.join(INTERFACES)}"
            )
    total = participants * trials * len(task) * len(interface)
    guess = estimate_wall_s(participants, trials, len(task), tuple(interface), jobs, time_limit)
    console.print(
        f"{quantity(total, 'simulated trial')} ({quantity(participants, 'operator')} x "
        f"{quantity(trials, 'trial')} x {quantity(len(task), 'task')} x "
        f"{quantity(len(interface), 'interface')}), {hands} hands, roughly "
        f"{duration(guess)} with --jobs {jobs}; Ctrl-C stops and keeps the finished trials",
        highlight=False,
        soft_wrap=True,
    )
    started = time.perf_counter()
    with Progress(console=console, transient=True) as bar:
        job = bar.add_task("simulated trials", total=total)
        done = [0]

        def advance(run) -> None:
            s = run.summary
            done[0] += 1
            left = (time.perf_counter() - started) / done[0] * (total - done[0])
            bar.console.print(
                f"{s.participant} {s.task}/{s.interface} trial {s.trial}: {s.outcome}, "
                f"{s.duration_s:.1f} s, {quantity(s.commands, 'command')} "
                f"({run.wall_s:.0f} s to run; {done[0]}/{total} done, about "
                f"{duration(left)} left)",
                highlight=False,
            )
            bar.advance(job)

        try:
            study, runs = simulate_study(
                directory, participants, seed, trials, tasks=tuple(task),
                interfaces=tuple(interface), time_limit_s=time_limit, objects=objects,
                model=model, jobs=jobs, overwrite=overwrite, progress=advance, hands=hands,
            )  # fmt: skip
        except StudyInterrupted as stopped:
            bar.stop()
            err_console.print(
                f"[yellow]interrupted:[/] {escape(stopped.message())}",
                soft_wrap=True, highlight=False,
            )  # fmt: skip
            raise typer.Exit(130) from None
    console.print(
        f"wrote a SIMULATED study to {directory}: {quantity(len(runs), 'trial')} of "
        f"{quantity(len(study.participants), 'simulated operator')} in "
        f"{duration(time.perf_counter() - started)}; report it with "
        f"`wovenskin study report {directory}`",
        highlight=False,
        soft_wrap=True,
    )


@study_app.command("synthetic")
@user_errors
def study_synthetic(
    directory: Path = typer.Argument(..., help="A new folder for the synthetic study."),
    participants: int = typer.Option(
        None, min=1, max=1000, help="Synthetic participants (default 6)."
    ),
    seed: int = typer.Option(
        0, min=0, max=2**32 - 1, help="Random seed (the same seed writes the same study)."
    ),
    trials: int = typer.Option(
        None, min=1, max=10000, help="Trials per task and interface (default 2)."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Write into a non-empty folder."),
) -> None:
    """Write a SYNTHETIC study (made-up numbers, labelled so in every file) to try the report."""
    from wovenskin.study.synthetic import PARTICIPANTS, TRIALS_PER_CONDITION, synthetic_study

    participants = PARTICIPANTS if participants is None else participants
    trials = TRIALS_PER_CONDITION if trials is None else trials
    study = synthetic_study(directory, participants, seed, trials, overwrite)
    console.print(
        f"wrote a SYNTHETIC study to {directory} "
        f"({quantity(len(study.participants), 'participant')}); "
        f"report it with `wovenskin study report {directory}`"
    )


@study_app.command("run")
@user_errors
@robot_errors
def study_run(
    directory: Path = DIR,
    participant: str = typer.Option(..., help="The participant's id (in study.toml)."),
    task: str = typer.Option(..., help="pick_place or pour (one of the study's tasks)."),
    interface: str = typer.Option(..., help="keyboard or skin (the pendant: the dashboard)."),
    trials: int = typer.Option(
        None, min=1, max=10000, help="Trials (default: the study's per condition)."
    ),
    first_trial: int = typer.Option(
        1, min=1, max=10000, help="Number of the first trial (to go on)."
    ),
    skin: str = typer.Option(None, help=SKIN_HELP + " Default: none (keyboard), sim (skin)."),
    model: Path = MODEL,
    mapping: Path = typer.Option(None, help="Action mapping TOML (skin_registered needs one)."),
    time_limit: float = typer.Option(
        None, min=0.1, max=86400.0, help="Seconds from the first command (default: the study's)."
    ),
    seconds: float = typer.Option(
        None, min=0.01, max=604800, help="Stop after this many seconds of session time."
    ),
    overwrite: bool = typer.Option(False, "--overwrite", help="Rerun trials already recorded."),
) -> None:
    """Run a participant's trials of one task and interface in the terminal view.

    Each trial resets the scene (seeded by participant, task and trial) and is timed from
    the first command; it ends on success, the task's failure, the time limit, or the
    experimenter's key: y success, n give up, x abort (space stops the arm, q quits).
    """
    from wovenskin.cli.app import err_console
    from wovenskin.errors import ConfigError
    from wovenskin.runtime.session import open_session
    from wovenskin.study.definition import load_study
    from wovenskin.study.session import StudyTrials
    from wovenskin.teleop.keyboard import TerminalKeyboard
    from wovenskin.ui.run_view import run_with_view, terminal_keys

    study = load_study(directory)
    person = study.participant(participant)
    for what, value, known in (
        ("task", task, study.tasks),
        ("interface", interface, study.interfaces),
    ):
        if value not in known:
            raise ConfigError(f"--{what} {value!r} is not in the study: {', '.join(known)}")
    if interface == "pendant":
        raise ConfigError("the teach pendant is a panel of the web dashboard: run it there")
    if interface == "skin_registered" and mapping is None:
        raise ConfigError('skin_registered needs --mapping: a mapping file with frame = "skin"')
    if seconds is not None and not seconds > 0:
        raise ConfigError(f"--seconds must be positive, got {seconds}")
    keyboard = TerminalKeyboard() if interface == "keyboard" else None
    skin = skin or ("none" if keyboard is not None else "sim")
    hooks: list = []
    session = open_session(
        skin, "sim", model, mapping=mapping, task=task,
        on_tick=lambda s: hooks[0].on_tick(s) if hooks else None,
    )  # fmt: skip
    block = StudyTrials(
        session, session.task, directory, person.id, person.expertise, interface,
        trials or study.trials_per_condition, first=first_trial, overwrite=overwrite,
        time_limit_s=time_limit if time_limit is not None else study.time_limit_s,
    )  # fmt: skip
    hooks.append(block)
    title = f"wovenskin study  {person.id}  {task} / {interface}  (y success, n give up, x abort)"
    try:
        with terminal_keys() as read:
            result = run_with_view(
                session, console, seconds, title=title, keyboard=keyboard,
                read_keys=lambda: block.keys(read()),
            )  # fmt: skip
    finally:
        block.close()
        session.close()
    console.print(result.summary(), highlight=False, soft_wrap=True)
    for s in block.summaries:
        console.print(
            f"trial {s.trial}: {s.outcome}, {s.duration_s:.1f} s, {s.commands} commands",
            highlight=False,
        )
    if not block.done:
        finished = "trial" if len(block.numbers) == 1 else "trials"
        err_console.print(f"{len(block.summaries)} of {len(block.numbers)} {finished} finished")
