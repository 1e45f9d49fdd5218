"""The measurements behind the recognition part of ``wovenskin reproduce``, as JSON-able figures.

This module owns what is run and how its results become figures: :class:`RecognitionConfig`
(what to run) and :func:`measure` (run it all), made of the steps: the simulated window data
set (:func:`build_dataset`), the transformer and BiLSTM trained and scored on the same data
on the random and grouped splits, with per-window latency and stream events
(:func:`compare_both`), the unseen labelled streams (:func:`unseen_streams`), the shipped
default model on those streams (:func:`shipped_on_streams`) and on the robustness suite
(:func:`robustness`), and HAART leave-one-participant-out (:func:`haart_lopo`); plus the
functions that turn each result into plain figures (``*_figures``, :func:`jsonable`).
:mod:`.recognition` (the public API and its presets) sets the figures into the report.
Needs torch.
"""

from __future__ import annotations

import math
import platform
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import suppress
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.bench.recognition import (
    DEFAULT_BASE_SEED,
    RecognitionBenchResult,
    figures,
    run_recognition_benchmark,
)
from wovenskin.recognition.event_scoring import EventScores
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.recognition.shipped import default_model_dir
from wovenskin.recording.formats import LabelledStream
from wovenskin.sim.stream import simulate_stream
from wovenskin.training.capture_lopo import FoldResult, LopoResult, leave_one_participant_out
from wovenskin.training.compare import (
    Comparison,
    ComparisonRow,
    SplitScore,
    StreamScore,
    compare_models,
    score_on_streams,
)
from wovenskin.training.config import CAPTURE_DEFAULTS, TrainConfig
from wovenskin.training.datasets import WindowDataset, generate_sim_dataset
from wovenskin.training.history import TrainEvent
from wovenskin.training.report import EvalReport, dataset_split, plot_confusion
from wovenskin.training.window_settings import WindowSettings

Log = Callable[[str], None]

MODELS = ("transformer", "bilstm")
"""The paper's model and its baseline, in the order the report shows them."""
SPLITS = ("random", "grouped")
"""The paper's split first: its models are the ones timed and run on streams."""
STREAM_SEED_ENTROPY = 7_100
"""Unseen stream ``i`` of seed ``s`` is simulated from
``SeedSequence((7100, s)).generate_state(n)[i]``, far from any training recording's
``SeedSequence(s, spawn_key=(i,))``."""
DATASET_WORKERS = 1
"""Simulated recordings are made in this process: ``wovenskin reproduce`` runs this part in
one worker process beside the simulated study, which keeps the other cores busy."""
EVENT_KEYS = ("events", "precision", "recall", "f1", "false_activations_per_min")


# ============================================================================== running


@dataclass(frozen=True)
class RecognitionConfig:
    """What the recognition part runs (presets: ``recognition.TINY``, ``QUICK``, ``FULL``).

    The last four fields (defaults: the project's ``wovenskin dataset`` recipe) set how
    many windows each simulated person contributes and how they are cut.
    """

    people: int  # simulated people/skins in the window data set
    epochs: int  # training epochs for each model
    streams: int  # unseen simulated labelled streams for stream-event scoring
    stream_seconds: float  # length of each (and of each robustness-suite stream)
    robustness_streams: int  # streams per condition of the robustness suite (0: skip it)
    conditions: tuple[str, ...] | None  # robustness conditions to run (None: all 15)
    haart: Path | None  # HAART labelled-captures .npz (None: not run; the section says how)
    haart_epochs: int
    seed: int = 0
    windows_per_person: int = 1000
    invalid_windows_per_person: int = 400
    seconds_per_person: float = 120.0
    recipe: str = "stream"

    def to_dict(self) -> dict[str, Any]:
        return jsonable(asdict(self))


