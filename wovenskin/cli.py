"""The ``wovenskin`` command line (Typer + Rich).

Each command is a thin layer over a library function; heavy imports happen inside the
commands so ``wovenskin --help`` stays instant.  Errors a user can cause (a missing file, a
bad option, an unplugged device) end with one red line and exit code 2, never a traceback.
"""

from __future__ import annotations

import functools
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

console = Console()
err_console = Console(stderr=True)

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
    """Turn expected user errors into one red line and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        from wovenskin.recording.formats import FormatError

        try:
            return fn(*args, **kwargs)
        except (FormatError, ValueError, FileNotFoundError, FileExistsError, OSError) as exc:
            message = " ".join(str(exc).split()) or type(exc).__name__
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
) -> None:
    """Show a skin live in the terminal: heatmap, contacts, frame rate, error counters."""
    from wovenskin.ui.view import run_view

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
    out: Path = typer.Option(..., help="Labelled-stream .npz to write (FORMATS.md)."),
    seconds: float = typer.Option(60.0, help="Length of the stream."),
    seed: int = typer.Option(1, help="Random seed: the same seed gives the same file."),
    rows: int = typer.Option(10, help="Skin rows."),
    cols: int = typer.Option(10, help="Skin columns."),
    gestures: str = typer.Option("", help="Comma-separated gestures to draw from (default: all)."),
    invalid_fraction: float = typer.Option(0.25, help="Share of events that are invalid touches."),
) -> None:
    """Write a labelled stream of a simulated person on a simulated skin."""
    from wovenskin.gestures import check_name
    from wovenskin.recording.formats import write_labelled_stream
    from wovenskin.sim.stream import simulate_stream
    from wovenskin.skin.layout import SkinLayout

    names = [check_name(g.strip()) for g in gestures.split(",") if g.strip()] or None
    stream = simulate_stream(
        seconds,
        seed,
        layout=SkinLayout(rows, cols),
        gestures=names,
        invalid_fraction=invalid_fraction,
    )
    write_labelled_stream(out, stream)
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
    """Guided recording: prompts each gesture with a countdown and labels every trial."""
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
    console.print(str(summary))


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


@bench_app.command("io")
@user_errors
def bench_io(
    frames: int = typer.Option(20000, help="Frames to push through each stage."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Decode and conditioning throughput for a 10 x 10 skin on one core."""
    import json

    from wovenskin.bench.io import run_io_benchmark

    result = run_io_benchmark(n_frames=frames)
    if json_out:
        print(json.dumps(result.to_dict()))
    else:
        console.print(result.table())


@bench_app.command("serial")
@user_errors
def bench_serial(
    stalls: int = typer.Option(10, help="Device stalls to time."),
    stall_ms: float = typer.Option(30.0, help="The reader's stall threshold."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Serial reader over a real pseudo-terminal: frames, errors, stall-report delay."""
    import json

    from wovenskin.bench.serial import run_serial_benchmark

    result = run_serial_benchmark(stalls, stall_ms)
    if json_out:
        print(json.dumps(result.to_dict()))
    else:
        console.print(result.table())


@bench_app.command("sim")
@user_errors
def bench_sim(
    seconds: float = typer.Option(60.0, help="Length of the simulated stream to time."),
    json_out: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """How many times faster than real time the simulated skin renders, on one core."""
    import json

    from wovenskin.bench.sim import run_sim_benchmark

    result = run_sim_benchmark(seconds)
    if json_out:
        print(json.dumps(result.to_dict()))
    else:
        console.print(result.table())


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


def main() -> None:
    app()


if __name__ == "__main__":
    main()
