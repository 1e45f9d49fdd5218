"""Commands for the skin itself: view, simulate, record, devices, info, convert, fake-device."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.markup import escape

from wovenskin.cli.app import (
    SKIN_HELP,
    app,
    console,
    err_console,
    user_errors,
)


@app.command()
@user_errors
def view(
    skin: str = typer.Option("sim", help=SKIN_HELP),
    seconds: float = typer.Option(
        None, min=0.01, max=604800, help="Stop after this many seconds (default: Ctrl-C)."
    ),
    fps: float = typer.Option(
        None, min=1.0, max=240.0, help="Display updates per second (default 25)."
    ),
    full_scale: float = typer.Option(
        0.0,
        min=0.0,
        max=1000.0,
        help="Relative change shown at full brightness (0: follow the signal).",
    ),
    smoothing_ms: float = typer.Option(
        None, min=0.0, max=5000.0, help="Moving-average length in ms (default 100)."
    ),
    snapshot: Path = typer.Option(None, help="Save the last screen as an SVG file at exit."),
    overwrite: bool = typer.Option(False, help="Replace an existing --snapshot file."),
) -> None:
    """Show a skin live in the terminal: heatmap, contacts, frame rate, error counters."""
    from wovenskin.outputs import check_new_output
    from wovenskin.ui.view import FPS, run_view

    if snapshot is not None:
        check_new_output(snapshot, overwrite)  # refused now, not after the session

    result = run_view(
        skin,
        seconds=seconds,
        fps=FPS if fps is None else fps,
        full_scale=full_scale or None,
        config=_config_for(smoothing_ms),
        console=console,
        snapshot=snapshot,
    )
    console.print(
        f"{result.frames} frames in {result.seconds:.1f} s, "
        f"display {result.display_rate_hz:.1f} updates/s, {result.bad_frames} bad frames"
    )


def _config_for(smoothing_ms: float | None):
    """Conditioning settings, or None (``--smoothing-ms`` not given) for the defaults at the
    source's own sample rate."""
    from wovenskin.signal.config import ConditioningConfig

    if smoothing_ms is None:
        return None
    return ConditioningConfig(smoothing_s=smoothing_ms / 1000)


