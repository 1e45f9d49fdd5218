"""The terminal status view of ``wovenskin run``: skin heatmap, command, robot, stops.

:func:`run_with_view` drives a :class:`~wovenskin.control.session.ControlSession` and
redraws at ``fps``: the conditioned skin with its contacts (the heatmap of
:mod:`wovenskin.ui.terminal`), the recogniser's top class, the active command and since
when, what the robot is doing, its TCP pose, speed and joints, and the stops with their
reasons.  Where stdin is a terminal, keys act at once: space stops everything (press it
again to resume), ``q`` quits; with a :class:`~wovenskin.teleop.keyboard.TerminalKeyboard`
(``wovenskin run --input keyboard``) the bound keys drive the arm too (held while their
auto-repeat lasts) and the key map is shown.  :func:`render_run` builds one screen, for
tests and snapshots.
"""

from __future__ import annotations

import os
import select
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from rich.console import Console, Group
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from wovenskin.control.session import ControlSession
from wovenskin.control.session_state import INTERRUPTED, SessionResult
from wovenskin.teleop.keyboard import TerminalKeyboard, key_map
from wovenskin.ui.terminal import heatmap, live_screen

STOP_KEY = " "
QUIT_KEYS = ("q", "Q")


@contextmanager
def terminal_keys(stream: Any = None) -> Iterator[Callable[[], str]]:
    """A function returning the keys pressed since its last call ('' without a terminal).

    On a terminal the input is switched to cbreak mode (keys arrive unbuffered, no echo)
    for the duration of the ``with`` block and restored afterwards.
    """
    stream = sys.stdin if stream is None else stream
    try:
        fd = stream.fileno()
        interactive = os.isatty(fd)
    except (AttributeError, OSError, ValueError):
        interactive = False
    if not interactive:
        yield lambda: ""
        return
    import termios
    import tty

    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd)

    def read_keys() -> str:
        keys = ""
        while select.select([fd], [], [], 0)[0]:
            chunk = os.read(fd, 64)
            if not chunk:
                break
            keys += chunk.decode(errors="ignore")
        return keys

    try:
        yield read_keys
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)


def handle_keys(session: ControlSession, keys: str) -> None:
    """Apply pressed keys: space stops (and resumes after its own stop), q quits."""
    for key in keys:
        if key == STOP_KEY:
            if session.user_stopped:
                session.resume()
            else:
                session.emergency_stop("stop key pressed")
        elif key in QUIT_KEYS:
            session.request_quit("quit with the q key")


def run_with_view(
    session: ControlSession,
    console: Console | None = None,
    seconds: float | None = None,
    fps: float = 20.0,
    title: str = "wovenskin run",
    read_keys: Callable[[], str] | None = None,
    keyboard: TerminalKeyboard | None = None,
) -> SessionResult:
    """Run ``session`` with the live view until it ends, ``q``, Ctrl-C or ``seconds``;
    ``keyboard``: the keys that drive the arm (added to the session's inputs)."""
    console = console or Console()
    if keyboard is not None and keyboard not in session.inputs.devices:
        session.add_input(keyboard)
    period = 1.0 / fps
    session.start()
    with terminal_keys() as terminal_read:
        read = read_keys or terminal_read
        next_draw = time.monotonic()
        try:
            with live_screen(console, auto_refresh=False, transient=False) as live:

                def keep_going() -> bool:
                    nonlocal next_draw
                    keys = read()
                    handle_keys(session, keyboard.feed(keys) if keyboard is not None else keys)
                    now = time.monotonic()
                    if now >= next_draw:
                        live.update(render_run(session, title, keyboard), refresh=True)
                        next_draw = max(next_draw + period, now)
                    return True

                result = session.run(seconds, should_continue=keep_going)
                live.update(render_run(session, title, keyboard), refresh=True)
        except KeyboardInterrupt:
            session.request_quit(INTERRUPTED)
            result = session.result()
    return result


