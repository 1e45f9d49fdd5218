"""Commands that build data sets, train, evaluate and compare models (training needs PyTorch).

Each command imports its library code when it runs: ``wovenskin --help`` stays instant
(the training modules pull in the simulator and scipy), and the modules that import torch
(training.compare, capture_train, capture_lopo) come after ``require_torch``, so the
ONNX-only ``eval`` works without torch.
"""

from __future__ import annotations

import json
from contextlib import nullcontext
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import Progress
from rich.table import Table

from wovenskin.cli.app import MODEL, app, console, err_console, require_torch, user_errors, warn
from wovenskin.cli.app import given as _given
from wovenskin.errors import ConfigError

if TYPE_CHECKING:
    from wovenskin.training.config import TrainConfig
    from wovenskin.training.distributed import Ranks

DEVICE_HELP = "auto (a CUDA GPU when torch sees one, else the CPU), cpu or cuda."
AMP_HELP = (
    "Mixed precision on CUDA: auto (bf16, fp16 on GPUs without bf16), bf16, fp16 or off; "
    "the CPU trains in float32."
)
SPLIT_HELP = "grouped (recordings, people and skins never seen in training) or random (85/15)."

# TrainConfig's settings as options: unset (None) each falls through to TrainConfig's
# default (training/config.py, the one home; tests/cli/test_cli_defaults.py checks the help).
BATCH_SIZE = typer.Option(None, min=1, max=65536, help="Windows per training step (default 64).")
LR = typer.Option(
    None,
    min=1e-7,
    max=1.0,
    help="Peak learning rate: AdamW, warm-up, cosine decay (default 0.003).",
)
PATIENCE = typer.Option(
    None, min=1, max=100000, help="Epochs without a better validation score to stop (default 5)."
)
SPLIT_SEED = typer.Option(
    None, min=0, max=2**32 - 1, help="Seed of the train/validation split (default 0)."
)
SEED = typer.Option(
    None,
    min=0,
    max=2**32 - 1,
    help="Seed of initialisation, batch order, augmentation (default 0).",
)
THREADS = typer.Option(
    None, min=1, max=256, help="Torch threads (default 1: fastest on a busy 2-core machine)."
)
DEVICE = typer.Option(None, help=DEVICE_HELP + " Default: auto.")
AMP = typer.Option(None, help=AMP_HELP + " Default: auto.")


def _json_object(text: str, option: str) -> dict:
    """Parse an option holding a JSON object ('' gives an empty one)."""
    if not text.strip():
        return {}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{option} is not valid JSON: {exc.msg} at column {exc.colno}") from None
    if not isinstance(value, dict):
        raise ConfigError(f"{option} must be a JSON object, e.g. '{{\"n_layers\": 2}}'")
    return value


def _open_or_build_dataset(data: Path | None, ui: Console):
    """The data set at ``data``, or the default one (generated with a progress bar if missing)."""
    from wovenskin.cli.app import dataset_progress
    from wovenskin.training import runs
    from wovenskin.training.report import DatasetSummary

    if data is not None or runs.default_dataset_exists():
        return runs.ensure_dataset(data)[0]
    ui.print(f"no data set given: building the default one in {runs.DEFAULT_DATASET_DIR} (once)")
    bar, update = dataset_progress(ui, "simulating recordings")
    with bar:
        ds, _ = runs.ensure_dataset(None, progress=update)
    summary = DatasetSummary.of(ds)
    ui.print(summary.table(ds.class_names))
    ui.print(summary.describe(), highlight=False, soft_wrap=True)
    return ds


def _interrupted(out: Path) -> typer.Exit:
    err_console.print(
        f"[yellow]interrupted:[/] the last finished epoch is saved in {escape(str(out))}; "
        "run the same command with --resume to continue",
        soft_wrap=True,
        highlight=False,
    )
    return typer.Exit(130)


