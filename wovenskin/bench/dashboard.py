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
  the page's update period included.  After each swipe's rest, from its lift-off message:
  the time to the first state with no command, to the first with the TCP still, and the
  TCP's way in between (how far the arm goes after the finger lifts).
- The vocabulary as a touch screen draws it: ``gesture_rounds`` rounds of the 14
  gestures, each performed by a new simulated person (:func:`~wovenskin.sim.performances.
  perform`) and sent as a touch screen would send it: one pointer per fingertip, a
  timestamped sample every 10 ms while the fingertip presses.  For each, the first
  command the page shows and the time from the first touch message to it.
- The vocabulary as a mouse draws it (``mouse_rounds``): what the page's mouse can draw
  -- the one- and two-finger swipes (a hand of two fingertips 18 mm apart), the
  two-finger circles and ``push`` (the button held still, then Shift or the wheel ramps
  the pressure, :data:`PRESS_RATE` per second) -- with strokes 40-90 mm long at 70-250 mm/s
  on average (docs/gestures.md's range; circles of 14-26 mm radius at 1-2.6 turns/s),
  each drawn twice: densely sampled (a pointer sample every 8 ms, a quiet page) and
  sparsely (3-13 samples per stroke, a busy page or a slow tablet).  A trial succeeds
  when the commands shown during it are exactly the gesture (no other one, no flicker).
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
from rich.table import Table

from wovenskin.bench.results import figure_table
from wovenskin.gestures import GESTURE_NAMES, GESTURES
from wovenskin.runtime.session import open_session
from wovenskin.sim.motion import minimum_jerk
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.ui.dashboard.runner import UI_RATE_HZ, DashboardRunner
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
    lift_off_median_ms: float = 0.0  # the lift-off's message -> a state with no command
    lift_off_p90_ms: float = 0.0
    lift_still_median_ms: float = 0.0  # the lift-off's message -> the TCP still again
    lift_travel_median_mm: float = 0.0  # the TCP's way from the lift-off's state to still
    lift_travel_max_mm: float = 0.0
    commands: list[str | None] = field(default_factory=list)
    gesture_rounds: int = 0
    drawn: dict[str, list[str | None]] = field(default_factory=dict)  # gesture -> first commands
    drawn_latency_ms: dict[str, list[float]] = field(default_factory=dict)  # right ones only
    mouse_rounds: int = 0
    # sampling ("dense"/"sparse") -> gesture -> per trial, the distinct commands shown
    mouse: dict[str, dict[str, list[list[str]]]] = field(default_factory=dict)

    def mouse_success(self, sampling: str) -> dict[str, tuple[int, int, int]]:
        """Per gesture: trials whose commands were exactly the gesture, trials that ended
        on it (a circle may start as a two-finger swipe and be taken over, as the execution
        rules allow), and trials."""
        return {
            name: (
                sum(shown == [name] for shown in trials),
                sum(bool(shown) and shown[-1] == name for shown in trials),
                len(trials),
            )
            for name, trials in self.mouse.get(sampling, {}).items()
        }

    @property
    def drawn_right(self) -> int:
        return sum(first == name for name, firsts in self.drawn.items() for first in firsts)

    @property
    def drawn_total(self) -> int:
        return sum(len(firsts) for firsts in self.drawn.values())

    def to_dict(self) -> dict:
        success = {s: self.mouse_success(s) for s in self.mouse}
        return {**asdict(self), "drawn_right": self.drawn_right, "drawn_total": self.drawn_total,
                "mouse_success": success}  # fmt: skip

    def table(self) -> Table:
        table = figure_table("wovenskin bench dashboard: sim skin + sim TM5-900, over the socket")
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
        table.add_row(
            "lift-off -> no command (client sees it)",
            f"median {self.lift_off_median_ms:.0f} ms, p90 {self.lift_off_p90_ms:.0f} ms",
        )
        table.add_row(
            "lift-off -> TCP still; its way after the lift",
            f"median {self.lift_still_median_ms:.0f} ms; median {self.lift_travel_median_mm:.1f}"
            f" mm, max {self.lift_travel_max_mm:.1f} mm",
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
        for sampling in self.mouse:
            success = self.mouse_success(sampling)
            right = sum(r for r, _, _ in success.values())
            ended = sum(e for _, e, _ in success.values())
            total = sum(n for _, _, n in success.values())
            table.add_row(
                f"drawn with a mouse, {sampling} samples ({self.mouse_rounds} rounds)",
                f"{right} / {total} exactly right, {ended} ended right",
            )
            for name, (r, _, n) in success.items():
                wrong = [" then ".join(shown) or "nothing"
                         for shown in self.mouse[sampling][name] if shown != [name]]  # fmt: skip
                detail = f"  ({'; '.join(wrong)})" if wrong else ""
                table.add_row(f"  {name}", f"{r} / {n}{detail}")
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


def _swipe(client: _Client, direction: int) -> tuple[float, float]:
    """Send one swipe's touch messages; returns the wall times of the first one and of the
    lift-off."""
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
    lifted = time.perf_counter()
    client.send({"type": "touch", "t": lifted, "touches": []})
    return t0, lifted


def _after_lift(seen: list[tuple[float, dict, int]], lifted: float) -> tuple[float, ...] | None:
    """From the states after a lift-off at ``lifted``: seconds to the first with no command,
    seconds to the first with the TCP still (and no command), and the TCP's way (m) from the
    last state before the lift to that one; None if either never came."""
    before = [s for t, s, _ in seen if t <= lifted]
    after = [(t, s) for t, s, _ in seen if t > lifted]
    off = next((t for t, s in after if not s["recognition"]["command"]), None)
    still = next((
        (t, s) for t, s in after
        if not s["recognition"]["command"] and s["robot"].get("tcp_speed", 0) <= MOVING_M_S
    ), None)  # fmt: skip
    if not before or off is None or still is None:
        return None
    way = np.subtract(still[1]["robot"]["tcp"]["pos"], before[-1]["robot"]["tcp"]["pos"])
    return off - lifted, still[0] - lifted, float(np.linalg.norm(way))


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


MOUSE_GESTURES = tuple(g.name for g in GESTURES if g.motion != "pinch")
"""What the page's mouse can draw: every gesture of the vocabulary but the pinches, which
need the wheel's spread, not a stroke."""
DENSE_PERIOD_S = 0.008  # a quiet page: a pointer sample every 8 ms
SPARSE_SAMPLES = (3, 13)  # a busy page: this many samples per stroke
MOUSE_FORCE_N = 0.2 + 2.8 * 0.35  # the page's force at the slider's default pressure
PRESS_RATE = 4.0  # pressure per second, as the page ramps Shift / the wheel
PRESS_MAX = 1.4  # the page's firm press (4.1 N)
HAND_GAP_MM = 18.0  # the page's default two-finger hand
HEARTBEAT_S = 0.25  # the page repeats resting fingers this often


def _mouse_path(name: str, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A mouse-drawn ``name``: times (s) and centre positions (mm) of the hand, and the
    pressure (0-1) along the stroke, with a bell-shaped speed profile."""
    if name == "push":
        rise = (PRESS_MAX - 0.35) / PRESS_RATE
        t = np.arange(0.0, 0.3 + rise + 1e-9, 0.004)
        pressure = np.clip(0.35 + PRESS_RATE * (t - 0.3), 0.35, PRESS_MAX)
        return t, np.tile([50.0, 70.0], (len(t), 1)), pressure
    if name.startswith("circle"):
        radius = rng.uniform(14.0, 26.0)
        turns_per_s = rng.uniform(1.0, 2.6)
        turns = rng.uniform(1.2, 2.0)
        duration = turns / turns_per_s
        t = np.arange(0.0, duration + 1e-9, 0.004)
        sign = 1.0 if name == "circle_cw_2f" else -1.0  # y grows downward: + is clockwise
        angle = sign * 2 * np.pi * turns * minimum_jerk(len(t), 0.0) ** 1.0
        centre = np.array([50.0, 70.0])
        xy = centre + radius * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        return t, xy, np.full(len(t), 0.35)
    length = rng.uniform(40.0, 90.0)
    speed = rng.uniform(70.0, 250.0)  # mm/s on average
    duration = length / speed
    t = np.arange(0.0, duration + 1e-9, 0.004)
    direction = name.removesuffix("_2f").removeprefix("swipe_")
    unit = {"up": (0, -1), "down": (0, 1), "left": (-1, 0), "right": (1, 0)}[direction]
    start = np.array([50.0, 70.0]) - np.array(unit) * length / 2
    xy = start + np.outer(minimum_jerk(len(t)), np.array(unit) * length)
    return t, xy, np.full(len(t), 0.35)


def _mouse_draw(client: _Client, name: str, sparse: bool, rng: np.random.Generator) -> float:
    """Send ``name`` as the page sends a mouse: the press, the stroke's pointer samples
    (every :data:`DENSE_PERIOD_S`, or 3-13 of them), the hand resting 0.6 s (with the
    page's heartbeat), the lift; returns the wall time of the press."""
    t, xy, pressure = _mouse_path(name, rng)
    fingers = 2 if name.endswith("_2f") else 1
    if sparse and name != "push":  # the press, a few samples at uneven times, the end
        n = int(rng.integers(SPARSE_SAMPLES[0], SPARSE_SAMPLES[1] + 1))
        picks = np.sort(rng.uniform(t[0], t[-1], size=n - 1))
        index = np.unique(np.searchsorted(t, np.concatenate([[t[0]], picks, [t[-1]]])))
        index = np.minimum(index, len(t) - 1)
    else:
        period = DENSE_PERIOD_S if not sparse else 0.05
        index = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, period)))
        index = np.minimum(np.concatenate([index, [len(t) - 1]]), len(t) - 1)

    def tips(k: int) -> list[dict]:
        force = 0.2 + 2.8 * float(pressure[k])
        x, y = float(xy[k, 0]), float(xy[k, 1])
        if fingers == 1:
            return [{"id": 1, "x_mm": x, "y_mm": y, "force_n": force}]
        return [{"id": 10 + i, "x_mm": x + dx, "y_mm": y, "force_n": force}
                for i, dx in enumerate((-HAND_GAP_MM / 2, HAND_GAP_MM / 2))]  # fmt: skip

    t0 = time.perf_counter()
    for k in index:
        time.sleep(max(0.0, t0 + t[k] - time.perf_counter()))
        client.send({"type": "touch", "t": t0 + float(t[k]), "touches": tips(int(k))})
    end = t0 + float(t[-1])
    for rest in np.arange(HEARTBEAT_S, REST_S + 1e-9, HEARTBEAT_S):
        time.sleep(max(0.0, end + rest - time.perf_counter()))
        client.send({"type": "touch", "t": end + float(rest), "touches": tips(len(t) - 1)})
    time.sleep(max(0.0, end + REST_S - time.perf_counter()))
    client.send({"type": "touch", "t": end + REST_S, "touches": []})
    return t0


def _commands_shown(client: _Client, since: float) -> list[str]:
    """The distinct commands the page showed since ``since``, in order."""
    shown: list[str] = []
    for _, state, _ in client.since(since):
        command = state["recognition"]["command"]
        if command and (not shown or shown[-1] != command):
            shown.append(command)
    return shown


def _first_command(client: _Client, since: float) -> tuple[str | None, float | None]:
    for t, state, _ in client.since(since):
        if state["recognition"]["command"]:
            return state["recognition"]["command"], (t - since) * 1000.0
    return None, None


IDLE_SECONDS = 5.0  # page states counted while idle
SWIPES = 6  # swipes sent over the socket, alternately up and down


def run_dashboard_benchmark(
    model: str | Path | None = None,
    idle_seconds: float = IDLE_SECONDS,
    swipes: int = SWIPES,
    ui_rate_hz: float = UI_RATE_HZ,
    gesture_rounds: int = 0,
    seed: int = 0,
    gestures: tuple[str, ...] = GESTURE_NAMES,
    mouse_rounds: int = 0,
    mouse_gestures: tuple[str, ...] = MOUSE_GESTURES,
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
            command_ms, motion_ms, lifts = [], [], []
            for k in range(swipes):
                direction = -1 if k % 2 == 0 else 1
                expected = "swipe_up" if direction < 0 else "swipe_down"
                start, lifted = _swipe(client, direction)
                time.sleep(1.0)  # the arm decelerates, the command log settles
                seen = client.since(start)
                lift = _after_lift(seen, lifted)
                if lift is not None:
                    lifts.append(lift)
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
            result.mouse_rounds = mouse_rounds
            for _ in range(mouse_rounds):
                client.send({"type": "command", "cmd": "home"})  # pushes walk the arm back
                time.sleep(4.0)
                for name in mouse_gestures:
                    for sampling in ("dense", "sparse"):
                        start = _mouse_draw(client, name, sampling == "sparse", rng)
                        time.sleep(1.0)  # the command ends, the arm settles
                        shown = _commands_shown(client, start)
                        result.mouse.setdefault(sampling, {}).setdefault(name, []).append(shown)
            result.swipes = swipes
            result.recognised, result.moved = len(command_ms), len(motion_ms)
            if command_ms:
                result.command_median_ms = float(np.median(command_ms))
                result.command_p90_ms = float(np.percentile(command_ms, 90))
            if motion_ms:
                result.motion_median_ms = float(np.median(motion_ms))
                result.motion_p90_ms = float(np.percentile(motion_ms, 90))
            if lifts:
                off_s, still_s, way_m = (np.array(v) for v in zip(*lifts, strict=True))
                result.lift_off_median_ms = float(np.median(off_s) * 1000.0)
                result.lift_off_p90_ms = float(np.percentile(off_s, 90) * 1000.0)
                result.lift_still_median_ms = float(np.median(still_s) * 1000.0)
                result.lift_travel_median_mm = float(np.median(way_m) * 1000.0)
                result.lift_travel_max_mm = float(np.max(way_m) * 1000.0)
    finally:
        server.stop()
    return result