def measure(out: Path, config: RecognitionConfig, work_name: str, log: Log) -> dict[str, Any]:
    """Everything the recognition part reports, measured now; PNGs and checkpoints in ``out``.

    Checkpoints and HAART folds go to ``out/work_name``; the window data set lives in a
    temporary directory only while the models train.  Returns plain JSON figures.
    """
    out.mkdir(parents=True, exist_ok=True)
    work = out / work_name
    started = time.perf_counter()
    timings: dict[str, float] = {}
    seeds = stream_seeds(config.streams, config.seed)
    log(f"recognition: simulating {config.streams} unseen stream(s) of {config.stream_seconds:g} s")
    streams, timings["streams_simulate"] = timed(
        lambda: unseen_streams(seeds, config.stream_seconds)
    )
    with tempfile.TemporaryDirectory(prefix="wovenskin-reproduce-") as tmp:
        log(f"recognition: building the window data set of {config.people} simulated people")
        ds, timings["dataset"] = timed(lambda: build_dataset(Path(tmp) / "windows", config, log))
        dataset = dataset_figures(ds, timings["dataset"], config.seed)
        log("recognition: training the transformer and the BiLSTM on both splits")
        train = TrainConfig(epochs=config.epochs, seed=config.seed, split_seed=config.seed)
        (comparison, reports), timings["compare"] = timed(
            lambda: compare_both(ds, work, train, streams, log)
        )
    log("recognition: the shipped default model on the unseen streams")
    shipped, timings["shipped_streams"] = timed(lambda: shipped_on_streams(streams))
    bench = haart = None
    if config.robustness_streams > 0:
        log("recognition: the robustness suite on the shipped default model")
        bench, timings["robustness"] = timed(lambda: robustness(config, log))
    if config.haart is not None:
        log(f"recognition: HAART leave-one-participant-out on {config.haart}")
        haart, timings["haart"] = timed(lambda: haart_lopo(config, work / "haart-lopo", log))
    pngs = confusion_pngs(out, reports, haart)
    timings["total"] = time.perf_counter() - started
    models = {row.model: model_figures(row) for row in comparison.rows}
    return jsonable({
        "config": config.to_dict(),
        "dataset": dataset,
        **models,
        "latency_ratio": models["transformer"]["latency_ms"] / models["bilstm"]["latency_ms"],
        "latency_repeats": comparison.latency_repeats,
        "cpu": cpu_name(),
        "stream_seeds": seeds,
        "shipped": {
            "model_dir": str(default_model_dir()),
            "streams": stream_figures(shipped),
            "robustness": None if bench is None else robustness_figures(bench),
        },
        "haart": None if haart is None else haart_figures(haart),
        "png": pngs,
        "timings_s": timings,
    })  # fmt: skip


def cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``), else what :mod:`platform` knows."""
    with suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def build_dataset(directory: Path, config: RecognitionConfig, log: Log) -> WindowDataset:
    """The simulated window data set: one new person on one new skin per recording."""
    c = config
    step = max(1, c.people // 5)

    def progress(done: int, total: int) -> None:
        if done and (done % step == 0 or done == total):
            log(f"  data set: {done}/{total} simulated people")

    return generate_sim_dataset(
        directory, c.people, c.windows_per_person, c.invalid_windows_per_person,
        c.seconds_per_person, seed=c.seed, workers=DATASET_WORKERS, progress=progress,
        settings=WindowSettings(recipe=c.recipe),
    )  # fmt: skip


def stream_seeds(n: int, seed: int) -> list[int]:
    """Seeds of the ``n`` unseen streams (see :data:`STREAM_SEED_ENTROPY`)."""
    if n < 1:
        return []
    state = np.random.SeedSequence((STREAM_SEED_ENTROPY, seed)).generate_state(n)
    return [int(s) for s in state]


def unseen_streams(seeds: Sequence[int], seconds: float) -> list[LabelledStream]:
    """``simulate_stream(seconds, seed)`` for every seed: a new person on a new skin each."""
    return [simulate_stream(seconds, seed) for seed in seeds]


def _epoch_logger(log: Log) -> Callable[[str, TrainEvent], None]:
    def progress(label: str, event: TrainEvent) -> None:
        if event.kind == "epoch" and event.record is not None:
            r = event.record
            log(
                f"  {label}: epoch {event.epoch}/{event.epochs}, validation accuracy "
                f"{100 * r.val_accuracy:.1f} %, {r.seconds:.0f} s"
            )

    return progress


def compare_both(
    ds: WindowDataset,
    work_dir: Path,
    config: TrainConfig,
    streams: Sequence[LabelledStream],
    log: Log,
) -> tuple[Comparison, dict[tuple[str, str], EvalReport]]:
    """Both models on both splits of ``ds`` (:func:`compare_models`) and their eval reports."""
    reports: dict[tuple[str, str], EvalReport] = {}

    def keep(model: str, split: str, report: EvalReport) -> None:
        reports[(model, split)] = report
        log(f"  {model} / {split}: {report.summary()}")

    comparison = compare_models(
        ds, work_dir, MODELS, SPLITS, config, progress=_epoch_logger(log), on_report=keep,
        streams=streams,
    )  # fmt: skip
    for state in work_dir.glob("*/*/training_state.pt"):  # resume state: ~10 MB, not needed
        state.unlink()
    return comparison, reports


def shipped_on_streams(streams: Sequence[LabelledStream]) -> StreamScore:
    """The shipped default model's whole live pipeline on ``streams``."""
    return score_on_streams(default_model_dir(), streams)


def robustness(config: RecognitionConfig, log: Log) -> RecognitionBenchResult:
    """The robustness suite on the shipped default model (ONNX Runtime, one thread)."""

    def progress(done: int, total: int, what: str) -> None:
        if done < total:
            log(f"  robustness: stream {done + 1}/{total} ({what})")

    return run_recognition_benchmark(
        OnnxRecognizer(default_model_dir(), threads=1),
        conditions=None if config.conditions is None else list(config.conditions),
        streams_per_condition=config.robustness_streams,
        seconds=config.stream_seconds,
        base_seed=robustness_base_seed(config.seed),
        progress=progress,
    )


def robustness_base_seed(seed: int) -> int:
    """The suite's base seed: ``wovenskin bench recognition``'s default for seed 0."""
    return DEFAULT_BASE_SEED + seed


def haart_config(epochs: int, seed: int) -> TrainConfig:
    """The project's capture recipe (:data:`CAPTURE_DEFAULTS`) with ``epochs`` and ``seed``."""
    return replace(CAPTURE_DEFAULTS, epochs=epochs, seed=seed, threads=1)


def haart_lopo(config: RecognitionConfig, out_dir: Path, log: Log) -> LopoResult:
    """Leave-one-participant-out on ``config.haart`` with the project's capture recipe."""
    assert config.haart is not None

    def fold_done(fold: FoldResult) -> None:
        log(
            f"  HAART fold {fold.index}/{fold.folds} ({fold.participant}): capture accuracy "
            f"{100 * fold.evaluation.capture_accuracy:.1f} %, {fold.train_seconds:.0f} s"
        )

    recipe = haart_config(config.haart_epochs, config.seed)
    return leave_one_participant_out(Path(config.haart), out_dir, recipe, on_fold=fold_done)


# ============================================================================== figures


