"""``wovenskin view``: a live terminal heatmap of any skin source.

Shows the conditioned signal with contact centroids, the frame rate, the display rate and
the source's error counters, refreshing at ``fps`` (default :data:`FPS`) while conditioning keeps
the full sample rate.  With the simulated skin it also shows what the simulated person is
doing, as ground truth.
"""

from __future__ import annotations

import io
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console

from wovenskin.runtime.pipeline import open_live_skin
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.live_skin import LiveSkin, RateMeter
from wovenskin.ui.run_view import QUIT_KEYS, terminal_keys
from wovenskin.ui.terminal import heatmap, live_screen, skin_panel, status_table

FPS = 25.0
"""Display updates per second of ``wovenskin view`` unless asked otherwise (``--fps``)."""


@dataclass
class ViewResult:
    """Figures of a finished view session (used by tests and ``--seconds`` runs)."""

    frames: int
    display_updates: int
    seconds: float
    bad_frames: int
    ended: bool

    @property
    def display_rate_hz(self) -> float:
        return self.display_updates / self.seconds if self.seconds > 0 else 0.0


class AutoScale:
    """Full scale of the colour map: follows the strongest recent signal, decays slowly."""

    def __init__(self, floor: float = 0.02, decay_per_update: float = 0.98) -> None:
        self.floor = floor
        self.decay = decay_per_update
        self.value = floor

    def update(self, signal: np.ndarray | None) -> float:
        peak = float(np.nanmax(signal)) if signal is not None and signal.size else 0.0
        peak = peak if np.isfinite(peak) else 0.0
        self.value = max(self.floor, peak, self.value * self.decay)
        return self.value


def run_view(
    skin: str = "sim",
    seconds: float | None = None,
    fps: float = FPS,
    full_scale: float | None = None,
    config: ConditioningConfig | None = None,
    console: Console | None = None,
    snapshot: Path | None = None,
    read_keys: Callable[[], str] | None = None,
) -> ViewResult:
    """Show ``skin`` live until ``q`` (as in ``run --view terminal``), Ctrl-C, the end of
    a replay, or ``seconds`` elapse.

    ``full_scale`` is the relative change drawn brightest; ``None`` follows the signal.
    ``snapshot``: save the last screen drawn as an SVG file when the view ends.
    ``read_keys`` returns the keys pressed since its last call (default: the terminal's).
    """
    console = console or Console()
    messages: list[str] = []
    live_skin = open_live_skin(skin, conditioning=config, on_message=messages.append).live_skin
    display_rate = RateMeter()
    scale = AutoScale()
    last_frame = None
    frames = updates = 0
    started = time.monotonic()
    period = 1.0 / fps
    live_skin.start()
    try:
        with (
            terminal_keys() as terminal_read,
            live_screen(console, auto_refresh=False, transient=False) as live,
        ):
            read = read_keys or terminal_read
            next_draw = started
            while True:
                now = time.monotonic()
                if seconds is not None and now - started >= seconds:
                    break
                if any(key in QUIT_KEYS for key in read()):
                    break
                out = live_skin.step(timeout=max(0.0, min(period, next_draw - now)))
                if out is not None:
                    frames += len(out.t)
                if live_skin.state.ended:
                    break
                now = time.monotonic()
                if now >= next_draw:
                    display_rate.add(now=now)
                    shown_scale = full_scale or scale.update(live_skin.state.signal)
                    frame = _render(live_skin, skin, shown_scale, display_rate.rate(now), messages)
                    live.update(frame, refresh=True)
                    last_frame = frame
                    updates += 1
                    next_draw = max(next_draw + period, now)
    except KeyboardInterrupt:
        pass
    finally:
        live_skin.close()
    if snapshot is not None and last_frame is not None:
        recorder = Console(record=True, width=console.width, file=io.StringIO())
        recorder.print(last_frame)
        recorder.save_svg(str(snapshot), title=f"wovenskin view {skin}")
    elapsed = time.monotonic() - started
    return ViewResult(frames, updates, elapsed, live_skin.stats().bad_frames, live_skin.state.ended)


def _render(
    live_skin: LiveSkin, spec: str, full_scale: float, display_hz: float, messages: list[str]
):
    st = live_skin.state
    info = live_skin.info
    extra = {"t": f"{st.t:8.2f} s", "full scale": f"{100 * full_scale:5.1f} %", "keys": "q quits"}
    label_of = getattr(live_skin.source, "current_label", None)
    if callable(label_of):
        extra["sim person"] = str(label_of() or "-")
    heat = heatmap(st.signal, st.contacts, full_scale=full_scale, shape=(info.rows, info.cols))
    status = status_table(
        live_skin.stats(), st.frame_rate_hz, display_hz, len(st.contacts), st.calibrating, extra
    )
    title = f"wovenskin view  {spec}  {info.rows}x{info.cols} @ {info.sample_rate_hz:g} Hz"
    return skin_panel(heat, status, title, messages)
