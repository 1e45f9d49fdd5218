"""The ``wovenskin`` command line (Typer + Rich).

Each command is a thin layer over a library function; heavy imports happen inside the
commands so ``wovenskin --help`` stays instant.  Errors a user can cause (a missing file, a
bad option, an unplugged device) end with one red line and exit code 2, never a traceback.
"""

from __future__ import annotations

import functools
import sys
from pathlib import Path

import typer
from rich.console import Console
from rich.markup import escape

app = typer.Typer(
    help="Gesture control of a robot arm with a woven capacitive tactile skin.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
bench_app = typer.Typer(help="Benchmarks: print measured figures and ratios.", no_args_is_help=True)
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


def user_errors(fn):
    """Turn expected user errors into one red line and exit code 2.

    An output that exists (:class:`~wovenskin.outputs.OutputExistsError`, raised by every
    writer) is refused naming ``--overwrite``, the option each writing command has."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from wovenskin.outputs import CLI_SWITCH, OutputExistsError
        from wovenskin.recording.formats import FormatError

        try:
            return fn(*args, **kwargs)
        except (FormatError, ValueError, FileNotFoundError, FileExistsError, OSError) as exc:
            text = exc.message(CLI_SWITCH) if isinstance(exc, OutputExistsError) else str(exc)
            message = " ".join(text.split()) or type(exc).__name__
            err_console.print(f"[red]error:[/] {escape(message)}", soft_wrap=True, highlight=False)
            raise typer.Exit(2) from None

    return wrapper


@app.command()
@user_errors
def view(
    skin: str = typer.Option("sim", help=SKIN_HELP),
    seconds: float = typer.Option(None, help="Stop after this many seconds (default: Ctrl-C)."),
    fps: float = typer.Option(25.0, help="Display updates per second."),
    full_scale: float = typer.Option(
        0.0, help="Relative change shown at full brightness (0: follow the signal)."
    ),
    smoothing_ms: float = typer.Option(100.0, help="Moving-average length in ms."),
    snapshot: Path = typer.Option(None, help="Save the last screen as an SVG file at exit."),
    overwrite: bool = typer.Option(False, help="Replace an existing --snapshot file."),
) -> None:
    """Show a skin live in the terminal: heatmap, contacts, frame rate, error counters."""
    from wovenskin.outputs import check_new_output
    from wovenskin.ui.view import run_view

    if snapshot is not None:
        check_new_output(snapshot, overwrite)  # refused now, not after the session

    result = run_view(
        skin,
        seconds=seconds,
        fps=fps,
        full_scale=full_scale or None,
        config=_config_for(smoothing_ms),
        console=console,
        snapshot=snapshot,
    )
    console.print(
        f"{result.frames} frames in {result.seconds:.1f} s, "
        f"display {result.display_rate_hz:.1f} updates/s, {result.bad_frames} bad frames"
    )


def _config_for(smoothing_ms: float):
    """Conditioning settings, or None for the defaults at the source's own sample rate."""
    from wovenskin.signal.config import ConditioningConfig

    if smoothing_ms == 100.0:
        return None
    return ConditioningConfig(smoothing_s=smoothing_ms / 1000)


@app.command()
@user_errors
def simulate(
    out: Path = typer.Option(..., help="Labelled-stream .npz to write (docs/formats.md)."),
    seconds: float = typer.Option(60.0, help="Length of the stream."),
    seed: int = typer.Option(1, help="Random seed: the same seed gives the same file."),
    rows: int = typer.Option(10, help="Skin rows."),
    cols: int = typer.Option(10, help="Skin columns."),
    gestures: str = typer.Option("", help="Comma-separated gestures to draw from (default: all)."),
    invalid_fraction: float = typer.Option(0.25, help="Share of events that are invalid touches."),
    overwrite: bool = typer.Option(False, help="Replace an existing file."),
) -> None:
    """Write a labelled stream of a simulated person on a simulated skin."""
    from wovenskin.gestures import check_name
    from wovenskin.outputs import check_new_output
    from wovenskin.recording.formats import write_labelled_stream
    from wovenskin.sim.stream import simulate_stream
    from wovenskin.skin.layout import SkinLayout

    names = [check_name(g.strip()) for g in gestures.split(",") if g.strip()] or None
    check_new_output(out, overwrite)  # before the simulation, not after it
    stream = simulate_stream(
        seconds,
        seed,
        layout=SkinLayout(rows, cols),
        gestures=names,
        invalid_fraction=invalid_fraction,
    )
    write_labelled_stream(out, stream, overwrite=overwrite)
    labels = list(stream.event_labels)
    console.print(
        f"wrote {out}: {len(stream.t)} frames ({seconds:g} s at {stream.sample_rate_hz:g} Hz), "
        f"{len(labels)} events ({sum(lab != 'invalid' for lab in labels)} gestures, "
        f"{sum(lab == 'invalid' for lab in labels)} invalid)"
    )


@app.command()
@user_errors
def record(
    out: Path = typer.Option(..., help="Native recording to write (.wsrec)."),
    skin: str = typer.Option("sim", help=SKIN_HELP),
    participant: str = typer.Option("anonymous", help="Who performs the gestures."),
    operator: str = typer.Option("", help="Who runs the session."),
    skin_id: str = typer.Option("", help="Which physical skin (default: the device id)."),
    trials: int = typer.Option(3, help="Trials per gesture."),
    gestures: str = typer.Option("", help="Comma-separated gestures (default: all 14)."),
    invalid_trials: int = typer.Option(3, help="Trials of deliberate invalid touches."),
    countdown: float = typer.Option(2.0, help="Seconds of countdown before each trial."),
    trial_seconds: float = typer.Option(3.0, help="Seconds to perform each trial."),
    seed: int = typer.Option(0, help="Seed of the trial order."),
    notes: str = typer.Option("", help="Free notes kept in the recording."),
    overwrite: bool = typer.Option(False, help="Replace an existing file."),
) -> None:
    """Guided recording: prompts each gesture with a countdown and labels every trial.

    Ctrl-C ends the session early: what was recorded is kept and the exit code is 130.
    """
    from wovenskin.gestures import GESTURE_NAMES, check_name
    from wovenskin.ui.record_session import RecordPlan, run_record_session

    names = [check_name(g.strip()) for g in gestures.split(",") if g.strip()] or list(GESTURE_NAMES)
    plan = RecordPlan(
        gestures=names,
        trials_per_gesture=trials,
        invalid_trials=invalid_trials,
        countdown_s=countdown,
        trial_s=trial_seconds,
        seed=seed,
    )
    summary = run_record_session(
        out,
        skin,
        plan,
        provenance={
            "participant": participant,
            "operator": operator,
            "skin_id": skin_id,
            "notes": notes,
        },
        overwrite=overwrite,
        console=console,
    )
    console.print(str(summary), highlight=False, soft_wrap=True)
    if summary.interrupted:  # a script must see that the session was cut short
        err_console.print(
            f"[yellow]interrupted:[/] the session was cut short by Ctrl-C; what was recorded "
            f"is kept in {escape(str(out))}",
            soft_wrap=True,
            highlight=False,
        )
        raise typer.Exit(130)


@app.command()
@user_errors
def devices(all_ports: bool = typer.Option(False, "--all", help="Show every port.")) -> None:
    """List serial ports with their USB descriptions (likely skins first)."""
    from rich.table import Table

    from wovenskin.skin.ports import list_ports

    ports = list_ports()
    shown = ports if all_ports else [p for p in ports if p.likely_skin or p.vid is not None]
    if not shown:
        console.print("no USB serial ports found" + ("" if all_ports else " (try --all)"))
        return
    table = Table("port", "description", "VID:PID", "serial", "manufacturer", "skin?")
    for p in sorted(shown, key=lambda p: (not p.likely_skin, p.device)):
        vidpid = f"{p.vid:04X}:{p.pid:04X}" if p.vid is not None and p.pid is not None else "-"
        table.add_row(
            p.device,
            p.description or "-",
            vidpid,
            p.serial_number or "-",
            p.manufacturer or "-",
            "likely" if p.likely_skin else "",
        )
    console.print(table)


@app.command()
@user_errors
def info(path: Path = typer.Argument(..., help="A .npz stream/captures or a .wsrec file.")) -> None:
    """Describe a data file: kind, shape, rate, labels, provenance, problems."""
    from wovenskin.recording.inspect import describe_file

    console.print(describe_file(path))


@app.command()
@user_errors
def convert(
    src: Path = typer.Argument(..., help="Input: .wsrec recording or labelled-stream .npz."),
    dst: Path = typer.Argument(..., help="Output: .npz (labelled stream) or .wsrec."),
    overwrite: bool = typer.Option(False, help="Replace an existing output file."),
) -> None:
    """Convert between the native recording format and the labelled-stream format."""
    from wovenskin.recording.inspect import convert_file

    console.print(convert_file(src, dst, overwrite=overwrite))


@app.command("fake-device")
@user_errors
def fake_device(
    seconds: float = typer.Option(None, help="Stop after this long (default: Ctrl-C)."),
    fmt: str = typer.Option("binary", "--format", help="binary (docs/protocol.md) or text."),
    seed: int = typer.Option(0, help="Seed of the simulated person."),
) -> None:
    """Run a simulated skin device on a pseudo-terminal, to test a setup without hardware."""
    from wovenskin.skin.fake_device import run_fake_device

    run_fake_device(seconds=seconds, fmt=fmt, seed=seed, console=console)


MODEL_HELP = "Checkpoint directory with model.onnx (default: the shipped model)."


def _pipeline_settings(recognizer, every: int, dwell_ms: float, min_probability: float | None):
    """Pipeline settings: the options given, else the model's recommendation, else defaults."""
    from wovenskin.recognition.pipeline import PipelineSettings, arbiter_settings_for_model

    arbiter = arbiter_settings_for_model(
        recognizer, dwell_s=dwell_ms / 1000, min_probability=min_probability
    )
    return PipelineSettings(every=every, arbiter=arbiter)


def _warn(message: str) -> None:
    err_console.print(f"[yellow]warning:[/] {escape(message)}", soft_wrap=True, highlight=False)


@app.command()
@user_errors
def replay(
    stream: Path = typer.Argument(..., help="Labelled-stream .npz (or native .wsrec)."),
    model: Path = typer.Option(None, help=MODEL_HELP),
    every: int = typer.Option(1, help="Run the model on every K-th frame's window."),
    dwell_ms: float = typer.Option(100.0, help="Dwell time before a gesture acts."),
    min_probability: float = typer.Option(
        None, help="Least class probability that counts (default: the model's recommendation)."
    ),
    threads: int = typer.Option(1, help="ONNX Runtime threads for the model."),
    json_out: bool = typer.Option(False, "--json", help="Print only the command log (JSON lines)."),
) -> None:
    """Run calibration, conditioning, recogniser and arbiter on a stream; print the commands."""
    from wovenskin.recognition.commandlog import commands_table, format_command_log
    from wovenskin.recognition.pipeline import load_recognizer, load_stream, run_pipeline
    from wovenskin.recording.files import unknown_labels, unknown_labels_message

    labelled = load_stream(stream)
    unknown = unknown_labels(labelled.event_labels)
    if unknown:  # replay only prints commands; eval-stream refuses to score such a stream
        _warn(unknown_labels_message(str(stream), unknown))
    recognizer = load_recognizer(model, threads=threads)
    settings = _pipeline_settings(recognizer, every, dwell_ms, min_probability)
    result = run_pipeline(labelled, recognizer, settings, on_warning=_warn)
    if json_out:
        print(format_command_log(result.commands), end="", flush=True)
    else:
        console.print(commands_table(result.commands))
    err_console.print(
        f"{len(result.commands)} command changes, {result.duration_s:.1f} s of stream in "
        f"{result.elapsed_s:.2f} s ({result.realtime_factor:.0f}x real time, "
        f"{result.windows_inferred} of {result.windows_predicted} windows classified)",
        highlight=False,
    )


@app.command("eval-stream")
@user_errors
def eval_stream(
    streams: list[Path] = typer.Argument(..., help="Labelled-stream .npz files with events."),
    model: Path = typer.Option(None, help=MODEL_HELP),
    every: int = typer.Option(1, help="Run the model on every K-th frame's window."),
    dwell_ms: float = typer.Option(100.0, help="Dwell time before a gesture acts."),
    min_probability: float = typer.Option(
        None, help="Least class probability that counts (default: the model's recommendation)."
    ),
    threads: int = typer.Option(1, help="ONNX Runtime threads for the model."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Score the pipeline's commands against labelled events: event F1, false activations."""
    import json
    from dataclasses import asdict

    from wovenskin.recognition.event_scoring import (
        aggregate,
        per_class_table,
        score_stream,
        scores_table,
    )
    from wovenskin.recognition.pipeline import load_recognizer, load_stream, run_pipeline
    from wovenskin.recording.files import unknown_labels, unknown_labels_message

    for path in streams:  # every file checked before minutes of pipeline are spent
        unknown = unknown_labels(load_stream(path).event_labels)
        if unknown:  # no command could match them: scored, they would pass as misses
            raise ValueError(f"{unknown_labels_message(str(path), unknown)}; not scored")
    recognizer = load_recognizer(model, threads=threads)
    settings = _pipeline_settings(recognizer, every, dwell_ms, min_probability)
    rows, details = [], []
    for path in streams:
        labelled = load_stream(path)
        if len(labelled.event_labels) == 0:
            _warn(f"{path} has no labelled events")
        with err_console.status(f"running the pipeline on {path}..."):
            result = run_pipeline(labelled, recognizer, settings, on_warning=_warn)
        scores = score_stream(result.commands, labelled)
        rows.append((path.name, scores))
        details.append(
            {"path": str(path), "realtime_factor": result.realtime_factor, **scores.to_dict()}
        )
    total = aggregate(s for _, s in rows)
    if json_out:
        document = {
            "model": str(recognizer.checkpoint_dir.resolve()),
            "settings": {"every": every, **asdict(settings.arbiter)},
            "streams": details,
            "total": total.to_dict(),
        }
        print(json.dumps(document))
    else:
        console.print(scores_table(rows, total))
        console.print(per_class_table(total))


def _show_bench(result, json_out: bool) -> None:
    """A benchmark's figures: one JSON object, or its Rich table."""
    if json_out:
        import json

        print(json.dumps(result.to_dict()))
    else:
        console.print(result.table())


@bench_app.command("io")
@user_errors
def bench_io(
    frames: int = typer.Option(20000, help="Frames to push through each stage."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Decode and conditioning throughput for a 10 x 10 skin on one core."""

    from wovenskin.bench.io import run_io_benchmark

    result = run_io_benchmark(n_frames=frames)
    _show_bench(result, json_out)


@bench_app.command("serial")
@user_errors
def bench_serial(
    stalls: int = typer.Option(10, help="Device stalls to time."),
    stall_ms: float = typer.Option(30.0, help="The reader's stall threshold."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Serial reader over a real pseudo-terminal: frames, errors, stall-report delay."""

    from wovenskin.bench.serial import run_serial_benchmark

    result = run_serial_benchmark(stalls, stall_ms)
    _show_bench(result, json_out)


@bench_app.command("sim")
@user_errors
def bench_sim(
    seconds: float = typer.Option(60.0, help="Length of the simulated stream to time."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """How many times faster than real time the simulated skin renders, on one core."""

    from wovenskin.bench.sim import run_sim_benchmark

    result = run_sim_benchmark(seconds)
    _show_bench(result, json_out)


@bench_app.command("detection")
@user_errors
def bench_detection(
    seeds: int = typer.Option(20, help="Simulated skins/people (seeds 0..N-1)."),
    seconds: float = typer.Option(60.0, help="Length of each simulated stream."),
) -> None:
    """Contact detection against the simulator's ground truth: phantoms, misses, release."""
    from wovenskin.bench.detection import run_detection_benchmark

    with console.status(f"conditioning {seeds} simulated streams of {seconds:g} s..."):
        report = run_detection_benchmark(range(seeds), seconds)
    for line in report.lines():
        console.print(line, highlight=False, soft_wrap=True)
    for seed, label, frac, snr in report.weak_events():
        console.print(f"weak event: seed {seed} {label} touched {frac:.2f} peak {snr:.0f} x noise")


# ----------------------------------------------------------------- recognition: data, models

TORCH_HINT = "pip install 'wovenskin[train]'"
SPLIT_HELP = "grouped (recordings, people and skins never seen in training) or random (85/15)."


def _require_torch(command: str) -> None:
    """Refuse a training command in one line when PyTorch is not installed."""
    import importlib.util

    if importlib.util.find_spec("torch") is None:
        raise ValueError(f"{command} needs PyTorch, which is not installed: {TORCH_HINT}")


def _json_object(text: str, option: str) -> dict:
    """Parse an option holding a JSON object ('' gives an empty one)."""
    import json

    if not text.strip():
        return {}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{option} is not valid JSON: {exc.msg} at column {exc.colno}") from None
    if not isinstance(value, dict):
        raise ValueError(f"{option} must be a JSON object, e.g. '{{\"n_layers\": 2}}'")
    return value


def _open_or_build_dataset(data: Path | None, ui: Console):
    """The data set at ``data``, or the default one (generated with a progress bar if missing)."""
    from wovenskin.training.compare import DEFAULT_DATASET_DIR, dataset_progress, ensure_dataset
    from wovenskin.training.report import DatasetSummary

    if data is not None or (DEFAULT_DATASET_DIR / "meta.json").is_file():
        return ensure_dataset(data)[0]
    ui.print(f"no data set given: building the default one in {DEFAULT_DATASET_DIR} (once)")
    bar, update = dataset_progress(ui, "simulating recordings")
    with bar:
        ds, _ = ensure_dataset(None, progress=update)
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
def dataset(
    out: Path = typer.Option(..., help="Directory of the window data set to write."),
    streams: list[Path] = typer.Option(
        None,
        help="Labelled streams (.npz) or recordings (.wsrec) to window instead of "
        "simulating: --streams A.npz B.npz ...",
    ),
    more_streams: list[Path] = typer.Argument(None, help="More streams (after --streams)."),
    recordings: int = typer.Option(140, help="Simulated recordings, each a new person and skin."),
    windows: int = typer.Option(1000, help="Gesture windows per recording."),
    invalid_windows: int = typer.Option(400, help="Windows of the invalid class per recording."),
    seconds: float = typer.Option(120.0, help="Length of each simulated recording."),
    recipe: str = typer.Option(
        "stream",
        help="stream: windows at every position, labelled by what they show; "
        "overlay: the paper's augmentation (gesture slices on background noise).",
    ),
    seed: int = typer.Option(0, help="Random seed: the same seed gives the same files."),
    workers: int = typer.Option(2, help="Worker processes."),
    dtype: str = typer.Option("float16", help="Storage of the windows: float16 or float32."),
    overwrite: bool = typer.Option(False, help="Replace an existing data set."),
) -> None:
    """Build a window data set from simulation or labelled streams."""
    from wovenskin.training.compare import dataset_progress
    from wovenskin.training.datasets import build_dataset_from_streams, generate_sim_dataset
    from wovenskin.training.report import DatasetSummary
    from wovenskin.training.windows import WindowSettings

    settings = WindowSettings(recipe=recipe)

    files = [*(streams or []), *(more_streams or [])]
    bar, update = dataset_progress(console, "windowing streams" if files else "simulating")
    with bar:
        if files:
            ds = build_dataset_from_streams(
                out, files, windows, invalid_windows, seed=seed, workers=workers,
                progress=update, dtype=dtype, overwrite=overwrite, settings=settings,
            )  # fmt: skip
        else:
            ds = generate_sim_dataset(
                out, recordings, windows, invalid_windows, seconds, seed=seed, workers=workers,
                progress=update, dtype=dtype, overwrite=overwrite, settings=settings,
            )  # fmt: skip
    summary = DatasetSummary.of(ds)
    console.print(summary.table(ds.class_names))
    console.print(summary.describe(), highlight=False, soft_wrap=True)


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
    epochs: int = typer.Option(None, help="Most epochs (default 3); may stop sooner."),
    batch_size: int = typer.Option(64, help="Windows per training step."),
    lr: float = typer.Option(3e-3, help="Peak learning rate (AdamW, warm-up, cosine decay)."),
    seed: int = typer.Option(0, help="Seed of initialisation, batch order and augmentation."),
    patience: int = typer.Option(5, help="Epochs without a better validation score to stop."),
    split_seed: int = typer.Option(0, help="Seed of the train/validation split."),
    hparams: str = typer.Option("", help="Model hyperparameters (JSON): '{\"n_layers\": 2}'."),
    resume: bool = typer.Option(False, help="Continue an interrupted run in the same --out."),
    time_budget: float = typer.Option(None, help="Minutes; no epoch starts that would overrun."),
    threads: int = typer.Option(
        1, help="Torch threads (one is fastest on a busy 2-core machine: measure)."
    ),
    overwrite: bool = typer.Option(False, help="Replace a trained model already in --out."),
) -> None:
    """Train a gesture classifier (PyTorch) with early stopping, checkpoints and resume."""
    _require_torch("wovenskin train")
    from wovenskin.training.compare import (
        DEFAULT_EPOCHS,
        RUNS_DIR,
        TrainOptions,
        TrainProgressDisplay,
        default_train_dir,
        train_on_dataset,
    )

    if captures is not None:
        if data is not None:
            raise ValueError("give --data or --captures, not both")
        out = out or RUNS_DIR / "models" / f"captures-{captures.stem}"
        _check_checkpoint_dir(out, overwrite, resume)
        _train_on_captures(captures, out, model, epochs, seed, threads, resume)
        return
    model = model or "transformer"
    out = out or default_train_dir(model, split)
    _check_checkpoint_dir(out, overwrite, resume)
    parameters = _json_object(hparams, "--hparams")
    ds = _open_or_build_dataset(data, console)
    options = TrainOptions(
        epochs=DEFAULT_EPOCHS if epochs is None else epochs, batch_size=batch_size, lr=lr,
        seed=seed, patience=patience, split_seed=split_seed, resume=resume,
        time_budget_s=None if time_budget is None else 60 * time_budget, threads=threads,
    )  # fmt: skip
    console.print(
        f"training {model} on {ds.path} ({split} split) into {out}", highlight=False, soft_wrap=True
    )
    try:
        with TrainProgressDisplay(console) as show:
            result = train_on_dataset(ds, out, model, split, options, parameters, show)
    except KeyboardInterrupt:
        raise _interrupted(out) from None
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


CHECKPOINT_FILES = ("model.pt", "model.onnx", "meta.json", "training_state.pt")


def _check_comparison_dir(out: Path, overwrite: bool, resume: bool) -> None:
    """Refuse to compare into ``out`` when it holds a comparison or a trained model (in
    ``out/<split>/<model>/``) unless resuming it or ``overwrite``."""
    from wovenskin.outputs import OutputExistsError
    from wovenskin.training.compare import COMPARE_FILE

    if resume or overwrite or not out.is_dir():
        return
    found = (out / COMPARE_FILE).exists() or any(
        (checkpoint / name).exists()
        for checkpoint in out.glob("*/*")
        for name in CHECKPOINT_FILES
    )
    if found:
        raise OutputExistsError(out, "a comparison (--resume continues it)")


def _check_checkpoint_dir(out: Path, overwrite: bool, resume: bool) -> None:
    """Refuse to train over a model already in ``out`` unless resuming it or ``overwrite``."""
    from wovenskin.outputs import OutputExistsError

    if resume or overwrite or not out.is_dir():
        return
    if any((out / name).exists() for name in CHECKPOINT_FILES):
        raise OutputExistsError(out, "a trained model (--resume continues it)")


def _train_on_captures(
    path: Path, out: Path | None, model: str | None, epochs: int | None, seed: int,
    threads: int, resume: bool,
) -> None:  # fmt: skip
    from wovenskin.training.captures import train_on_captures
    from wovenskin.training.compare import RUNS_DIR, TrainProgressDisplay

    out = out or RUNS_DIR / "models" / f"captures-{path.stem}"
    console.print(
        f"training on labelled captures {path} into {out}", highlight=False, soft_wrap=True
    )
    try:
        with TrainProgressDisplay(console) as show:
            result = train_on_captures(
                path, out, model=model, epochs=epochs, seed=seed, threads=threads,
                progress=show, resume=resume,
            )  # fmt: skip
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
    from rich.table import Table

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
    model: Path = typer.Option(
        None, help="Checkpoint directory with model.onnx (default: the shipped model)."
    ),
    data: Path = typer.Option(
        None,
        help="Window data set (default: the one the model was trained on, else "
        "runs/datasets/sim-default).",
    ),
    split: str = typer.Option(
        None, help="grouped, random or all (default: the split the model was trained on)."
    ),
    split_seed: int = typer.Option(None, help="Seed of the split (default: the training one)."),
    out: Path = typer.Option(None, help="Report directory (default: MODEL/eval-SPLIT)."),
    captures: Path = typer.Option(None, help="Score on labelled captures (.npz) instead."),
    lopo: bool = typer.Option(
        False, help="With --captures: leave-one-participant-out training and scoring."
    ),
    arch: str = typer.Option(None, help="With --lopo: the model to train in every fold."),
    epochs: int = typer.Option(None, help="With --lopo: most epochs per fold."),
    threads: int = typer.Option(1, help="ONNX Runtime threads (--lopo: torch threads)."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object, nothing else."),
) -> None:
    """Score a model with ONNX Runtime: accuracy, macro-F1, per-class table, confusion matrix."""
    import json

    from wovenskin.recognition.shipped import DEFAULT_MODEL_DIR, resolve_model_dir

    if captures is not None:
        _eval_captures(captures, model, out, lopo, arch, epochs, threads, json_out)
        return
    if lopo:
        raise ValueError("--lopo needs --captures FILE")
    from rich.progress import Progress

    from wovenskin.training.checkpoint import read_meta
    from wovenskin.training.compare import DEFAULT_DATASET_DIR, RUNS_DIR
    from wovenskin.training.report import evaluate_on_dataset, per_class_table, write_report

    model_dir = resolve_model_dir(model)
    if data is None:
        trained_on = read_meta(model_dir).training_data.get("dataset") or {}
        recorded = trained_on.get("path") if isinstance(trained_on, dict) else None
        if recorded and Path(recorded).is_dir():
            data = Path(recorded)
        elif (DEFAULT_DATASET_DIR / "meta.json").is_file():
            data = DEFAULT_DATASET_DIR
        else:
            raise ValueError("no data set to score on: pass --data DIR (see wovenskin dataset)")
    with Progress(console=err_console, transient=True, disable=not err_console.is_terminal) as bar:
        task = bar.add_task("classifying windows", total=None)
        report = evaluate_on_dataset(
            model_dir, data, split, split_seed, threads,
            lambda done, total: bar.update(task, completed=done, total=total),
        )  # fmt: skip
    if out is None:
        shipped = model_dir.resolve() == DEFAULT_MODEL_DIR.resolve()
        base = RUNS_DIR / "eval" / "shipped" if shipped else model_dir
        out = base / f"eval-{report.split}"
    files = write_report(report, out)
    for warning in report.warnings:
        _warn(warning)
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
    epochs: int | None, threads: int, json_out: bool,
) -> None:  # fmt: skip
    import json

    from wovenskin.training import captures as captures_module

    if lopo:
        _require_torch("wovenskin eval --lopo")
        from wovenskin.training.compare import RUNS_DIR, TrainProgressDisplay

        if model is not None:
            raise ValueError("--lopo trains its own models: name the architecture with --arch")
        out = out or RUNS_DIR / "lopo" / path.stem
        options = {k: v for k, v in (("model", arch), ("epochs", epochs)) if v is not None}
        with TrainProgressDisplay(err_console) as show:
            result = captures_module.leave_one_participant_out(
                path, out, threads=threads, progress=show, **options
            )
        title = f"leave-one-participant-out on {path}"
    else:
        from wovenskin.recognition.shipped import resolve_model_dir

        with err_console.status(f"scoring {path}..."):
            result = captures_module.evaluate_captures(path, resolve_model_dir(model))
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
    models: str = typer.Option("transformer,bilstm,tcn", help="Comma-separated models."),
    split: str = typer.Option("grouped", help="grouped, random or both: grouped,random."),
    epochs: int = typer.Option(None, help="Most epochs per model (default 3); may stop sooner."),
    batch_size: int = typer.Option(64, help="Windows per training step."),
    lr: float = typer.Option(3e-3, help="Peak learning rate."),
    seed: int = typer.Option(0, help="Training seed (the same for every model)."),
    patience: int = typer.Option(5, help="Early-stopping patience in epochs."),
    split_seed: int = typer.Option(0, help="Seed of the train/validation split."),
    hparams: str = typer.Option(
        "", help='Hyperparameters per model, JSON: \'{"bilstm": {"hidden": 64}}\'.'
    ),
    resume: bool = typer.Option(False, help="Continue interrupted runs in --out."),
    overwrite: bool = typer.Option(False, help="Replace a comparison already in --out."),
    time_budget: float = typer.Option(None, help="Minutes per model and split."),
    threads: int = typer.Option(
        1, help="Torch threads for training (one is fastest on a busy 2-core machine)."
    ),
    latency_repeats: int = typer.Option(300, help="Timed batch-1 calls per model."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object, nothing else."),
) -> None:
    """Train and score several models on the same data and split: the side-by-side table."""
    import json

    _require_torch("wovenskin compare")
    from wovenskin.training.compare import (
        DEFAULT_EPOCHS,
        TrainOptions,
        TrainProgressDisplay,
        compare_models,
    )

    epochs = DEFAULT_EPOCHS if epochs is None else epochs
    names = [m.strip() for m in models.split(",") if m.strip()]
    splits = [s.strip() for s in split.split(",") if s.strip()]
    parameters = _json_object(hparams, "--hparams")
    if any(not isinstance(v, dict) for v in parameters.values()):
        raise ValueError("--hparams must map model names to JSON objects")
    ui = err_console if json_out else console
    targets = [out] if len(data or [None]) == 1 else [out / Path(str(d)).name for d in data]
    for target in targets:  # refused before any data set is built or model trained
        _check_comparison_dir(target, overwrite, resume)
    datasets = [_open_or_build_dataset(d, ui) for d in (data or [None])]
    options = TrainOptions(
        epochs=epochs, batch_size=batch_size, lr=lr, seed=seed, patience=patience,
        split_seed=split_seed, resume=resume,
        time_budget_s=None if time_budget is None else 60 * time_budget, threads=threads,
    )  # fmt: skip

    def reported(model: str, split_name: str, report) -> None:
        ui.print(f"{model} / {split_name}: {report.summary()}", highlight=False, soft_wrap=True)

    comparisons = []
    for ds in datasets:
        target = out if len(datasets) == 1 else out / Path(str(ds.path)).name
        try:
            with TrainProgressDisplay(ui) as show:
                comparisons.append(
                    compare_models(
                        ds, target, names, splits, options, parameters, latency_repeats, show,
                        reported, streams=list(streams or []),
                    )  # fmt: skip
                )
        except KeyboardInterrupt:
            raise _interrupted(target) from None
    if json_out:
        documents = [c.to_dict() for c in comparisons]
        print(json.dumps(documents[0] if len(documents) == 1 else {"comparisons": documents}))
    else:
        for comparison in comparisons:
            console.print(comparison.table())
        console.print(f"written: compare.json in {out} (per data set) and an eval report per model")


@bench_app.command("recognition")
@user_errors
def bench_recognition(
    model: Path = typer.Option(None, help=MODEL_HELP),
    streams_per_condition: int = typer.Option(3, help="Unseen simulated streams per condition."),
    seconds: float = typer.Option(60.0, help="Length of each simulated stream."),
    seed: int = typer.Option(
        9000, help="Base seed; each stream's seed derives from it, the condition and the stream."
    ),
    conditions: str = typer.Option(
        None, help="Comma-separated subset of the conditions (default: all of them)."
    ),
    min_probability: float = typer.Option(
        None, help="Least class probability that counts (default: the model's recommendation)."
    ),
    threads: int = typer.Option(1, help="ONNX Runtime threads for the model."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """The live pipeline on unseen simulated streams by condition: F1, false alarms, latency."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from wovenskin.bench.recognition import condition_names, run_recognition_benchmark
    from wovenskin.recognition.pipeline import load_recognizer

    names = condition_names(conditions)
    recognizer = load_recognizer(model, threads=threads)
    settings = _pipeline_settings(recognizer, 1, 100.0, min_probability)
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=err_console,
    )
    task = bar.add_task("bench recognition", total=len(names) * streams_per_condition)

    def update(done: int, total: int, what: str) -> None:
        bar.update(task, completed=done, total=total, description=f"bench recognition: {what}")

    with bar:
        result = run_recognition_benchmark(
            recognizer, settings, names, streams_per_condition, seconds, seed, progress=update
        )
    for message in result.warnings:
        _warn(message)
    _show_bench(result, json_out)
    if json_out:
        err_console.print(f"wall time {result.wall_s:.1f} s", highlight=False)


@bench_app.command("model")
@user_errors
def bench_model(
    repeats: int = typer.Option(500, help="Timed batch-1 calls per model and runtime."),
    batch_size: int = typer.Option(256, help="Batch of the throughput figures."),
    shipped: bool = typer.Option(True, help="Also time the shipped default model."),
    seconds: float = typer.Option(1.0, help="Seconds of calls behind each throughput figure."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Per-window latency (batch 1, one thread) and throughput on ONNX Runtime and torch."""

    _require_torch("wovenskin bench model")
    from wovenskin.bench.model import run_model_benchmark

    with err_console.status("benchmarking models...") as status:
        result = run_model_benchmark(
            repeats, batch_size, include_shipped=shipped, throughput_seconds=seconds,
            progress=lambda message: status.update(f"bench model: {message}"),
        )  # fmt: skip
    _show_bench(result, json_out)


# ----------------------------------------------------------------------- robot control

ROBOT_HELP = (
    "Robot: sim (the simulated TM5-900), tm:HOST[:PORT][?listen_port=N&state_port=N] "
    "(Techman, docs/techman.md) or ur:HOST[?model=ur5e] (UR: ur3e, ur5e, ur10e, ur16e); "
    "any kind takes ?safety=degraded to accept an arm without kinematics (docs/safety.md)."
)
pose_app = typer.Typer(help="Named robot poses: the task's initial pose and home.")
app.add_typer(pose_app, name="pose")


def robot_errors(fn):
    """Robot errors (one line) end like user errors: a red line and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from wovenskin.robots.base import RobotError

        try:
            return fn(*args, **kwargs)
        except RobotError as exc:
            raise ValueError(f"robot: {exc}") from None

    return wrapper


@app.command()
@user_errors
@robot_errors
def run(
    skin: str = typer.Option(
        None, help=SKIN_HELP + " Default: sim:auto=0 with the dashboard, else sim."
    ),
    robot: str = typer.Option("sim", help=ROBOT_HELP),
    model: Path = typer.Option(None, help=MODEL_HELP),
    view: str = typer.Option("dashboard", help="dashboard (web page), terminal or none."),
    headless: bool = typer.Option(
        False, help="No view (same as --view none); replays run as fast as possible."
    ),
    host: str = typer.Option("127.0.0.1", help="Dashboard address; not loopback needs a token."),
    port: int = typer.Option(8000, help="Dashboard port."),
    token: str = typer.Option(None, help="Dashboard token (made up when --host is not local)."),
    open_browser: bool = typer.Option(
        True, "--open/--no-open", help="Open the dashboard in the default web browser."
    ),
    ui_rate: float = typer.Option(40.0, help="Dashboard updates per second (30-60)."),
    trace: str = typer.Option(
        None, help="Write a JSON line per control tick to this .jsonl file ('-': stdout)."
    ),
    record: Path = typer.Option(None, help="Record the session (.wsrec): skin, commands, robot."),
    seconds: float = typer.Option(None, help="Stop after this many seconds of skin time."),
    mapping: Path = typer.Option(None, help="Action mapping TOML (default: the packaged one)."),
    poses: Path = typer.Option(None, help="Pose file (default: ~/.config/wovenskin/poses.toml)."),
    overwrite: bool = typer.Option(False, help="Replace existing --trace / --record files."),
) -> None:
    """Drive a robot with gestures: skin, recogniser, mapping, safety and robot in one loop.

    With no options: the live dashboard at http://127.0.0.1:8000 on the simulated skin
    and arm.

    --skin serial:PORT and --robot tm:HOST (or ur:HOST) drive real hardware through the
    same loop.
    """
    from wovenskin.control.session import open_session
    from wovenskin.control.trace import TraceWriter

    if headless:
        view = "none"
    if view not in ("dashboard", "terminal", "none"):
        raise ValueError(f"--view must be dashboard, terminal or none, got {view!r}")
    headless = view == "none"
    if skin is None:
        skin = "sim:auto=0" if view == "dashboard" else "sim"
    to_stdout = trace == "-"
    out = err_console if to_stdout or headless else console
    if trace == "-" and not headless:
        raise ValueError("--trace - (stdout) needs --headless")
    if seconds is not None and not seconds > 0:
        raise ValueError(f"--seconds must be positive, got {seconds}")
    if view == "dashboard":
        _run_dashboard(
            skin, robot, model, host=host, port=port, token=token, open_browser=open_browser,
            ui_rate=ui_rate, trace=trace, record=record, seconds=seconds, mapping=mapping,
            poses=poses, overwrite=overwrite,
        )  # fmt: skip
        return
    writer = TraceWriter(trace, overwrite=overwrite) if trace else None

    def report(message: str) -> None:
        if headless:
            err_console.print(escape(message), highlight=False, soft_wrap=True)

    try:
        session = open_session(
            skin, robot, model, fast_replay=headless, mapping=mapping, poses=poses,
            trace=writer, record=record, overwrite=overwrite, on_message=report,
        )  # fmt: skip
    except BaseException:
        if writer is not None:
            writer.close()
        raise
    try:
        if headless:
            try:
                result = session.run(seconds)
            except KeyboardInterrupt:
                session.request_quit("interrupted (Ctrl-C)")
                result = session.result()
        else:
            from wovenskin.ui.run_view import run_with_view

            result = run_with_view(session, console, seconds, title=f"wovenskin run  {robot}")
    finally:
        session.close()
    out.print(result.summary(), highlight=False, soft_wrap=True)
    if writer is not None and writer.path is not None:
        out.print(f"trace: {writer.lines} lines in {writer.path}", highlight=False)
    if record is not None:
        out.print(f"recording: {record}", highlight=False)


def _has_desktop() -> bool:
    """Whether a graphical browser can open: without a desktop, Python's ``webbrowser``
    would start a text browser (lynx, w3m) in this terminal and take it over."""
    import os
    import sys

    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _run_dashboard(
    skin: str, robot: str, model: Path | None, *, host: str, port: int, token: str | None,
    open_browser: bool, ui_rate: float, trace: str | None, record: Path | None,
    seconds: float | None, mapping: Path | None, poses: Path | None, overwrite: bool,
) -> None:  # fmt: skip
    """``wovenskin run`` with the web dashboard (see :mod:`wovenskin.ui.dashboard`)."""
    import socket
    import webbrowser

    from wovenskin.control.session import open_session
    from wovenskin.control.trace import TraceWriter
    from wovenskin.ui.dashboard.runner import DashboardRunner
    from wovenskin.ui.dashboard.server import needs_token, new_token, other_device_urls, serve

    if not 30.0 <= ui_rate <= 60.0:
        raise ValueError(f"--ui-rate must be 30-60 updates per second, got {ui_rate}")
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn does
        try:
            probe.bind((host, port))
        except OSError as exc:
            why = f"cannot listen on {host}:{port} ({exc.strerror})"
            raise ValueError(f"{why}: choose another with --port") from None
    if needs_token(host) and token is None:
        token = new_token()
    first = {"record": record, "trace": TraceWriter(trace, overwrite=overwrite) if trace else None}

    def opener(skin_spec: str, robot_spec: str):
        # The recording and trace given on the command line belong to the first session.
        recording, writer = first.pop("record", None), first.pop("trace", None)
        return open_session(
            skin_spec, robot_spec, model, mapping=mapping, poses=poses, trace=writer,
            record=recording, overwrite=overwrite,
        )  # fmt: skip

    runner = DashboardRunner(opener, skin, robot, ui_rate_hz=ui_rate)

    def ready(url: str) -> None:
        console.print(f"wovenskin dashboard: [bold]{url}[/bold]  (Ctrl-C quits)")
        for other in other_device_urls(url, host):  # --host 0.0.0.0: a tablet on the network
            console.print(f"  from another device: [bold]{other}[/bold]", highlight=False)
        console.print(f"skin {runner.skin_spec}, robot {runner.robot_spec}", highlight=False)
        if open_browser and _has_desktop():
            webbrowser.open(url)

    serve(runner, host, port, token if needs_token(host) else token, on_ready=ready,
          seconds=seconds)  # fmt: skip
    console.print("dashboard closed; the robot was stopped and disconnected", highlight=False)


@pose_app.command("set")
@user_errors
@robot_errors
def pose_set(
    name: str = typer.Argument(..., help="initial or home."),
    robot: str = typer.Option("sim", help=ROBOT_HELP),
    poses: Path = typer.Option(None, help="Pose file (default: ~/.config/wovenskin/poses.toml)."),
) -> None:
    """Store the robot's current pose under NAME (initial: the task's initial pose)."""
    from wovenskin.control.poses import PoseStore, set_pose_from_robot
    from wovenskin.robots.registry import make_robot

    store = PoseStore.load(poses)
    backend = make_robot(robot)
    backend.connect()
    try:
        pose = set_pose_from_robot(store, name, backend)
    finally:
        backend.disconnect()
    console.print(f"stored {name}: {_pose_line(pose.q, pose.tcp)}", highlight=False)
    console.print(f"in {store.path}", highlight=False)


@pose_app.command("show")
@user_errors
def pose_show(
    poses: Path = typer.Option(None, help="Pose file (default: ~/.config/wovenskin/poses.toml)."),
) -> None:
    """Show the stored poses and, where none is stored, the simulated arm's built-in ones."""
    from wovenskin.control.poses import PoseStore

    store = PoseStore.load(poses)
    for name in store.names:
        pose = store.get(name)
        console.print(f"{name}: {_pose_line(pose.q, pose.tcp)}", highlight=False)
    if store.names:
        console.print(f"stored in {store.path}", highlight=False)
    else:
        console.print(f"no poses stored in {store.path}", highlight=False)
    missing = [name for name in ("home", "initial") if name not in store.names]
    if missing:
        console.print(
            "built-in poses of the simulated TM5-900 (--robot sim), used by Go home / Go to "
            "initial and the 5-finger pinches while none is stored (wovenskin/robots/sim/"
            "tm5_900.py: HOME_Q, INITIAL_Q; a real arm needs `wovenskin pose set NAME`):",
            highlight=False,
        )
        for name, (q, tcp) in _builtin_poses(missing).items():
            console.print(f"  {name}: {_pose_line(q, tcp)}", highlight=False)


def _builtin_poses(names: list[str]) -> dict:
    """``{name: (q, tcp Pose)}`` of the simulated TM5-900's built-in home/initial poses."""
    from scipy.spatial.transform import Rotation

    from wovenskin.robots.base import Pose
    from wovenskin.robots.sim import tm5_900

    out = {}
    for name in names:
        q = tm5_900.HOME_Q if name == "home" else tm5_900.INITIAL_Q
        transform = tm5_900.forward_kinematics(q)
        x, y, z, w = Rotation.from_matrix(transform[:3, :3]).as_quat()
        out[name] = (q, Pose(transform[:3, 3], [w, x, y, z]))
    return out


def _pose_line(q, tcp) -> str:
    import numpy as np

    joints = ", ".join(f"{v:.1f}" for v in np.degrees(np.asarray(q, dtype=float)))
    x, y, z = 1000 * np.asarray(tcp.position, dtype=float)
    w, qx, qy, qz = tcp.quat
    return (
        f"joints [{joints}] deg; TCP x {x:.1f} y {y:.1f} z {z:.1f} mm, "
        f"quat [{w:.4f}, {qx:.4f}, {qy:.4f}, {qz:.4f}]"
    )


@bench_app.command("control")
@user_errors
def bench_control(
    model: Path = typer.Option(None, help=MODEL_HELP),
    loop_seconds: float = typer.Option(5.0, help="Seconds of the real-time control loop."),
    streams: int = typer.Option(2, help="Simulated streams behind the latency figures."),
    stream_seconds: float = typer.Option(40.0, help="Length of each simulated stream."),
    ik_steps: int = typer.Option(1000, help="Timed IK steps."),
    stops: bool = typer.Option(
        True, "--stops/--no-stops", help="Measure stop times after release, STOP and watchdog."
    ),
    stop_robot: str = typer.Option(
        "sim",
        help="The arm behind the stop times: 'sim' (simulated clock) or 'techman-fake' (the "
        "Techman client against the fake Techman controller, real time, ~3 min).",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """IK step time, control-loop rate and jitter, first contact to first motion, stop
    times. ``--loop-seconds 0 --streams 0`` measures only the IK and the stops."""

    from wovenskin.bench.control import run_control_benchmark

    with err_console.status("benchmarking the control loop..."):
        result = run_control_benchmark(
            model, loop_seconds, streams, stream_seconds, ik_steps, stops=stops,
            stop_robot=stop_robot,
        )  # fmt: skip
    _show_bench(result, json_out)


@bench_app.command("safety")
@user_errors
def bench_safety(
    episodes: int = typer.Option(40, help="Episodes of random twists (6 commands each)."),
    seed: int = typer.Option(0, help="Seed of the random postures and twists."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """The safety layer's adversarial probe on the simulated arm: joint-margin clearance
    at 30-148 deg/s, measured speeds over the caps, the box and the margins under random
    twists (simulated clock: the figures do not depend on the machine's load)."""
    from wovenskin.bench.safety import run_safety_benchmark

    with err_console.status("probing the safety layer..."):
        result = run_safety_benchmark(episodes, seed)
    _show_bench(result, json_out)


@bench_app.command("dashboard")
@user_errors
def bench_dashboard(
    model: Path = typer.Option(None, help=MODEL_HELP),
    idle_seconds: float = typer.Option(5.0, help="Seconds of page states counted while idle."),
    swipes: int = typer.Option(6, help="Swipes sent over the socket (alternately up and down)."),
    ui_rate: float = typer.Option(40.0, help="Page updates per second asked of the server."),
    rounds: int = typer.Option(
        2, help="Rounds of the 14 gestures drawn as on a touch screen (0: none)."
    ),
    seed: int = typer.Option(0, help="Seed of the simulated people who draw the gestures."),
    mouse_rounds: int = typer.Option(
        2,
        help="Rounds of the gestures a mouse draws (swipes 40-90 mm at 70-250 mm/s, circles, "
        "push), each densely and sparsely sampled (0: none).",
    ),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Dashboard page rate, touch -> command -> motion latency, the 14 gestures drawn as
    on a touch screen and the gestures drawn with a mouse (dense and sparse pointer
    samples, success per gesture), all over its WebSocket."""

    from wovenskin.bench.dashboard import run_dashboard_benchmark

    if swipes < 1 or idle_seconds <= 0 or rounds < 0 or mouse_rounds < 0:
        raise ValueError(
            "--swipes must be >= 1, --idle-seconds positive, --rounds and --mouse-rounds >= 0"
        )
    with err_console.status("benchmarking the dashboard..."):
        result = run_dashboard_benchmark(
            model, idle_seconds, swipes, ui_rate, rounds, seed, mouse_rounds=mouse_rounds
        )
    _show_bench(result, json_out)


def main() -> None:
    app()


if __name__ == "__main__":
    main()
