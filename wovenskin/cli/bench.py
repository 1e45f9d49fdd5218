"""``wovenskin bench ...``: benchmarks that print measured figures and ratios.

Each command imports its benchmark when it runs: the benchmarks pull in the simulator,
MuJoCo, ONNX Runtime or torch, which every other command would otherwise load at start.
"""

from __future__ import annotations

from pathlib import Path

import typer

from wovenskin.cli.app import (
    JSON_OUT,
    MIN_PROBABILITY,
    MODEL,
    READER,
    THREADS,
    bench_app,
    console,
    counting_bar,
    err_console,
    given,
    pipeline_settings,
    require_torch,
    show_bench,
    user_errors,
    warn,
)
from wovenskin.errors import ConfigError


@bench_app.command("io")
@user_errors
def bench_io(
    frames: int = typer.Option(
        20000, min=1, max=100000000, help="Frames to push through each stage."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Decode and conditioning throughput for a 10 x 10 skin on one core."""

    from wovenskin.bench.io import run_io_benchmark

    result = run_io_benchmark(n_frames=frames)
    show_bench(result, json_out)


@bench_app.command("serial")
@user_errors
def bench_serial(
    stalls: int = typer.Option(10, min=0, max=10000, help="Device stalls to time."),
    stall_ms: float = typer.Option(
        30.0, min=0.0, max=10000.0, help="The reader's stall threshold."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Serial reader over a real pseudo-terminal: frames, errors, stall-report delay."""

    from wovenskin.bench.serial import run_serial_benchmark

    result = run_serial_benchmark(stalls, stall_ms)
    show_bench(result, json_out)


@bench_app.command("sim")
@user_errors
def bench_sim(
    seconds: float = typer.Option(
        60.0, min=0.1, max=3600, help="Length of the simulated stream to time."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """How many times faster than real time the simulated skin renders, on one core."""

    from wovenskin.bench.sim import run_sim_benchmark

    result = run_sim_benchmark(seconds)
    show_bench(result, json_out)


@bench_app.command("live")
@user_errors
def bench_live(
    model: Path = MODEL,
    streams: int = typer.Option(
        None, min=1, max=100000, help="Independent mixed streams to time (default 2)."
    ),
    seconds: float = typer.Option(
        None, min=0.1, max=3600, help="Length of each stream (default 60)."
    ),
    seed: int = typer.Option(
        None, min=0, max=2**32 - 1, help="Seed of the first stream (default 23000)."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """The live path on one core: conditioning, the network, tracking and reading, the
    arbiter, fed as a live skin delivers frames; x real time per reader."""
    from wovenskin.bench.live import run_live_benchmark
    from wovenskin.recognition.pipeline import load_recognizer

    recognizer = load_recognizer(model, threads=1)
    with err_console.status("bench live: timing the live path on one core..."):
        result = run_live_benchmark(
            recognizer, **given(streams=streams, seconds=seconds, seed=seed)
        )
    show_bench(result, json_out)


@bench_app.command("detection")
@user_errors
def bench_detection(
    seeds: int = typer.Option(20, min=1, max=100000, help="Simulated skins/people (seeds 0..N-1)."),
    seconds: float = typer.Option(60.0, min=0.1, max=3600, help="Length of each simulated stream."),
) -> None:
    """Contact detection against the simulator's ground truth: phantoms, misses, release."""
    from wovenskin.bench.detection import run_detection_benchmark

    with console.status(f"conditioning {seeds} simulated streams of {seconds:g} s..."):
        report = run_detection_benchmark(range(seeds), seconds)
    for line in report.lines():
        console.print(line, highlight=False, soft_wrap=True)
    for seed, label, frac, snr in report.weak_events():
        console.print(f"weak event: seed {seed} {label} touched {frac:.2f} peak {snr:.0f} x noise")


@bench_app.command("tracking")
@user_errors
def bench_tracking(
    trials: int = typer.Option(
        None, min=1, max=10000, help="Simulated performances per gesture (default 3)."
    ),
    seed: int = typer.Option(
        None, min=0, max=2**32 - 1, help="Base seed of the trials (default 31000)."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Contact tracks against the simulator's ground-truth fingertips: count, position, identity."""
    from wovenskin.bench.tracking import run_tracking_benchmark

    with err_console.status("bench tracking...") as status:
        result = run_tracking_benchmark(
            progress=lambda what: status.update(f"bench tracking: {what}"),
            **given(trials=trials, seed=seed),  # unset: bench/tracking.py's defaults
        )
    show_bench(result, json_out)


# ----------------------------------------------------------------- recognition: data, models


@bench_app.command("recognition")
@user_errors
def bench_recognition(
    model: Path = MODEL,
    streams_per_condition: int = typer.Option(
        None, min=1, max=100000, help="Unseen simulated streams per condition (default 3)."
    ),
    seconds: float = typer.Option(
        None, min=0.1, max=3600, help="Length of each simulated stream (default 60)."
    ),
    seed: int = typer.Option(
        None,
        min=0,
        max=2**32 - 1,
        help="Base seed; each stream's seed derives from it, the condition and the stream "
        "(default 9000).",
    ),
    conditions: str = typer.Option(
        None, help="Comma-separated subset of the conditions (default: all of them)."
    ),
    min_probability: float = MIN_PROBABILITY,
    reader: str | None = READER,
    threads: int = THREADS,
    json_out: bool = JSON_OUT,
) -> None:
    """The live pipeline on unseen simulated streams by condition: F1, false alarms, latency."""
    from wovenskin.bench.conditions import DEFAULT_SECONDS, condition_names
    from wovenskin.bench.recognition import (
        DEFAULT_BASE_SEED,
        DEFAULT_STREAMS_PER_CONDITION,
        run_recognition_benchmark,
    )
    from wovenskin.recognition.pipeline import load_recognizer

    if streams_per_condition is None:
        streams_per_condition = DEFAULT_STREAMS_PER_CONDITION
    seconds = DEFAULT_SECONDS if seconds is None else seconds
    seed = DEFAULT_BASE_SEED if seed is None else seed
    names = condition_names(conditions)
    recognizer = load_recognizer(model, threads=threads)
    settings = pipeline_settings(recognizer, min_probability=min_probability, reader=reader)
    bar, task = counting_bar(err_console, "bench recognition", len(names) * streams_per_condition)

    def update(done: int, total: int, what: str) -> None:
        bar.update(task, completed=done, total=total, description=f"bench recognition: {what}")

    with bar:
        result = run_recognition_benchmark(
            recognizer, settings, names, streams_per_condition, seconds, seed, progress=update
        )
    for message in result.warnings:
        warn(message)
    show_bench(result, json_out)
    if json_out:
        err_console.print(f"wall time {result.wall_s:.1f} s", highlight=False)


@bench_app.command("gestures")
@user_errors
def bench_gestures(
    model: Path = MODEL,
    streams: int = typer.Option(
        None, min=0, max=100000, help="Mixed independent streams (default 4; 0: none)."
    ),
    seconds: float = typer.Option(
        None, min=0.1, max=3600, help="Length of each mixed stream (default 120)."
    ),
    seed: int = typer.Option(
        None,
        min=0,
        max=2**32 - 1,
        help="Base seed: mixed streams seed, seed+1, ...; flicks seed+1000+k; held "
        "swipes seed+2000+k (default 22000).",
    ),
    flicks: int = typer.Option(
        None, min=0, max=10000, help="Flicks through the simulated arm (default 40; 0: none)."
    ),
    held: int = typer.Option(
        None, min=0, max=10000, help="Held swipes through the simulated arm (default 14; 0: none)."
    ),
    hold: float = typer.Option(
        None, min=0.1, max=600.0, help="Seconds a held swipe's finger stays still (default 2.5)."
    ),
    save_streams: Path = typer.Option(
        None, help="Folder to keep every generated stream in (labelled-stream .npz)."
    ),
    gain_scale: float = typer.Option(
        None,
        min=0.01,
        max=100.0,
        help="The mixed streams' skins respond this many times as strongly as drawn "
        "(0.12: a weak skin, 3: a strong one; default 1).",
    ),
    min_probability: float = MIN_PROBABILITY,
    reader: str | None = READER,
    threads: int = THREADS,
    json_out: bool = JSON_OUT,
) -> None:
    """Recognition and arm motion on independent labelled streams (people and skins made
    apart from the simulator): event F1, false activations, recall per class, latency;
    flicks and held swipes on the simulated TM5-900: moved, travel, brake and rest."""
    from wovenskin.bench.gestures import run_gestures_benchmark
    from wovenskin.outputs import check_writable
    from wovenskin.recognition.pipeline import load_recognizer

    if save_streams is not None:
        check_writable(save_streams, folder=True)  # refused now, not after the streams

    recognizer = load_recognizer(model, threads=threads)
    settings = pipeline_settings(recognizer, min_probability=min_probability, reader=reader)
    with err_console.status("bench gestures...") as status:
        result = run_gestures_benchmark(
            recognizer, settings, progress=lambda what: status.update(f"bench gestures: {what}"),
            save_dir=save_streams, **given(  # unset: bench/gestures.py's defaults
                streams=streams, seconds=seconds, seed=seed, flicks=flicks, held=held, hold_s=hold,
                gain_scale=gain_scale,
            ),
        )  # fmt: skip
    for message in result.warnings:
        warn(message)
    show_bench(result, json_out)
    if json_out:
        err_console.print(f"wall time {result.wall_s:.1f} s", highlight=False)


@bench_app.command("adapt")
@user_errors
def bench_adapt(
    people: int = typer.Option(
        2, min=1, max=1000, help="New people (each with their own skin) to adapt to."
    ),
    weak: bool = typer.Option(True, help="Weak skins: a fifth of a typical skin's change."),
    seconds: float = typer.Option(
        120.0, min=0.1, max=3600, help="Length of each person's recording."
    ),
    tests: int = typer.Option(
        3, min=1, max=1000, help="Further streams of each person to score on."
    ),
    custom: bool = typer.Option(False, help="Add two gestures of the people's own."),
    out: Path = typer.Option(Path("runs/bench/adapt"), help="Folder for recordings and models."),
    base: Path = typer.Option(None, help="Model to adapt (default: the shipped model)."),
    seed: int = typer.Option(
        None,
        min=0,
        max=2**32 - 1,
        help="Person i and their skin are drawn with seed + i (default: the bench's SEED).",
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Adapt to new people and skins made apart from the simulator: their other streams
    scored by the base and the adapted model (F1, false activations, latency), adapt's time."""
    require_torch("wovenskin bench adapt")
    from wovenskin.bench.adapt import run_adapt_benchmark
    from wovenskin.outputs import check_writable

    check_writable(out, folder=True)  # refused now, not after the recordings

    with err_console.status("bench adapt...") as status:
        result = run_adapt_benchmark(
            out, people, weak, seconds, tests, custom=custom, base=base,
            progress=lambda what: status.update(f"bench adapt: {what}"),
            **({} if seed is None else {"seed": seed}),
        )  # fmt: skip
    show_bench(result, json_out)


@bench_app.command("ros2")
@user_errors
def bench_ros2(
    seconds: float = typer.Option(
        30.0, min=0.1, max=3600, help="Length of the simulated stream replayed."
    ),
    out: Path = typer.Option(Path("runs/bench/ros2"), help="Folder for logs and recordings."),
    json_out: bool = JSON_OUT,
) -> None:
    """Replay a labelled stream through run --robot ros2: against a stand-in MoveIt Servo in
    another process (loopback only): every twist on the wire, lift-offs, joint-state loss."""
    from wovenskin.bench.ros2 import run_ros2_benchmark
    from wovenskin.outputs import check_writable

    check_writable(out, folder=True)  # refused now, not after the replay

    with err_console.status("bench ros2...") as status:
        result = run_ros2_benchmark(
            out, seconds, progress=lambda what: status.update(f"bench ros2: {what}")
        )
    show_bench(result, json_out)


@bench_app.command("model")
@user_errors
def bench_model(
    repeats: int = typer.Option(
        500, min=1, max=10000000, help="Timed batch-1 calls per model and runtime."
    ),
    batch_size: int = typer.Option(256, min=1, max=65536, help="Batch of the throughput figures."),
    shipped: bool = typer.Option(True, help="Also time the shipped default model."),
    seconds: float = typer.Option(
        1.0, min=0.1, max=600.0, help="Seconds of calls behind each throughput figure."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Per-window latency (batch 1, one thread) and throughput on ONNX Runtime and torch."""

    require_torch("wovenskin bench model")
    from wovenskin.bench.model import run_model_benchmark

    with err_console.status("benchmarking models...") as status:
        result = run_model_benchmark(
            repeats, batch_size, include_shipped=shipped, throughput_seconds=seconds,
            progress=lambda message: status.update(f"bench model: {message}"),
        )  # fmt: skip
    show_bench(result, json_out)


# ----------------------------------------------------------------------- robot control


@bench_app.command("control")
@user_errors
def bench_control(
    model: Path = MODEL,
    loop_seconds: float = typer.Option(
        5.0, min=0, max=3600, help="Seconds of the real-time control loop (0: none)."
    ),
    streams: int = typer.Option(
        2, min=0, max=100000, help="Simulated streams behind the latency figures (0: none)."
    ),
    stream_seconds: float = typer.Option(
        40.0, min=0.1, max=3600, help="Length of each simulated stream."
    ),
    ik_steps: int = typer.Option(1000, min=1, max=10000000, help="Timed IK steps."),
    stops: bool = typer.Option(
        True, "--stops/--no-stops", help="Measure stop times after release, STOP and watchdog."
    ),
    stop_robot: str = typer.Option(
        "sim",
        help="The arm behind the stop times: 'sim' (simulated clock) or 'techman-fake' (the "
        "Techman client against the fake Techman controller, real time, ~3 min).",
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """IK step time, control-loop rate and jitter, first contact to first motion, stop
    times. ``--loop-seconds 0 --streams 0`` measures only the IK and the stops."""

    from wovenskin.bench.control import run_control_benchmark

    with err_console.status("benchmarking the control loop..."):
        result = run_control_benchmark(
            model, loop_seconds, streams, stream_seconds, ik_steps, stops=stops,
            stop_robot=stop_robot,
        )  # fmt: skip
    show_bench(result, json_out)


@bench_app.command("tasks")
@user_errors
def bench_tasks(
    task: str = typer.Option("pour", help="The task scene: pour or pick_place."),
    seconds: float = typer.Option(
        5.0, min=0.1, max=3600, help="Simulated seconds per measurement."
    ),
    tick: float = typer.Option(0.02, min=0.001, max=1.0, help="Control tick in seconds."),
    seed: int = typer.Option(
        0, min=0, max=2**32 - 1, help="Seed of the scene and the simulated person."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Real-time factor of a study task's physics: alone, with the arm under control, and
    with the recogniser running on a simulated skin beside them (>= 1 keeps up)."""
    from wovenskin.bench.tasks import run_tasks_benchmark

    with err_console.status(f"stepping the {task} scene..."):
        result = run_tasks_benchmark(task, seconds, tick, seed)
    show_bench(result, json_out)


@bench_app.command("safety")
@user_errors
def bench_safety(
    episodes: int = typer.Option(
        40, min=1, max=100000, help="Episodes of random twists (6 commands each)."
    ),
    seed: int = typer.Option(
        0, min=0, max=2**32 - 1, help="Seed of the random postures and twists."
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """The safety layer's adversarial probe on the simulated arm: joint-margin clearance
    at 30-148 deg/s, measured speeds over the caps, the box and the margins under random
    twists (simulated clock: the figures do not depend on the machine's load)."""
    from wovenskin.bench.safety import run_safety_benchmark

    with err_console.status("probing the safety layer..."):
        result = run_safety_benchmark(episodes, seed)
    show_bench(result, json_out)


@bench_app.command("dashboard")
@user_errors
def bench_dashboard(
    model: Path = MODEL,
    idle_seconds: float = typer.Option(
        None, min=0.1, max=3600, help="Seconds of page states counted while idle (default 5)."
    ),
    swipes: int = typer.Option(
        None, min=1, max=10000, help="Swipes over the socket, alternately up and down (default 6)."
    ),
    ui_rate: float = typer.Option(
        None, min=1.0, max=240.0, help="Page updates per second asked of the server (default 40)."
    ),
    rounds: int = typer.Option(
        2, min=0, max=10000, help="Rounds of the 14 gestures drawn as on a touch screen (0: none)."
    ),
    seed: int = typer.Option(
        0, min=0, max=2**32 - 1, help="Seed of the simulated people who draw the gestures."
    ),
    mouse_rounds: int = typer.Option(
        2,
        min=0,
        max=10000,
        help="Rounds of the gestures a mouse draws (swipes 40-90 mm at 70-250 mm/s, circles, "
        "push), each densely and sparsely sampled (0: none).",
    ),
    json_out: bool = JSON_OUT,
) -> None:
    """Dashboard page rate, touch -> command -> motion latency, the 14 gestures drawn as
    on a touch screen and the gestures drawn with a mouse (dense and sparse pointer
    samples, success per gesture), all over its WebSocket."""

    from wovenskin.bench.dashboard import IDLE_SECONDS, SWIPES, run_dashboard_benchmark
    from wovenskin.ui.dashboard.runner import UI_RATE_HZ

    ui_rate = UI_RATE_HZ if ui_rate is None else ui_rate
    idle_seconds = IDLE_SECONDS if idle_seconds is None else idle_seconds
    swipes = SWIPES if swipes is None else swipes
    if swipes < 1 or idle_seconds <= 0 or rounds < 0 or mouse_rounds < 0:
        raise ConfigError(
            "--swipes must be >= 1, --idle-seconds positive, --rounds and --mouse-rounds >= 0"
        )
    with err_console.status("benchmarking the dashboard..."):
        result = run_dashboard_benchmark(
            model, idle_seconds, swipes, ui_rate, rounds, seed, mouse_rounds=mouse_rounds
        )
    show_bench(result, json_out)
