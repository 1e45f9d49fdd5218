"""``wovenskin view``: a live terminal heatmap of any skin source.

Shows the conditioned signal with contact centroids, the frame rate, the display rate and
the source's error counters, refreshing at ``fps`` (default 25) while conditioning keeps
the full sample rate.  With the simulated skin it also shows what the simulated person is
doing, as ground truth.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from rich.console import Console
from rich.live import Live

from wovenskin.live import LiveSkin, RateMeter
from wovenskin.signal.config import ConditioningConfig
from wovenskin.skin.source import open_source
from wovenskin.ui.terminal import heatmap, skin_panel, status_table


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


def run_view(
    skin: str = "sim",
    seconds: float | None = None,
    fps: float = 25.0,
    full_scale: float = 0.3,
    config: ConditioningConfig | None = None,
    console: Console | None = None,
) -> ViewResult:
    """Show ``skin`` live until Ctrl-C, the end of a replay, or ``seconds`` elapse."""
    console = console or Console()
    source = open_source(skin)
    messages: list[str] = []
    live_skin = LiveSkin(source, config, on_message=messages.append)
    display_rate = RateMeter()
    frames = updates = 0
    started = time.monotonic()
    period = 1.0 / fps
    live_skin.start()
    try:
        with Live(console=console, auto_refresh=False, transient=False) as live:
            next_draw = started
            while True:
                now = time.monotonic()
                if seconds is not None and now - started >= seconds:
                    break
                out = live_skin.step(timeout=max(0.0, min(period, next_draw - now)))
                if out is not None:
                    frames += len(out.t)
                if live_skin.state.ended:
                    break
                now = time.monotonic()
                if now >= next_draw:
                    display_rate.add(now=now)
                    live.update(
                        _render(live_skin, skin, full_scale, display_rate.rate(now), messages),
                        refresh=True,
                    )
                    updates += 1
                    next_draw = max(next_draw + period, now)
    except KeyboardInterrupt:
        pass
    finally:
        live_skin.close()
    elapsed = time.monotonic() - started
    return ViewResult(frames, updates, elapsed, live_skin.stats().bad_frames, live_skin.state.ended)


def _render(
    live_skin: LiveSkin, spec: str, full_scale: float, display_hz: float, messages: list[str]
):
    st = live_skin.state
    info = live_skin.info
    extra = {"t": f"{st.t:8.2f} s"}
    label_of = getattr(live_skin.source, "current_label", None)
    if callable(label_of):
        extra["sim person"] = str(label_of() or "-")
    heat = heatmap(st.signal, st.contacts, full_scale=full_scale, shape=(info.rows, info.cols))
    status = status_table(
        live_skin.stats(), st.frame_rate_hz, display_hz, len(st.contacts), st.calibrating, extra
    )
    title = f"wovenskin view  {spec}  {info.rows}x{info.cols} @ {info.sample_rate_hz:g} Hz"
    return skin_panel(heat, status, title, messages)
