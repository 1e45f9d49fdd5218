"""The simulated user study of the report: Tables I and II beside the paper's.

:func:`study_section` runs :func:`~wovenskin.study.simulate.simulate_study` (simulated
novices and experts through the skin, the keyboard and the pendant, on the simulated arm)
into ``OUT/study``, writes that study's own report (``wovenskin study report``: tables,
Friedman and Wilcoxon tests, plots) into ``OUT/study/report``, and returns the report's
blocks: the paper's layout with the paper's value beside each simulated one, the relative
time reductions of the skin against each baseline, the statistics, the plots, what the
simulated operators did (gestures misread, moves started the wrong way, give-ups) and
where the simulation differs from the paper.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.io import atomic_write_text
from wovenskin.reproduce.paper import PAPER_PARTICIPANTS, PAPER_TABLES, paper_reduction
from wovenskin.study.definition import HANDS_SOURCES, TIME_LIMIT_S
from wovenskin.study.document import Block, Bullets, Heading, Image, Table, Text
from wovenskin.study.reader import TrialResult, read_trials
from wovenskin.study.report import SIMULATED_BANNER, report_blocks, write_report
from wovenskin.study.simulate import HANDS, TrialRun, simulate_study
from wovenskin.study.tables import fmt, fmt_mean_std, reduction, summarise
from wovenskin.wording import quantity

INTERFACES = ("skin", "keyboard", "pendant")
SIMULATED = Text(SIMULATED_BANNER)  # the study report's banner: this report says it itself
PLOT_CAPTIONS = {
    "box": "{task}: time and commands per interface and expertise, simulated trials",
    "paths": "{task}: TCP paths of one simulated operator, top view",
}
TASK_TITLES = {"pick_place": "Table I: pick-and-place", "pour": "Table II: pouring"}


@dataclass(frozen=True)
class StudyConfig:
    """How big a simulated study the report runs."""

    participants: int  # novices and experts in turn
    trials: int  # per task and interface
    tasks: tuple[str, ...] = ("pick_place", "pour")
    interfaces: tuple[str, ...] = INTERFACES
    jobs: int = 2
    time_limit_s: float = TIME_LIMIT_S
    seed: int = 0
    hands: str = HANDS  # whose people and skins touch the skin


TINY = StudyConfig(
    participants=1,
    trials=1,
    tasks=("pick_place",),
    interfaces=("keyboard",),
    jobs=1,
    time_limit_s=40.0,
)
QUICK = StudyConfig(participants=2, trials=1, jobs=1, time_limit_s=120.0)
FULL = StudyConfig(participants=6, trials=10)


def _command(config: StudyConfig) -> str:
    tasks = " ".join(f"--task {t}" for t in config.tasks)
    if config.interfaces != INTERFACES:
        tasks += " " + " ".join(f"--interface {i}" for i in config.interfaces)
    return (
        f"wovenskin study simulate OUT/study --participants {config.participants} "
        f"--trials {config.trials} --seed {config.seed} {tasks} --time-limit "
        f"{config.time_limit_s:g} --jobs {config.jobs} --hands {config.hands}"
    )


def _cell_text(values: list[float]) -> str:
    if not values:
        return "n/a"
    std = float(np.std(values, ddof=1)) if len(values) > 1 else math.nan
    return fmt_mean_std(float(np.mean(values)), std)


def _comparison_table(trials: list[TrialResult], task: str) -> tuple[Table, dict]:
    rows, figures = [], {}
    header = ["interface", "paper time (s)", "simulated time (s)", "paper commands",
              "simulated commands", "simulated trials"]  # fmt: skip
    if task == "pour":
        header += ["paper SR (%)", "simulated SR (%)"]
    for interface in INTERFACES:
        for expertise in ("novice", "expert"):
            cell = summarise(trials, task, interface, expertise)
            paper = PAPER_TABLES[task][(interface, expertise)]
            row = [
                f"{interface} ({expertise[:3]}.)",
                fmt_mean_std(paper.time_mean, paper.time_std),
                fmt_mean_std(cell.time_mean, cell.time_std),
                fmt_mean_std(paper.commands_mean, paper.commands_std),
                fmt_mean_std(cell.commands_mean, cell.commands_std),
                str(cell.trials),
            ]
            if task == "pour":
                row += [fmt(paper.success_rate or math.nan), fmt(100 * cell.success_rate)]
            rows.append(tuple(row))
            figures[f"{interface}/{expertise}"] = {
                "time_mean": cell.time_mean, "time_std": cell.time_std,
                "commands_mean": cell.commands_mean, "commands_std": cell.commands_std,
                "success_rate": cell.success_rate, "trials": cell.trials,
            }  # fmt: skip
    return Table(tuple(header), tuple(rows)), figures


def _reductions(trials: list[TrialResult], task: str) -> tuple[Table, dict]:
    rows, figures = [], {}
    for expertise in ("novice", "expert"):
        skin = summarise(trials, task, "skin", expertise).time_mean
        for baseline in ("keyboard", "pendant"):
            other = summarise(trials, task, baseline, expertise).time_mean
            ours = reduction(skin, other)
            paper = paper_reduction(task, expertise, baseline)
            rows.append((f"skin vs {baseline} ({expertise})", f"{paper:.1f} %", f"{fmt(ours)} %"))
            figures[f"{expertise}/{baseline}"] = {"paper": paper, "simulated": ours}
    table = Table(("time reduction", "paper", "simulated"), tuple(rows))
    return table, figures


def _differences(figures: dict) -> list[str]:
    """Plain sentences where the simulation's direction differs from the paper's."""
    notes = []
    for task, by in figures.items():
        for key, value in by["reductions"].items():
            ours, paper = value["simulated"], value["paper"]
            expertise, baseline = key.split("/")
            if not math.isfinite(ours):
                notes.append(f"{task}, {expertise}s: no simulated figure for skin vs {baseline}.")
            elif ours <= 0:
                notes.append(
                    f"{task}, {expertise}s: the skin was NOT faster than the {baseline} in "
                    f"simulation ({ours:+.1f} % reduction; the paper: {paper:.1f} %)."
                )
            elif abs(ours - paper) > 15:
                notes.append(
                    f"{task}, {expertise}s: the skin's time reduction against the {baseline} "
                    f"is {ours:.1f} % in simulation, {paper:.1f} % in the paper."
                )
    return notes


def _operator_summary(runs: list[TrialRun]) -> tuple[Table, dict]:
    rows, figures = [], {}
    for interface in INTERFACES:
        mine = [r for r in runs if r.summary.interface == interface]
        if not mine:
            continue
        sim_s = sum(r.summary.end_t - r.summary.start_t for r in mine)
        wall = sum(r.wall_s for r in mine)
        gave_up = sum(bool(r.gave_up) for r in mine)
        figures[interface] = {
            "trials": len(mine), "misread_per_trial": float(np.mean([r.misread for r in mine])),
            "wrong_way_per_trial": float(np.mean([r.wrong_way for r in mine])),
            "gave_up": gave_up, "real_time_factor": sim_s / wall if wall > 0 else math.nan,
        }  # fmt: skip
        f = figures[interface]
        rows.append((interface, str(len(mine)), f"{f['misread_per_trial']:.2f}",
                     f"{f['wrong_way_per_trial']:.2f}", str(gave_up),
                     f"{f['real_time_factor']:.2f}"))  # fmt: skip
    header = ("interface", "trials", "gestures misread / trial", "wrong-way starts / trial",
              "gave up", "simulated s per wall s")  # fmt: skip
    return Table(header, tuple(rows)), figures


def study_section(
    out_dir: Path, config: StudyConfig, log: Callable[[str], None] = print
) -> tuple[list[Block], dict[str, Any]]:
    """Run the simulated study into ``out_dir/study`` and return (blocks, figures)."""
    folder = Path(out_dir) / "study"
    started = time.perf_counter()

    def progress(run: TrialRun) -> None:
        s = run.summary
        log(f"  {s.participant} {s.task}/{s.interface} #{s.trial}: {s.outcome} "
            f"{s.duration_s:.1f} s, {s.commands} commands ({run.wall_s:.0f} s wall)")  # fmt: skip

    study, runs = simulate_study(
        folder, config.participants, config.seed, config.trials, tasks=config.tasks,
        interfaces=config.interfaces, time_limit_s=config.time_limit_s, jobs=config.jobs,
        overwrite=True, progress=progress, hands=config.hands,
    )  # fmt: skip
    wall = time.perf_counter() - started
    rows = [
        {**asdict(r.summary), "wall_s": r.wall_s, "misread": r.misread,
         "wrong_way": r.wrong_way, "gave_up": r.gave_up}
        for r in runs
    ]  # fmt: skip
    atomic_write_text(folder / "runs.json", json.dumps(rows, indent=1, default=str))
    report = write_report(folder, folder / "report", overwrite=True)
    trials, warnings = read_trials(folder)
    command = _command(config)
    blocks: list[Block] = [
        Heading("The user study in simulation (Tables I and II)", 2),
        Text(
            f"**Simulated operators, not people.** `{command}` ran "
            f"{quantity(len(runs), 'trial')} of "
            f"{quantity(config.participants, 'simulated operator')} "
            "(novices and experts in turn; the "
            f"paper: {PAPER_PARTICIPANTS}) in {wall / 60:.1f} min on this machine. Each "
            "trial is a fresh session on the simulated TM5-900 with its gripper; the "
            "operator's timing (thinking, reaction, key presses, pointing, gestures) is drawn "
            "per person from the keystroke-level model and reaction-time literature "
            "(docs/operators.md); on the skin every gesture is performed by the "
            f"{HANDS_SOURCES[config.hands]} (hands `{config.hands}`) and goes through "
            "conditioning, the recogniser and the arbiter, so a misread gesture costs the "
            "operator time. A pick-and-place trial moves one object (cube, cylinder, prism "
            "in turn), as the paper's trial does."
        ),
    ]
    figures: dict[str, Any] = {"config": asdict(config), "trials": len(runs), "wall_s": wall}
    for task in config.tasks:
        table, cells = _comparison_table(trials, task)
        reductions, reduced = _reductions(trials, task)
        figures[task] = {"cells": cells, "reductions": reduced}
        blocks += [
            Heading(f"{TASK_TITLES.get(task, task)}: paper and simulation", 3),
            Text(
                "Mean ± sample standard deviation over trials (time-outs count at the "
                "limit; SR: trials that ended in success, no spill). Paper: its table."
            ),
            table,
            Text(
                "Relative time reduction of the skin against each baseline "
                "(100 × (baseline − skin) / baseline, over the means above):"
            ),  # fmt: skip
            reductions,
        ]
    notes = _differences({t: figures[t] for t in config.tasks})
    blocks += [Heading("Where the simulation differs from the paper", 3)]
    blocks.append(Bullets(tuple(notes)) if notes else Text(
        "In every task and expertise group the skin was faster than both baselines, within "
        "15 points of the paper's reductions."))  # fmt: skip
    operators, operated = _operator_summary(runs)
    figures["operators"] = operated
    blocks += [
        Heading("What the simulated operators did", 3),
        Text(
            "Per interface: gestures the recogniser read as another or as nothing (each "
            "costs a lift, a thought and a retry), moves a tool-frame interface started the "
            "wrong way (noticed, let go, corrected), trials given up, and how much faster "
            "than real time the trials ran here."
        ),  # fmt: skip
        operators,
    ]
    study_blocks = report_blocks(
        study, trials, [], warnings, {t: [] for t in config.tasks}, synthetic=False
    )
    blocks += [Heading("Statistics of the simulated study", 3)]
    blocks += [_demoted(b) for b in study_blocks if b not in (study_blocks[0], SIMULATED)]
    for image in report.images:
        task, kind = image.stem.rsplit("-", 1)
        caption = PLOT_CAPTIONS.get(kind, kind).format(task=task)
        blocks.append(Image(f"study/report/{image.name}", caption))
    figures["warnings"] = warnings
    return blocks, figures


def _demoted(block: Block) -> Block:
    if isinstance(block, Heading):
        return Heading(block.text, min(6, block.level + 2))
    return block