@app.command()
@user_errors
def train(
    data: Path = typer.Option(
        None,
        help="Window data set directory (default: runs/datasets/sim-default, built if missing).",
    ),
    captures: Path = typer.Option(None, help="Train on labelled captures (.npz) instead."),
    out: Path = typer.Option(None, help="Checkpoint directory (default: runs/models/MODEL-SPLIT)."),
    model: str = typer.Option(None, help="transformer (default), bilstm or tcn."),
    split: str = typer.Option("grouped", help=SPLIT_HELP),
    epochs: int = typer.Option(
        None, min=1, max=100000, help="Most epochs (default 3); may stop sooner."
    ),
    batch_size: int = BATCH_SIZE,
    lr: float = LR,
    seed: int = SEED,
    patience: int = PATIENCE,
    split_seed: int = SPLIT_SEED,
    hparams: str = typer.Option("", help="Model hyperparameters (JSON): '{\"n_layers\": 2}'."),
    resume: bool = typer.Option(False, help="Continue an interrupted run in the same --out."),
    time_budget: float = typer.Option(
        None, min=0.1, max=100000.0, help="Minutes; no epoch starts that would overrun."
    ),
    threads: int = THREADS,
    overwrite: bool = typer.Option(False, help="Replace a trained model already in --out."),
    init_from: Path = typer.Option(
        None,
        help="Fine-tune: start from this checkpoint's weights (e.g. wovenskin/models/default); "
        "same model, hyperparameters and classes.",
    ),
    device: str = DEVICE,
    amp: str = AMP,
) -> None:
    """Train a gesture classifier (PyTorch) with early stopping, checkpoints and resume.

    Several processes or GPUs: torchrun --nproc-per-node N -m wovenskin.cli train ...
    """
    from wovenskin.training import runs
    from wovenskin.training.config import CAPTURE_DEFAULTS, TrainConfig
    from wovenskin.training.progress import TrainProgressDisplay

    require_torch("wovenskin train")
    from wovenskin.training import distributed  # needs torch
    from wovenskin.training.compare import train_on_dataset

    settings = _given(
        batch_size=batch_size, lr=lr, seed=seed, patience=patience, split_seed=split_seed,
        threads=threads, epochs=epochs, device=device, amp=amp,
        time_budget_s=None if time_budget is None else 60 * time_budget,
        init_from=None if init_from is None else str(init_from),
    )  # fmt: skip
    if captures is not None:
        if data is not None:
            raise ConfigError("give --data or --captures, not both")
        if distributed.launched():
            raise ConfigError("torchrun trains on window data sets (--data), not captures")
        if init_from is not None:
            raise ConfigError("--init-from fine-tunes on a window data set (--data), not captures")
        out = out or runs.default_captures_dir(captures)
        runs.check_checkpoint_dir(out, overwrite, resume)
        # Captures keep their own recipe (CAPTURE_DEFAULTS), which the options given change.
        settings.pop("split_seed", None)  # captures are split by participant, not by seed
        config = replace(CAPTURE_DEFAULTS.with_model(model), resume=resume, **settings).checked()
        _train_on_captures(captures, out, config, _hardware_line(config, distributed.SINGLE))
        return
    model = model or TrainConfig.model
    out = out or runs.default_train_dir(model, split)
    parameters = _json_object(hparams, "--hparams")
    config = TrainConfig.from_dict(
        {**settings, "resume": resume, "model": model, "hparams": parameters}
    )
    with distributed.session(config.device) as ranks:
        hardware = _hardware_line(config, ranks)  # an unusable device or precision: refused now
        runs.check_checkpoint_dir(out, overwrite, resume)
        distributed.barrier(ranks)  # every rank has checked before rank 0 writes
        if ranks.active and data is None and not runs.default_dataset_exists():
            raise ConfigError(
                "under torchrun, build the data set first (wovenskin dataset) and give --data"
            )
        ds = _open_or_build_dataset(data, console)
        if ranks.is_main:
            console.print(
                f"training {model} on {ds.path} ({split} split) into {out}, {hardware}",
                highlight=False,
                soft_wrap=True,
            )
        display = TrainProgressDisplay(console) if ranks.is_main else nullcontext(None)
        try:
            with display as show:
                result = train_on_dataset(ds, out, split, config, show)
        except KeyboardInterrupt:
            raise _interrupted(out) from None
    if not ranks.is_main:
        return  # rank 0 reports
    v = result.validation
    resumed = f", resumed at epoch {result.resumed_from_epoch}" if result.resumed_from_epoch else ""
    console.print(
        f"best epoch {result.best_epoch} of {result.epochs_run} ({result.stop_reason}{resumed}): "
        f"validation accuracy {100 * v.accuracy:.2f} %, macro-F1 {v.macro_f1:.4f} on {v.n} "
        f"windows\ncheckpoint {out} (model.pt, model.onnx, meta.json); full report: "
        f"wovenskin eval --model {out}",
        highlight=False,
        soft_wrap=True,
    )