def jsonable(value: Any) -> Any:
    """``value`` as plain JSON: non-finite floats become None, numpy and paths plain."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | np.integer):
        return int(value)
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    return value


def dataset_figures(ds: WindowDataset, seconds_to_build: float, seed: int) -> dict[str, Any]:
    """Size of the data set and of the training/validation sides of both splits."""
    labels = np.asarray(ds.labels)
    invalid = ds.class_names.index("invalid") if "invalid" in ds.class_names else -1
    sides = {}
    for name in SPLITS:
        split = dataset_split(ds, name, seed=seed)
        sides[name] = {
            "description": split.name,
            "n_train": int(split.train.size),
            "n_val": int(split.val.size),
            "held_out": {k: len(v) for k, v in split.held_out.items()},
        }
    return {
        "windows": len(ds),
        "invalid_windows": int(np.sum(labels == invalid)),
        "people": len(set(np.asarray(ds.person).tolist())),
        "skins": len(set(np.asarray(ds.skin).tolist())),
        "splits": sides,
        "build_seconds": seconds_to_build,
    }


def _split_figures(score: SplitScore) -> dict[str, Any]:
    keys = ("accuracy", "macro_f1", "n_val", "epochs_run", "best_epoch", "train_seconds")
    return {k: getattr(score, k) for k in keys}


def model_figures(row: ComparisonRow) -> dict[str, Any]:
    """One compared model: both splits, ORT latency and the stream events."""
    return {
        "params": row.params,
        **{split: _split_figures(score) for split, score in row.scores.items()},
        "latency_ms": row.latency_median_ms,
        "latency_p99_ms": row.latency_p99_ms,
        "streams": None if row.stream is None else stream_figures(row.stream),
    }


def stream_figures(score: StreamScore) -> dict[str, Any]:
    """A :class:`StreamScore` under the keys of the robustness figures."""
    return {
        "streams": score.n_streams,
        "events": score.n_events,
        "precision": score.precision,
        "recall": score.recall,
        "f1": score.f1,
        "false_activations_per_min": score.false_per_min,
        "median_latency_ms": score.median_latency_ms,
        "median_motion_latency_ms": score.median_motion_latency_ms,
    }


def _event_figures(scores: EventScores) -> dict[str, Any]:
    f = figures(scores)
    picked = {k: f[k] for k in EVENT_KEYS}
    for key in ("median_latency_s", "median_motion_latency_s"):
        value = f[key]
        picked[key.replace("_s", "_ms")] = None if value is None else 1e3 * value
    return picked


def robustness_figures(result: RecognitionBenchResult) -> dict[str, Any]:
    """Pooled and per-condition event figures of the suite, its targets and its time."""
    worst = result.worst_condition
    return {
        "model": result.model,
        "streams_per_condition": result.streams_per_condition,
        "seconds": result.seconds,
        "base_seed": result.base_seed,
        "pooled": _event_figures(result.pooled),
        "conditions": {c.name: _event_figures(c.scores) for c in result.conditions},
        "worst_condition": None if worst is None else {"name": worst[0], "f1": worst[1]},
        "targets": result.targets(),
        "wall_s": result.wall_s,
    }


def haart_figures(result: LopoResult) -> dict[str, Any]:
    """Pooled LOPO figures and each participant's capture accuracy."""
    return {
        "source": result.source,
        "capture_accuracy": result.capture_accuracy,
        "window_accuracy": result.window_accuracy,
        "macro_f1": result.captures.macro_f1,
        "n_captures": result.captures.n,
        "participants": {f.participant: f.evaluation.capture_accuracy for f in result.folds},
        "epochs": result.config.epochs,
        "model": result.config.model,
        "seed": result.config.seed,
        "seconds": result.seconds,
    }


def confusion_pngs(
    out: Path, reports: Mapping[tuple[str, str], EvalReport], haart: LopoResult | None
) -> dict[str, str]:
    """Confusion-matrix PNGs of both models on both splits (and HAART's): paths in ``out``."""
    pngs = {}
    for (model, split), report in sorted(reports.items()):
        name = f"recognition-confusion-{model}-{split}.png"
        plot_confusion(report.metrics, out / name, title=f"{model}, {split} split")
        pngs[f"{model}/{split}"] = name
    if haart is not None:
        name = "recognition-confusion-haart-lopo.png"
        plot_confusion(haart.captures, out / name, title="HAART, leave one participant out")
        pngs["haart"] = name
    return pngs


def timed(call: Callable[[], Any]) -> tuple[Any, float]:
    """``call()`` and the seconds it took."""
    started = time.perf_counter()
    return call(), time.perf_counter() - started
