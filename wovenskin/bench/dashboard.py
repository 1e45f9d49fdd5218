"""``wovenskin bench dashboard``: page update rate and touch-to-robot latency over the socket.

Runs the real dashboard (:class:`~wovenskin.ui.dashboard.server.BackgroundServer` with the
shipped recogniser, the simulated skin and arm) and talks to it as the page does, over its
WebSocket, from a client in this process:

- Page rate: state messages received per second while idle, the spread of the intervals
  between them and their size.
- Touch to robot: ``swipes`` one-finger swipes sent as timestamped touch messages (one
  per 10 ms, as a pointer reports, 85 mm in 0.45 s with a minimum-jerk speed profile, then
  the finger rests 0.6 s and
  lifts), alternately up and down so the arm stays in its workspace.  For each, the wall
  time from the first touch message to the first state naming the right command, and to
  the first state in which the TCP moves (faster than 1 mm/s), as the client sees them:
  socket, touch jitter buffer, physics, conditioning, recogniser, dwell, safety, arm and
  the page's update period included.
- The vocabulary as a touch screen draws it: ``gesture_rounds`` rounds of the 14
  gestures, each performed by a new simulated person (:func:`~wovenskin.sim.performances.
  perform`) and sent as a touch screen would send it: one pointer per fingertip, a
  timestamped sample every 10 ms while the fingertip presses.  For each, the first
  command the page shows and the time from the first touch message to it.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from rich.table import Table

from wovenskin.control.session import open_session
from wovenskin.gestures import GESTURE_NAMES
from wovenskin.sim.motion import minimum_jerk
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.server import BackgroundServer

MOVING_M_S = 1e-3
SWIPE_MM = 85.0
SWIPE_S = 0.45
REST_S = 0.6
POINTER_PERIOD_S = 0.01
FORCE_N = 1.2  # a firm sliding touch (people slide with 0.25-2 N)
X_MM = 50.0


@dataclass
class DashboardBenchResult:
    ui_rate_hz: float
    idle_seconds: float
    states_per_s: float = 0.0
    interval_median_ms: float = 0.0
    interval_p90_ms: float = 0.0
    state_bytes: int = 0
    swipes: int = 0
    recognised: int = 0
    moved: int = 0
    command_median_ms: float = 0.0
    command_p90_ms: float = 0.0
    motion_median_ms: float = 0.0
    motion_p90_ms: float = 0.0
    commands: list[str | None] = field(default_factory=list)
    gesture_rounds: int = 0
    drawn: dict[str, list[str | None]] = field(default_factory=dict)  # gesture -> first commands
    drawn_latency_ms: dict[str, list[float]] = field(default_factory=dict)  # right ones only

    @property
    def drawn_right(self) -> int:
        return sum(first == name for name, firsts in self.drawn.items() for first in firsts)

    @property
    def drawn_total(self) -> int:
        return sum(len(firsts) for firsts in self.drawn.values())

    def to_dict(self) -> dict:
        return {**asdict(self), "drawn_right": self.drawn_right, "drawn_total": self.drawn_total}

    def table(self) -> Table:
        table = Table(title="wovenskin bench dashboard: sim skin + sim TM5-900, over the socket")
        table.add_column("figure")
        table.add_column("value", justify="right")
        table.add_row(
            f"page states ({self.idle_seconds:g} s idle, asked {self.ui_rate_hz:g}/s)",
            f"{self.states_per_s:.1f} /s",
        )
        table.add_row(
            "interval between states",
            f"median {self.interval_median_ms:.1f} ms, p90 {self.interval_p90_ms:.1f} ms",
        )
        table.add_row("state message size", f"{self.state_bytes / 1024:.1f} KiB")
        table.add_row("swipes recognised / moved the arm", f"{self.recognised} / {self.moved}"
                      f" of {self.swipes}")  # fmt: skip
        table.add_row(
            "first touch -> command (client sees it)",
            f"median {self.command_median_ms:.0f} ms, p90 {self.command_p90_ms:.0f} ms",
        )
        table.add_row(
            "first touch -> TCP moving (client sees it)",
            f"median {self.motion_median_ms:.0f} ms, p90 {self.motion_p90_ms:.0f} ms",
        )
        if self.drawn:
            latencies = [v for values in self.drawn_latency_ms.values() for v in values]
            table.add_row(
                f"gestures drawn as on a touch screen ({self.gesture_rounds} rounds)",
                f"{self.drawn_right} / {self.drawn_total} right first command",
            )
            if latencies:
                table.add_row(
                    "  first touch -> right command",
                    f"median {np.median(latencies):.0f} ms, p90 "
                    f"{np.percentile(latencies, 90):.0f} ms",
                )
            for name, firsts in self.drawn.items():
                wrong = [str(first) for first in firsts if first != name]
                if wrong:
                    table.add_row(f"  {name} taken for", ", ".join(wrong))
        return table


class _Client:
    """The page's side of the socket: a reader thread keeps the newest state and times."""

    def __init__(self, ws) -> None:
        self.ws = ws
        self.states: list[tuple[float, dict, int]] = []
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for text in self.ws:
                message = json.loads(text)
                if message.get("type") == "state":
                    with self._lock:
                        self.states.append((time.perf_counter(), message, len(text)))
        except Exception:  # the socket closed
            return

    def since(self, t0: float) -> list[tuple[float, dict, int]]:
        with self._lock:
            return [s for s in self.states if s[0] >= t0]

    def send(self, message: dict) -> None:
        self.ws.send(json.dumps(message))