def _hardware_line(config: TrainConfig, ranks: Ranks) -> str:
    """Where a run computes, in words: device, precision and processes."""
    from wovenskin.training.device import amp_dtype, resolve_device  # needs torch

    where = resolve_device(config.device, ranks.local_rank)
    dtype = amp_dtype(config.amp, where)
    text = "on the CPU (float32)" if where.type == "cpu" else f"on {where}"
    if dtype is not None:
        text += f" ({str(dtype).removeprefix('torch.')} mixed precision)"
    if ranks.active:
        text += f", {ranks.world_size} processes (DistributedDataParallel)"
    return text


def _train_on_captures(path: Path, out: Path, config: TrainConfig, hardware: str) -> None:
    from wovenskin.training.capture_train import train_on_captures  # needs torch
    from wovenskin.training.progress import TrainProgressDisplay

    console.print(
        f"training on labelled captures {path} into {out}, {hardware}",
        highlight=False,
        soft_wrap=True,
    )
    try:
        with TrainProgressDisplay(console) as show:
            result = train_on_captures(path, out, config, progress=show)
    except KeyboardInterrupt:
        raise _interrupted(out) from None
    validation = getattr(result, "validation", None)
    if validation is not None:
        console.print(
            f"best epoch {result.best_epoch} ({result.stop_reason}): validation window "
            f"accuracy {100 * validation.accuracy:.2f} %, macro-F1 {validation.macro_f1:.4f}",
            highlight=False,
            soft_wrap=True,
        )
    console.print(
        f"checkpoint {out}; per-capture scores: wovenskin eval --captures FILE --model {out}",
        highlight=False,
        soft_wrap=True,
    )


def _print_scalars(document: dict, title: str) -> None:
    """The top-level numbers and strings of a result document, as a two-column table."""
    table = Table(title=title, show_header=False)
    for key, value in document.items():
        if isinstance(value, float):
            table.add_row(key, f"{value:.4f}")
        elif isinstance(value, int | str) and not isinstance(value, bool):
            table.add_row(key, str(value))
    console.print(table)