@app.command()
@user_errors
def simulate(
    out: Path = typer.Option(..., help="Labelled-stream .npz to write (docs/formats.md)."),
    seconds: float = typer.Option(60.0, min=0.1, max=3600, help="Length of the stream."),
    seed: int = typer.Option(
        1, min=0, max=2**32 - 1, help="Random seed: the same seed gives the same file."
    ),
    rows: int = typer.Option(None, min=1, max=64, help="Skin rows (default 10)."),
    cols: int = typer.Option(None, min=1, max=64, help="Skin columns (default 10)."),
    gestures: str = typer.Option("", help="Comma-separated gestures to draw from (default: all)."),
    invalid_fraction: float = typer.Option(
        0.25, min=0.0, max=1.0, help="Share of events that are invalid touches."
    ),
    overwrite: bool = typer.Option(False, help="Replace an existing file."),
) -> None:
    """Write a labelled stream of a simulated person on a simulated skin."""
    from wovenskin.gestures import check_name
    from wovenskin.outputs import check_new_output
    from wovenskin.recording.formats import write_labelled_stream
    from wovenskin.sim.stream import simulate_stream
    from wovenskin.skin.layout import SkinLayout

    names = [check_name(g.strip()) for g in gestures.split(",") if g.strip()] or None
    grid = {key: value for key, value in (("rows", rows), ("cols", cols)) if value is not None}
    layout = SkinLayout(**grid).check_supported(where="--rows/--cols")
    check_new_output(out, overwrite)  # before the simulation, not after it
    stream = simulate_stream(
        seconds,
        seed,
        layout=layout,
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
    trials: int = typer.Option(None, min=1, max=10000, help="Trials per gesture (default 3)."),
    gestures: str = typer.Option(
        "", help="Comma-separated gestures (default: all 14, or every gesture of --mapping)."
    ),
    mapping: Path = typer.Option(
        None,
        help="Mapping file: prompt its [gestures], custom ones (docs/custom-gestures.md) too.",
    ),
    invalid_trials: int = typer.Option(
        None, min=0, max=10000, help="Trials of deliberate invalid touches (default 3)."
    ),
    countdown: float = typer.Option(
        None, min=0.0, max=60.0, help="Seconds of countdown before each trial (default 2)."
    ),
    trial_seconds: float = typer.Option(
        None, min=0.5, max=600.0, help="Seconds to perform each trial (default 3)."
    ),
    seed: int = typer.Option(
        None, min=0, max=2**32 - 1, help="Seed of the trial order (default 0)."
    ),
    notes: str = typer.Option("", help="Free notes kept in the recording."),
    overwrite: bool = typer.Option(False, help="Replace an existing file."),
) -> None:
    """Guided recording: prompts each gesture with a countdown and labels every trial.

    With --mapping, the gestures of its [gestures] table are prompted, a custom gesture
    with its description, and labelled with their names.  Ctrl-C ends the session early:
    what was recorded is kept and the exit code is 130.
    """
    from wovenskin.control.mapping import ActionMapping
    from wovenskin.gestures import GESTURE_NAMES, check_name
    from wovenskin.outputs import check_new_output
    from wovenskin.ui.record_session import RecordPlan, run_record_session

    check_new_output(out, overwrite)  # refused now, not after the session
    action_mapping = ActionMapping.load(mapping) if mapping is not None else None
    known = action_mapping.class_names if action_mapping is not None else None
    default = action_mapping.prompted() if action_mapping is not None else list(GESTURE_NAMES)
    names = [check_name(g.strip(), known) for g in gestures.split(",") if g.strip()] or default
    custom = action_mapping.custom if action_mapping is not None else {}
    given = {
        "trials_per_gesture": trials, "invalid_trials": invalid_trials,
        "countdown_s": countdown, "trial_s": trial_seconds, "seed": seed,
    }  # fmt: skip
    plan = RecordPlan(names, **{key: value for key, value in given.items() if value is not None})
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
        custom={name: custom[name] for name in dict.fromkeys(names) if name in custom},
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
def info(
    path: Path = typer.Argument(
        ..., help="A .npz stream/captures, a .wsrec file or a wovenskin ROS 2 bag (.mcap)."
    ),
) -> None:
    """Describe a data file: kind, shape, rate, labels, provenance, problems."""
    from wovenskin.recording.inspect import describe_file

    console.print(describe_file(path))


@app.command()
@user_errors
def convert(
    src: Path = typer.Argument(
        ..., help="Input: .wsrec recording, labelled-stream .npz, or ROS 2 bag (.mcap or dir)."
    ),
    dst: Path = typer.Argument(..., help="Output: .npz (labelled stream), .wsrec or .mcap."),
    overwrite: bool = typer.Option(False, help="Replace an existing output file."),
) -> None:
    """Convert between recordings (.wsrec), labelled streams (.npz) and ROS 2 bags (.mcap).

    .wsrec <-> .mcap is lossless (docs/recording-format.md, "ROS 2 bags"); a bag plays
    with `ros2 bag play` and opens in Foxglove or PlotJuggler."""
    from wovenskin.recording.inspect import convert_file

    console.print(convert_file(src, dst, overwrite=overwrite))


@app.command("fake-device")
@user_errors
def fake_device(
    seconds: float = typer.Option(
        None, min=0.01, max=604800, help="Stop after this long (default: Ctrl-C)."
    ),
    fmt: str = typer.Option("binary", "--format", help="binary (docs/protocol.md) or text."),
    seed: int = typer.Option(0, min=0, max=2**32 - 1, help="Seed of the simulated person."),
) -> None:
    """Run a simulated skin device on a pseudo-terminal, to test a setup without hardware."""
    from wovenskin.sim.fake_device import run_fake_device

    run_fake_device(seconds=seconds, fmt=fmt, seed=seed, console=console)