def _swipe(client: _Client, direction: int) -> float:
    """Send one swipe's touch messages; returns the wall time of the first one."""
    start_y = 115.0 if direction < 0 else 25.0  # up: from low on the skin toward row 0
    steps = int(SWIPE_S / POINTER_PERIOD_S)
    progress = minimum_jerk(steps + 1)  # a hand's bell-shaped speed profile
    t0 = time.perf_counter()
    for k in range(steps + 1):
        y = start_y + direction * SWIPE_MM * float(progress[k])
        touch = {"id": 1, "x_mm": X_MM, "y_mm": y, "force_n": FORCE_N}
        client.send({"type": "touch", "t": time.perf_counter(), "touches": [touch]})
        time.sleep(max(0.0, t0 + (k + 1) * POINTER_PERIOD_S - time.perf_counter()))
    time.sleep(REST_S)
    client.send({"type": "touch", "t": time.perf_counter(), "touches": []})
    return t0


def _draw(client: _Client, name: str, rng: np.random.Generator) -> float:
    """Perform ``name`` as a new simulated person, sent as touch-screen pointers (a sample
    every :data:`POINTER_PERIOD_S` while a fingertip presses); returns the first send time."""
    performance = perform(name, Person.sample(rng), rng)
    tips = performance.fingertips()
    fs = performance.sample_rate_hz
    step = max(1, int(round(POINTER_PERIOD_S * fs)))
    pressing = performance.touching()
    first = int(np.argmax(pressing))  # from the first contact: a screen sees no hovering
    t0 = time.perf_counter()
    for k in range(first, performance.n_frames, step):
        touches = [
            {"id": i + 1, "x_mm": float(c.x_mm[k]), "y_mm": float(c.y_mm[k]),
             "force_n": float(c.force_n[k])}
            for i, c in enumerate(tips)
            if k < c.n_frames and c.force_n[k] > 0
        ]  # fmt: skip
        client.send({"type": "touch", "t": time.perf_counter(), "touches": touches})
        time.sleep(max(0.0, t0 + (k - first + step) / fs - time.perf_counter()))
    client.send({"type": "touch", "t": time.perf_counter(), "touches": []})
    return t0


def _first_command(client: _Client, since: float) -> tuple[str | None, float | None]:
    for t, state, _ in client.since(since):
        if state["recognition"]["command"]:
            return state["recognition"]["command"], (t - since) * 1000.0
    return None, None


def run_dashboard_benchmark(
    model: str | Path | None = None,
    idle_seconds: float = 5.0,
    swipes: int = 6,
    ui_rate_hz: float = 40.0,
    gesture_rounds: int = 0,
    seed: int = 0,
    gestures: tuple[str, ...] = GESTURE_NAMES,
) -> DashboardBenchResult:
    def opener(skin: str, robot: str):
        return open_session(skin, robot, model)

    runner = DashboardRunner(opener, "sim:auto=0,seed=21", "sim", ui_rate_hz=ui_rate_hz)
    server = BackgroundServer(runner)
    url = server.start()
    result = DashboardBenchResult(ui_rate_hz, idle_seconds)
    from websockets.sync.client import connect

    try:
        with connect(url.replace("http://", "ws://").split("?")[0] + "ws") as ws:
            client = _Client(ws)
            deadline = time.monotonic() + 20.0
            while runner.latest() is None or runner.latest()["skin"]["calibrating"]:
                if time.monotonic() > deadline:
                    raise RuntimeError("the dashboard did not finish calibrating in 20 s")
                time.sleep(0.05)
            t0 = time.perf_counter()
            time.sleep(idle_seconds)
            idle = client.since(t0)
            stamps = np.array([s[0] for s in idle])
            if len(stamps) > 1:
                intervals = np.diff(stamps) * 1000.0
                result.states_per_s = (len(stamps) - 1) / (stamps[-1] - stamps[0])
                result.interval_median_ms = float(np.median(intervals))
                result.interval_p90_ms = float(np.percentile(intervals, 90))
                result.state_bytes = int(np.median([s[2] for s in idle]))
            command_ms, motion_ms = [], []
            for k in range(swipes):
                direction = -1 if k % 2 == 0 else 1
                expected = "swipe_up" if direction < 0 else "swipe_down"
                start = _swipe(client, direction)
                time.sleep(1.0)  # the arm decelerates, the command log settles
                seen = client.since(start)
                named = [t for t, s, _ in seen if s["recognition"]["command"] == expected]
                moving = [t for t, s, _ in seen if s["robot"].get("tcp_speed", 0) > MOVING_M_S]
                first = next((s["recognition"]["command"] for _, s, _ in seen
                              if s["recognition"]["command"]), None)  # fmt: skip
                result.commands.append(first)
                if named:
                    command_ms.append((named[0] - start) * 1000.0)
                    if moving:
                        motion_ms.append((moving[0] - start) * 1000.0)
            rng = np.random.default_rng(seed)
            result.gesture_rounds = gesture_rounds
            for _ in range(gesture_rounds):
                for name in gestures:
                    start = _draw(client, name, rng)
                    time.sleep(1.0)  # the command ends, the arm settles
                    first, latency = _first_command(client, start)
                    result.drawn.setdefault(name, []).append(first)
                    if first == name and latency is not None:
                        result.drawn_latency_ms.setdefault(name, []).append(latency)
            result.swipes = swipes
            result.recognised, result.moved = len(command_ms), len(motion_ms)
            if command_ms:
                result.command_median_ms = float(np.median(command_ms))
                result.command_p90_ms = float(np.percentile(command_ms, 90))
            if motion_ms:
                result.motion_median_ms = float(np.median(motion_ms))
                result.motion_p90_ms = float(np.percentile(motion_ms, 90))
    finally:
        server.stop()
    return result