@app.command("eval")
@user_errors
def eval_command(
    model: Path = MODEL,
    data: Path = typer.Option(
        None,
        help="Window data set (default: the one the model was trained on, else "
        "runs/datasets/sim-default).",
    ),
    split: str = typer.Option(
        None, help="grouped, random or all (default: the split the model was trained on)."
    ),
    split_seed: int = typer.Option(
        None, min=0, max=2**32 - 1, help="Seed of the split (default: the training one)."
    ),
    out: Path = typer.Option(None, help="Report directory (default: MODEL/eval-SPLIT)."),
    captures: Path = typer.Option(None, help="Score on labelled captures (.npz) instead."),
    lopo: bool = typer.Option(
        False, help="With --captures: leave-one-participant-out training and scoring."
    ),
    arch: str = typer.Option(None, help="With --lopo: the model to train in every fold."),
    epochs: int = typer.Option(None, min=1, max=100000, help="With --lopo: most epochs per fold."),
    threads: int = typer.Option(
        None, min=1, max=256, help="ONNX Runtime threads (default 1; --lopo: torch's)."
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object, nothing else."),
) -> None:
    """Score a model with ONNX Runtime: accuracy, macro-F1, per-class table, confusion matrix."""
    from wovenskin.outputs import check_writable
    from wovenskin.recognition.shipped import DEFAULT_MODEL_DIR, resolve_model_dir
    from wovenskin.training import runs
    from wovenskin.training.report import evaluate_on_dataset, per_class_table, write_report

    if out is not None:
        check_writable(out, folder=True)  # refused now, not after the scoring
    if captures is not None:
        _eval_captures(captures, model, out, lopo, arch, epochs, threads, json_out)
        return
    if lopo:
        raise ConfigError("--lopo needs --captures FILE")
    model_dir = resolve_model_dir(model)
    data = data or runs.eval_dataset_dir(model_dir)
    with Progress(console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
        task = bar.add_task("classifying windows", total=None)
        report = evaluate_on_dataset(
            model_dir, data, split, split_seed, **_given(threads=threads),
            progress=lambda done, total: bar.update(task, completed=done, total=total),
        )  # fmt: skip
    if out is None:
        shipped = model_dir.resolve() == DEFAULT_MODEL_DIR.resolve()
        base = runs.RUNS_DIR / "eval" / "shipped" if shipped else model_dir
        out = base / f"eval-{report.split}"
    files = write_report(report, out)
    for warning in report.warnings:
        warn(warning)
    if json_out:
        document = {
            **report.to_dict(),
            "report_dir": str(out),
            "files": [str(files.metrics_json), str(files.confusion_json), str(files.confusion_png)],
        }
        print(json.dumps(document))
        return
    console.print(per_class_table(report.metrics, title=f"{report.model_name} on {data}"))
    console.print(report.summary(), highlight=False, soft_wrap=True)
    console.print(f"report: {files.metrics_json}, {files.confusion_json}, {files.confusion_png}")


def _eval_captures(
    path: Path, model: Path | None, out: Path | None, lopo: bool, arch: str | None,
    epochs: int | None, threads: int | None, json_out: bool,
) -> None:  # fmt: skip
    from wovenskin.recognition.shipped import resolve_model_dir
    from wovenskin.training import capture_eval, runs
    from wovenskin.training.config import CAPTURE_DEFAULTS
    from wovenskin.training.progress import TrainProgressDisplay

    if lopo:
        require_torch("wovenskin eval --lopo")
        from wovenskin.training.capture_lopo import leave_one_participant_out  # needs torch

        if model is not None:
            raise ConfigError("--lopo trains its own models: name the architecture with --arch")
        config = replace(CAPTURE_DEFAULTS.with_model(arch), **_given(threads=threads))
        if epochs is not None:
            config = replace(config, epochs=epochs)
        with TrainProgressDisplay(err_console) as show:
            result = leave_one_participant_out(
                path, out or runs.default_lopo_dir(path), config, progress=show
            )
        title = f"leave-one-participant-out on {path}"
    else:
        with err_console.status(f"scoring {path}..."):
            result = capture_eval.evaluate_captures(path, resolve_model_dir(model))
        title = f"{path} scored by {model or 'the shipped model'}"
    document = result.to_dict()
    if json_out:
        print(json.dumps(document))
    else:
        _print_scalars(document, title)


@app.command()
@user_errors
def compare(
    data: list[Path] = typer.Option(
        None,
        help="Window data set (default: runs/datasets/sim-default, built if missing); give "
        "--data twice (e.g. a stream-recipe and an overlay-recipe set) to compare recipes.",
    ),
    streams: list[Path] = typer.Option(
        None,
        help="Labelled streams (.npz) to run each model's whole pipeline on: event F1, "
        "false activations/min and latency beside the window figures.",
    ),
    out: Path = typer.Option(Path("runs/compare"), help="Directory of checkpoints and reports."),
    models: str = typer.Option(
        "", help="Comma-separated models (default: every registered one: transformer,bilstm,tcn)."
    ),
    split: str = typer.Option("grouped", help="grouped, random or both: grouped,random."),
    epochs: int = typer.Option(
        None, min=1, max=100000, help="Most epochs per model (default 3); may stop sooner."
    ),
    batch_size: int = BATCH_SIZE,
    lr: float = LR,
    seed: int = SEED,
    patience: int = PATIENCE,
    split_seed: int = SPLIT_SEED,
    hparams: str = typer.Option(
        "", help='Hyperparameters per model, JSON: \'{"bilstm": {"hidden": 64}}\'.'
    ),
    resume: bool = typer.Option(False, help="Continue interrupted runs in --out."),
    overwrite: bool = typer.Option(False, help="Replace a comparison already in --out."),
    time_budget: float = typer.Option(
        None, min=0.1, max=100000.0, help="Minutes per model and split."
    ),
    threads: int = THREADS,
    latency_repeats: int = typer.Option(
        None, min=1, max=10000000, help="Timed batch-1 calls per model (default 300)."
    ),
    device: str = DEVICE,
    amp: str = AMP,
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object, nothing else."),
) -> None:
    """Train and score several models on the same data and split: the side-by-side table."""
    from wovenskin.training import runs
    from wovenskin.training.config import TrainConfig
    from wovenskin.training.progress import TrainProgressDisplay

    require_torch("wovenskin compare")
    from wovenskin.training import distributed
    from wovenskin.training.compare import compare_models  # needs torch

    if distributed.launched():
        raise ConfigError("compare runs in one process: under torchrun, use wovenskin train")

    names = [m.strip() for m in models.split(",") if m.strip()]
    splits = [s.strip() for s in split.split(",") if s.strip()]
    parameters = _json_object(hparams, "--hparams")
    if any(not isinstance(v, dict) for v in parameters.values()):
        raise ConfigError("--hparams must map model names to JSON objects")
    ui = err_console if json_out else console
    targets = [out] if len(data or [None]) == 1 else [out / Path(str(d)).name for d in data]
    for target in targets:  # refused before any data set is built or model trained
        runs.check_comparison_dir(target, overwrite, resume)
    config = TrainConfig.from_dict(
        {"resume": resume, **_given(
            batch_size=batch_size, lr=lr, seed=seed, patience=patience, split_seed=split_seed,
            threads=threads, epochs=epochs, device=device, amp=amp,
            time_budget_s=None if time_budget is None else 60 * time_budget,
        )}
    )  # fmt: skip
    datasets = [_open_or_build_dataset(d, ui) for d in (data or [None])]

    def reported(model: str, split_name: str, report) -> None:
        ui.print(f"{model} / {split_name}: {report.summary()}", highlight=False, soft_wrap=True)

    comparisons, repeats = [], _given(latency_repeats=latency_repeats)  # unset: LATENCY_REPEATS
    for ds in datasets:
        target = out if len(datasets) == 1 else out / Path(str(ds.path)).name
        try:
            with TrainProgressDisplay(ui) as show:
                comparison = compare_models(
                    ds, target, names, splits, config, parameters, progress=show,
                    on_report=reported, streams=list(streams or []), **repeats,
                )  # fmt: skip
            comparisons.append(comparison)
        except KeyboardInterrupt:
            raise _interrupted(target) from None
    if json_out:
        documents = [c.to_dict() for c in comparisons]
        print(json.dumps(documents[0] if len(documents) == 1 else {"comparisons": documents}))
    else:
        for comparison in comparisons:
            console.print(comparison.table())
        console.print(f"written: compare.json in {out} (per data set) and an eval report per model")
