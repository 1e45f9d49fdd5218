"""Terminal rendering of the skin: a coloured heatmap with contacts, and a status panel.

Each channel is drawn as a block of ``3 x 2`` character cells, which keeps the 10 mm x 14 mm
channel aspect on a typical terminal font.  Frames arrive already in ``[row, col]`` order
(row 0 at the top, column 0 on the left), so drawing them row by row shows the skin as
the user faces it.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from rich.console import Console, Group
from rich.live import Live
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from wovenskin.skin.frames import SourceStats

# Anchors of a perceptually ordered dark-to-bright map (black, indigo, red, orange, yellow).
_ANCHORS = np.array(
    [
        [0, 0, 4],
        [40, 11, 84],
        [101, 21, 110],
        [159, 42, 99],
        [212, 72, 66],
        [245, 125, 21],
        [250, 193, 39],
        [252, 255, 164],
    ],
    dtype=float,
)
_PALETTE_SIZE = 32


def _palette() -> list[str]:
    positions = np.linspace(0, len(_ANCHORS) - 1, _PALETTE_SIZE)
    colours = []
    for p in positions:
        i = min(int(p), len(_ANCHORS) - 2)
        f = p - i
        r, g, b = (1 - f) * _ANCHORS[i] + f * _ANCHORS[i + 1]
        colours.append(f"#{int(r):02x}{int(g):02x}{int(b):02x}")
    return colours


PALETTE = _palette()


def heatmap(
    signal: np.ndarray | None,
    contacts: list | None = None,
    full_scale: float = 0.3,
    cell_width: int = 3,
    cell_height: int = 2,
    shape: tuple[int, int] = (10, 10),
) -> Text:
    """Render a ``[row, col]`` frame of relative change as coloured blocks.

    ``full_scale`` is the relative change drawn at the brightest colour; contact centroids
    (objects with ``row``/``col``) are marked with a dot in their nearest channel.
    """
    rows, cols = shape if signal is None else signal.shape
    marks = set()
    for c in contacts or []:
        marks.add((int(round(c.row)), int(round(c.col))))
    if signal is None:
        levels = np.zeros((rows, cols), dtype=int)
    else:
        scaled = np.nan_to_num(signal / full_scale, nan=0.0, posinf=1.0, neginf=0.0)
        levels = np.clip((scaled * (_PALETTE_SIZE - 1)).round(), 0, _PALETTE_SIZE - 1).astype(int)
    text = Text()
    for r in range(rows):
        for line in range(cell_height):
            for c in range(cols):
                style = f"on {PALETTE[levels[r, c]]}"
                mark = (r, c) in marks and line == (cell_height - 1) // 2
                if mark:
                    body = "●".center(cell_width)
                    text.append(body, style=f"bold white {style}")
                else:
                    text.append(" " * cell_width, style=style)
            text.append("\n")
    return text


def status_table(
    stats: SourceStats,
    frame_rate_hz: float,
    display_rate_hz: float,
    n_contacts: int,
    calibrating: bool,
    extra: dict[str, str] | None = None,
) -> Table:
    """Counters and rates beside the heatmap."""
    table = Table.grid(padding=(0, 1))
    table.add_column(style="dim", justify="right")
    table.add_column()
    state = "[yellow]calibrating: hands off[/]" if calibrating else "[green]running[/]"
    if stats.stalled:
        state = "[red]stalled[/]"
    if not stats.connected:
        state = "[red]disconnected[/]"
    table.add_row("state", state)
    table.add_row("frame rate", f"{frame_rate_hz:6.1f} Hz")
    table.add_row("display", f"{display_rate_hz:6.1f} Hz")
    table.add_row("contacts", str(n_contacts))
    table.add_row("good frames", str(stats.good_frames))
    table.add_row("bad frames", _count(stats.bad_frames))
    table.add_row("dropped", _count(stats.dropped_frames))
    table.add_row("resets", _count(stats.resets))
    table.add_row("reconnects", _count(stats.reconnects))
    if stats.last_error:
        table.add_row("last error", Text(stats.last_error[:40], style="red"))
    for key, value in (extra or {}).items():
        table.add_row(key, value)
    return table


def _count(n: int) -> str:
    return f"[red]{n}[/]" if n else "0"


def skin_panel(heat: Text, status: Table, title: str, messages: list[str]) -> Group:
    """Heatmap and status side by side, recent messages underneath."""
    grid = Table.grid(padding=(0, 2))
    grid.add_column()
    grid.add_column()
    grid.add_row(heat, status)
    footer = Text("\n".join(messages[-4:]), style="dim")
    return Group(Panel(grid, title=title, expand=False), footer)


@contextmanager
def live_screen(console: Console, **options: Any) -> Iterator[Live]:
    """rich's ``Live`` display whose last screen always ends its line.

    On a terminal rich moves to a new line when the display stops; on anything else (a
    pipe, a file) it does not, so the next output was glued to the last screen
    ("...simulated skin startedwrote p01.wsrec").  Every live view goes through here."""
    try:
        with Live(console=console, **options) as live:
            yield live
    finally:
        if not console.is_terminal:
            console.line()
