"""Commands that drive a robot: run (terminal or web dashboard) and pose."""

from __future__ import annotations

import sys
from pathlib import Path

import typer
from rich.markup import escape

from wovenskin.cli.app import (
    MODEL,
    POSES,
    ROBOT_HELP,
    SKIN_HELP,
    app,
    console,
    err_console,
    pose_app,
    robot_errors,
    user_errors,
)
from wovenskin.errors import ConfigError


@app.command()
@user_errors
@robot_errors
def run(
    skin: str = typer.Option(
        None,
        help=SKIN_HELP + " none: no skin (keys only). Default: sim:auto=0 with the dashboard, "
        "none with --input keyboard, else sim.",
    ),
    robot: str = typer.Option("sim", help=ROBOT_HELP),
    model: Path = MODEL,
    view: str = typer.Option(
        None,
        help="dashboard (web page; also 'web'), terminal or none. Default: dashboard; "
        "terminal with --input keyboard.",
    ),
    input_kind: str = typer.Option(
        "skin",
        "--input",
        help="skin, keyboard (keys drive the arm: in the terminal view, or on the dashboard's "
        "page) or pendant (the dashboard's jog panel).",
    ),
    study: Path = typer.Option(
        None, help="A study folder (wovenskin study init): the dashboard's study panel runs trials."
    ),
    task: str = typer.Option(
        None, help="Run on a study task's scene: pick_place or pour (simulated arm only)."
    ),
    headless: bool = typer.Option(
        False,
        help="No view (same as --view none); replays run as fast as possible on the "
        "simulated arm (in real time on a real one).",
    ),
    host: str = typer.Option("127.0.0.1", help="Dashboard address; not loopback needs a token."),
    port: int = typer.Option(8000, min=1, max=65535, help="Dashboard port (1-65535)."),
    token: str = typer.Option(None, help="Dashboard token (made up when --host is not local)."),
    open_browser: bool = typer.Option(
        True, "--open/--no-open", help="Open the dashboard in the default web browser."
    ),
    ui_rate: float = typer.Option(
        None, min=1.0, max=240.0, help="Dashboard updates per second, 30-60 (default 40)."
    ),
    trace: str = typer.Option(
        None, help="Write a JSON line per control tick to this .jsonl file ('-': stdout)."
    ),
    record: Path = typer.Option(None, help="Record the session (.wsrec): skin, commands, robot."),
    seconds: float = typer.Option(
        None, min=0.01, max=604800, help="Stop after this many seconds of skin time."
    ),
    mapping: Path = typer.Option(None, help="Action mapping TOML (default: the packaged one)."),
    poses: Path = POSES,
    overwrite: bool = typer.Option(False, help="Replace existing --trace / --record files."),
    ros2_publish: str = typer.Option(
        None,
        help="Publish the skin on ROS 2 (docs/ros2.md): 'on', or rates in Hz and more, e.g. "
        "frames=50,contacts=20,gesture=20,probabilities=0,ns=/wovenskin,domain=0.",
    ),
) -> None:
    """Drive a robot with gestures: skin, recogniser, mapping, safety and robot in one loop.

    With no options: the live dashboard at http://127.0.0.1:8000 on the simulated skin
    and arm.

    --skin serial:PORT and --robot tm:HOST (or ur:HOST) drive real hardware through the
    same loop.
    """
    from wovenskin.control.trace import TraceWriter
    from wovenskin.runtime.session import open_session

    view, skin = _view_and_skin(view, skin, input_kind, headless)
    headless = view == "none"
    to_stdout = trace == "-"
    out = err_console if to_stdout or headless else console
    if trace == "-" and not headless:
        raise ConfigError("--trace - (stdout) needs --headless")
    if seconds is not None and not seconds > 0:
        raise ConfigError(f"--seconds must be positive, got {seconds}")
    topics = _ros2_topics(ros2_publish)
    _check_outputs(trace, record, overwrite)
    if view == "dashboard":
        _run_dashboard(
            skin, robot, model, host=host, port=port, token=token, open_browser=open_browser,
            ui_rate=ui_rate, trace=trace, record=record, seconds=seconds, mapping=mapping,
            poses=poses, overwrite=overwrite, task=task, interface=input_kind, study=study,
            topics=topics,
        )  # fmt: skip
        return
    if study is not None:
        raise ConfigError("--study runs trials from the dashboard's study panel: use --view web")

    def report(message: str) -> None:
        if headless:
            err_console.print(escape(message), highlight=False, soft_wrap=True)

    publisher = _skin_publisher(topics, report)
    writer = TraceWriter(trace, overwrite=overwrite) if trace else None
    try:
        session = open_session(
            skin, robot, model, fast_replay=headless, mapping=mapping, poses=poses,
            trace=writer, record=record, overwrite=overwrite, on_message=report, task=task,
            on_tick=publisher.on_tick if publisher is not None else None,
        )  # fmt: skip
    except BaseException:
        if writer is not None:
            writer.close()
        if publisher is not None:
            publisher.close()
        raise
    from wovenskin.control.session_state import INTERRUPTED

    try:
        if headless:
            try:
                result = session.run(seconds)
            except KeyboardInterrupt:
                session.request_quit(INTERRUPTED)
                result = session.result()
        else:
            from wovenskin.teleop.keyboard import TerminalKeyboard
            from wovenskin.ui.run_view import run_with_view

            if session.task is not None:
                session.task.reset(0)
            keyboard = TerminalKeyboard() if input_kind == "keyboard" else None
            title = f"wovenskin run  {robot}" + (f"  task {task}" if task else "")
            result = run_with_view(session, console, seconds, title=title, keyboard=keyboard)
    finally:
        session.close()
        if publisher is not None:
            publisher.close()
    out.print(result.summary(), highlight=False, soft_wrap=True)
    if publisher is not None:
        out.print(publisher.summary(), highlight=False, soft_wrap=True)
    if writer is not None and writer.path is not None:
        out.print(f"trace: {writer.lines} lines in {writer.path}", highlight=False)
    if record is not None:
        out.print(f"recording: {record}", highlight=False)
    if result.ended == INTERRUPTED:
        raise typer.Exit(130)