def render_run(
    session: ControlSession, title: str = "wovenskin run", keyboard: TerminalKeyboard | None = None
) -> Group:
    """One screen of the view (with the key map when ``keyboard`` drives the arm)."""
    skin = session.live_skin.state
    info = session.live_skin.info
    heat = heatmap(skin.signal, skin.contacts, shape=(info.rows, info.cols))
    grid = Table.grid(padding=(0, 2))
    grid.add_column()
    grid.add_column()
    grid.add_row(heat, _status(session))
    header = f"{title}  skin {info.rows}x{info.cols} @ {info.sample_rate_hz:g} Hz"
    keys = Text("space: stop / resume   q: quit", style="dim")
    if keyboard is not None:
        bindings = key_map(session.mapping, keyboard.layout, keyboard.gripper_key)
        keys.append("\n" + "  ".join(f"{b.key}: {b.action}" for b in bindings[:6]))
        keys.append("\n" + "  ".join(f"{b.key}: {b.action}" for b in bindings[6:12]))
        keys.append("\n" + "  ".join(f"{b.key}: {b.action}" for b in bindings[12:]))
        keys.append("   (hold a key to move; it stops when the key's auto-repeat stops)")
    messages = Text("\n".join(list(session.state.messages)[-5:]), style="dim")
    return Group(Panel(grid, title=header, expand=False), keys, messages)


def _status(session: ControlSession) -> Table:
    st = session.state
    skin = session.live_skin.state
    table = Table.grid(padding=(0, 1))
    table.add_column(style="dim", justify="right")
    table.add_column()
    table.add_row("t", f"{st.t:8.2f} s")
    if skin.calibrating:
        table.add_row("skin", "[yellow]calibrating: hands off[/]")
    elif skin.stalled:
        table.add_row("skin", "[red]stalled[/]")
    else:
        table.add_row("skin", f"[green]streaming[/] {skin.frame_rate_hz:5.0f} Hz")
    table.add_row("contacts", str(len(skin.contacts or [])))
    table.add_row("recogniser", f"{st.top[0]} {100 * st.top[1]:3.0f} %")
    if st.gesture is not None:
        since = st.t - (st.gesture_since or st.t)
        table.add_row("command", Text(f"{st.gesture}  ({since:4.1f} s)", style="bold green"))
    elif getattr(st, "held", None):
        table.add_row("command", Text(str(st.held), style="bold green"))
    else:
        table.add_row("command", "none")
    unsure = getattr(st, "unsure", "")
    if unsure:
        table.add_row("", Text(unsure, style="italic yellow"))
    table.add_row("robot", _robot_line(session))
    holding = session.holding() if hasattr(session, "holding") else ()
    if holding:  # which limit holds the arm back, for as long as it holds
        table.add_row("held back", Text("\n".join(line[:70] for line in holding), style="yellow"))
    robot = st.robot
    if robot is not None:
        x, y, z = 1000 * np.asarray(robot.tcp.position)
        table.add_row("TCP", f"x {x:7.1f}  y {y:7.1f}  z {z:7.1f} mm")
        w, qx, qy, qz = robot.tcp.quat
        table.add_row("quat", f"w {w:+.3f} x {qx:+.3f} y {qy:+.3f} z {qz:+.3f}")
        table.add_row("speed", f"{1000 * robot.tcp_speed:6.1f} mm/s")
        joints = " ".join(f"{np.degrees(v):6.1f}" for v in robot.q)
        table.add_row("joints", f"{joints} deg")
        if robot.fault:
            table.add_row("fault", Text(robot.fault, style="red"))
    twist = np.asarray(st.twist)
    table.add_row(
        "twist",
        f"v {1000 * np.linalg.norm(twist[:3]):5.1f} mm/s  "
        f"w {np.degrees(np.linalg.norm(twist[3:])):5.1f} deg/s",
    )
    table.add_row("stops", _stops_text(session))
    if hasattr(session, "command_count"):
        table.add_row("commands", str(session.command_count))
    if st.last_error:
        table.add_row("last error", Text(st.last_error[:60], style="red"))
    return table


def _robot_line(session: ControlSession) -> Text:
    if session.user_stopped:
        return Text("STOPPED (space resumes)", style="bold red")
    if session.safety.stopped:
        return Text("stopped by the safety layer", style="bold red")
    return Text(session.state.action)


def _stops_text(session: ControlSession) -> Text:
    stops = session.state.stops
    if not stops:
        return Text("none")
    text = Text(f"{len(stops)}")
    for stop in stops[-3:]:
        text.append(f"\n{stop.t:7.2f} s {stop.source}: {stop.reason}"[:70], style="red")
    return text
