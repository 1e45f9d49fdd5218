"""``wovenskin reproduce``: one report (Markdown + HTML + PNGs) of the paper's evaluation.

:func:`reproduce` runs the recognition part (:mod:`.recognition`) and the simulated study
(:mod:`.study`) at one of three sizes (:data:`CONFIGS`: ``tiny`` for the test suite,
``quick`` for a first look in under 10 minutes, ``full`` for the committed report), and
writes ``report.md``, ``report.html`` (images embedded), the PNGs and ``figures.json``
(every number in the report) into the output folder.  The report opens with when, where
and how it was made, and says in every section which command and data made each figure
and where the result differs from the paper.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import platform
import subprocess
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from wovenskin.errors import ConfigError
from wovenskin.io import atomic_write_text, to_jsonable
from wovenskin.outputs import check_new_output
from wovenskin.reproduce import recognition, study
from wovenskin.reproduce.paper import PAPER_REDUCTION_TEXT
from wovenskin.study.document import Block, Bullets, Heading, Text, to_html, to_markdown
from wovenskin.study.simulate import check_hands


@dataclass(frozen=True)
class ReproduceConfig:
    """The sizes of one report."""

    name: str
    recognition: recognition.RecognitionConfig
    study: study.StudyConfig


CONFIGS = {
    "tiny": ReproduceConfig("tiny", recognition.TINY, study.TINY),
    "quick": ReproduceConfig("quick", recognition.QUICK, study.QUICK),
    "full": ReproduceConfig("full", recognition.FULL, study.FULL),
}


@dataclass(frozen=True)
class ReproduceResult:
    markdown: Path
    html: Path
    figures: Path
    wall_s: float


def _git_commit() -> str:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=5,
            cwd=Path(__file__).resolve().parent,
        )  # fmt: skip
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _machine() -> str:
    cpus = os.cpu_count() or 0
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (
        f"{platform.system()} {platform.machine()}, {cpus} CPU cores, Python "
        f"{platform.python_version()}, load average {load} at the start"
    )


def _limits() -> Bullets:
    return Bullets(
        (
            "No person, no real skin and no real arm took part: every study figure comes "
            "from simulated operators on the simulated TM5-900 and a simulated skin. The "
            "operators' timing comes from published human-performance models "
            "(docs/operators.md), not from the paper's participants.",
            "The simulated operators do not model what the paper argues the skin gives: a "
            "more natural mapping from intent to motion (their wrong-way starts have the "
            "same rate on the skin and the keyboard), less looking away from the robot, "
            "fatigue, or learning across conditions (only within one).",
            "Recognition figures on simulated data measure the recogniser against our own "
            "simulator; the HAART section is the one measurement on real human touch "
            "(a pressure grid, not this skin).",
        )
    )


def _timed_recognition(out: Path, config: recognition.RecognitionConfig) -> tuple:
    """The recognition section and its wall time (run in a worker process beside the
    study: training takes one core, the study's trials the others)."""
    started = time.perf_counter()
    blocks, figures = recognition.recognition_section(out, config, log=print)
    return blocks, figures, time.perf_counter() - started


def reproduce(
    out_dir: str | Path,
    config: ReproduceConfig | str = "quick",
    *,
    haart: str | Path | None = None,
    jobs: int | None = None,
    trials: int | None = None,
    overwrite: bool = False,
    command: str = "",
    log: Callable[[str], None] = print,
    hands: str | None = None,
) -> ReproduceResult:
    """Run everything at ``config``'s size and write the report into ``out_dir``;
    ``hands``: the simulated study's (default :data:`~wovenskin.study.simulate.HANDS`)."""
    if isinstance(config, str):
        if config not in CONFIGS:
            raise ConfigError(f"unknown report size {config!r}: use {', '.join(CONFIGS)}")
        config = CONFIGS[config]
    out = Path(out_dir)
    markdown = check_new_output(out / "report.md", overwrite, "a report")
    rec = config.recognition
    if haart is not None:
        rec = recognition.RecognitionConfig(**{**asdict(rec), "haart": Path(haart)})
    sim = config.study
    if jobs is not None:
        sim = study.StudyConfig(**{**asdict(sim), "jobs": jobs})
    if trials is not None:
        sim = study.StudyConfig(**{**asdict(sim), "trials": trials})
    if hands is not None:
        sim = study.StudyConfig(**{**asdict(sim), "hands": check_hands(hands)})
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    when = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    head = [
        Heading("wovenskin: the paper's evaluation, regenerated", 1),
        Text(
            f"Made {when} by `{command or 'wovenskin reproduce'}` (size `{config.name}`) at "
            f"commit {_git_commit()} on {_machine()}. Every number below was measured by "
            "this run; the paper's are quoted beside them. The paper reports "
            f"{PAPER_REDUCTION_TEXT}."
        ),
        Heading("What this report cannot show", 3),
        _limits(),
    ]
    log("recognition (in a worker process) and the simulated study ...")
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        recognising = pool.submit(_timed_recognition, out, rec)
        t0 = time.perf_counter()
        study_blocks, study_figures = study.study_section(out, sim, log=log)
        study_s = time.perf_counter() - t0
        rec_blocks, rec_figures, rec_s = recognising.result()
    wall = time.perf_counter() - started
    timing = Text(
        f"This run took {wall / 60:.1f} min: recognition {rec_s / 60:.1f} min in one worker "
        f"process, beside it the simulated study {study_s / 60:.1f} min "
        f"({sim.jobs} trial(s) at once)."
    )
    blocks: list[Block] = [*head, timing, *rec_blocks, *study_blocks]
    figures: dict[str, Any] = {
        "made": when, "size": config.name, "command": command, "commit": _git_commit(),
        "machine": _machine(), "wall_s": wall, "recognition_s": rec_s, "study_s": study_s,
        "recognition": rec_figures, "study": study_figures,
    }  # fmt: skip
    atomic_write_text(markdown, to_markdown(blocks))
    html = out / "report.html"
    atomic_write_text(html, to_html(blocks, "wovenskin: the paper's evaluation, regenerated", out))
    figures_path = out / "figures.json"
    atomic_write_text(figures_path, json.dumps(to_jsonable(figures), indent=1) + "\n")
    return ReproduceResult(markdown, html, figures_path, wall)