INPUTS = ("skin", "keyboard", "pendant")


def _ros2_topics(value: str | None):
    """The ``--ros2-publish`` settings (None: off); a bad value or no ``cyclonedds`` is one
    line, before anything is opened."""
    from wovenskin.runtime.ros2_settings import parse_ros2_publish, require_cyclonedds

    topics = parse_ros2_publish(value)
    if topics is not None:
        require_cyclonedds()
    return topics


def _skin_publisher(topics, report):
    """A :class:`~wovenskin.runtime.ros2_publish.SkinPublisher` for ``topics`` (None: none)."""
    if topics is None:
        return None
    from wovenskin.runtime.ros2_publish import SkinPublisher

    publisher = SkinPublisher(topics, on_message=report)
    report(f"publishing the skin on {topics.describe()}")
    return publisher


def _view_and_skin(
    view: str | None, skin: str | None, input_kind: str, headless: bool
) -> tuple[str, str]:
    """The view and skin spec ``wovenskin run`` uses; a bad combination is one line."""
    if input_kind not in INPUTS:
        raise ConfigError(f"--input must be skin, keyboard or pendant, got {input_kind!r}")
    if headless:
        view = "none"
    view = "dashboard" if view == "web" else view
    if view is None:
        view = "terminal" if input_kind == "keyboard" else "dashboard"
    if view not in ("dashboard", "terminal", "none"):
        raise ConfigError(f"--view must be dashboard, terminal or none, got {view!r}")
    if input_kind == "pendant" and view != "dashboard":
        raise ConfigError(
            "the teach pendant is a panel of the web dashboard: use --view dashboard (--view web)"
        )
    if input_kind == "keyboard" and view == "none":
        raise ConfigError("--input keyboard needs a view to read keys in (terminal or dashboard)")
    if skin is None:
        skin = (
            "none" if input_kind == "keyboard" else ("sim:auto=0" if view == "dashboard" else "sim")
        )
    return view, skin


def _has_desktop() -> bool:
    """Whether a graphical browser can open: without a desktop, Python's ``webbrowser``
    would start a text browser (lynx, w3m) in this terminal and take it over."""
    import os

    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _check_outputs(trace: str | None, record: Path | None, overwrite: bool) -> None:
    """The --trace and --record files can be written: refused now, not when the session opens."""
    from wovenskin.outputs import check_new_output

    for path in (None if trace in (None, "-") else trace, record):
        if path is not None:
            check_new_output(path, overwrite)


def _run_dashboard(
    skin: str, robot: str, model: Path | None, *, host: str, port: int, token: str | None,
    open_browser: bool, ui_rate: float | None, trace: str | None, record: Path | None,
    seconds: float | None, mapping: Path | None, poses: Path | None, overwrite: bool,
    task: str | None = None, interface: str = "skin", study: Path | None = None,
    topics=None,
) -> None:  # fmt: skip
    """``wovenskin run`` with the web dashboard (see :mod:`wovenskin.ui.dashboard`)."""
    import socket
    import webbrowser

    from wovenskin.control.trace import TraceWriter
    from wovenskin.runtime.session import open_session
    from wovenskin.ui.dashboard.runner import UI_RATE_HZ, DashboardRunner
    from wovenskin.ui.dashboard.server import needs_token, new_token, other_device_urls, serve

    ui_rate = UI_RATE_HZ if ui_rate is None else ui_rate
    if not 30.0 <= ui_rate <= 60.0:
        raise ConfigError(f"--ui-rate must be 30-60 updates per second, got {ui_rate}")
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn does
        try:
            probe.bind((host, port))
        except OSError as exc:
            why = f"cannot listen on {host}:{port} ({exc.strerror})"
            raise ConfigError(f"{why}: choose another with --port") from None
    if needs_token(host) and token is None:
        token = new_token()
    first = {"record": record, "trace": TraceWriter(trace, overwrite=overwrite) if trace else None}

    def opener(skin_spec: str, robot_spec: str, task=None, model=model):
        # The recording and trace given on the command line belong to the first session;
        # ``model``: one the page put in use (record and adapt), else --model.
        recording, writer = first.pop("record", None), first.pop("trace", None)
        return open_session(
            skin_spec, robot_spec, model, mapping=mapping, poses=poses, trace=writer,
            record=recording, overwrite=overwrite, task=task,
            on_tick=publisher.on_tick if publisher is not None else None,
        )  # fmt: skip

    chosen = {"task": task} if task is not None else {}  # the dashboard's task selector
    runner = DashboardRunner(
        opener, skin, robot, ui_rate_hz=ui_rate, interface=interface, study_dir=study, **chosen
    )

    def ready(url: str) -> None:
        console.print(f"wovenskin dashboard: [bold]{url}[/bold]  (Ctrl-C quits)")
        for other in other_device_urls(url, host):  # --host 0.0.0.0: a tablet on the network
            console.print(f"  from another device: [bold]{other}[/bold]", highlight=False)
        console.print(f"skin {runner.skin_spec}, robot {runner.robot_spec}", highlight=False)
        if open_browser and _has_desktop():
            webbrowser.open(url)

    publisher = _skin_publisher(topics, lambda line: console.print(escape(line)))
    try:
        serve(runner, host, port, token if needs_token(host) else token, on_ready=ready,
              seconds=seconds)  # fmt: skip
    finally:
        if publisher is not None:
            publisher.close()
    console.print("dashboard closed; the robot was stopped and disconnected", highlight=False)
    if publisher is not None:
        console.print(publisher.summary(), highlight=False, soft_wrap=True)


@pose_app.command("set")
@user_errors
@robot_errors
def pose_set(
    name: str = typer.Argument(..., help="initial or home."),
    robot: str = typer.Option("sim", help=ROBOT_HELP),
    poses: Path = POSES,
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
    poses: Path = POSES,
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
    from wovenskin.robots.base import Pose
    from wovenskin.robots.sim import tm5_900

    out = {}
    for name in names:
        q = tm5_900.HOME_Q if name == "home" else tm5_900.INITIAL_Q
        out[name] = (q, Pose.from_transform(tm5_900.forward_kinematics(q)))
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


@app.command()
@user_errors
def profile(
    mapping: Path = typer.Option(None, help="A mapping file (default: the packaged one)."),
    plot: Path = typer.Option(None, help="Also draw the profile into this PNG."),
) -> None:
    """How far and how fast one gesture moves the tool for how long it is held."""
    from rich.table import Table

    from wovenskin.control.mapping import ActionMapping
    from wovenskin.outputs import check_writable
    from wovenskin.ui.profile_plot import plot_profile, profile_rows

    if plot is not None:
        check_writable(plot)
    loaded = ActionMapping.load(mapping)
    speed = loaded.settings.profile
    table = Table(title=f"speed profile: {speed.kind} ({loaded.source})")
    for column in ("held (s)", "share of full speed", "speed (mm/s)", "way (mm)", "turn (deg)"):
        table.add_column(column, justify="right")
    for held, fraction, mm_s, way, turn in profile_rows(loaded):
        table.add_row(f"{held:.1f}", f"{fraction:.0%}", f"{mm_s:.0f}", f"{way:.1f}", f"{turn:.1f}")
    console.print(table)
    if plot is not None:
        console.print(f"wrote {plot_profile(loaded, plot)}", highlight=False)
