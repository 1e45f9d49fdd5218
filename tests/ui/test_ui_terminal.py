"""Tests of the terminal heatmap: orientation, contact marks, robustness to bad values."""

import numpy as np
from rich.console import Console

from wovenskin.signal.contacts import Contact
from wovenskin.skin.frames import SourceStats
from wovenskin.ui.terminal import PALETTE, heatmap, live_screen, skin_panel, status_table
from wovenskin.ui.view import run_view


def _styles_by_row(text, cols, cell_width=3, cell_height=2):
    """Background colour of every channel, read back from the rendered spans."""
    plain = text.plain.split("\n")
    assert len(plain[0]) == cols * cell_width
    colours = []
    for span in text.spans:
        colours.append(str(span.style).split("on ")[-1])
    rows = len(colours) // (cols * cell_height)
    return np.array(colours).reshape(rows, cell_height, cols)[:, 0, :]


def test_brightest_cell_is_where_the_signal_is():
    signal = np.zeros((10, 10), np.float32)
    signal[0, 9] = 0.3  # top right
    colours = _styles_by_row(heatmap(signal, full_scale=0.3), 10)
    assert colours[0, 9] == PALETTE[-1]
    assert colours[9, 0] == PALETTE[0]


def test_contact_is_marked_in_its_channel():
    signal = np.zeros((6, 8), np.float32)
    text = heatmap(signal, [Contact(row=2.2, col=4.7, size=3, peak=0.1, strength=0.2)])
    lines = text.plain.split("\n")
    assert "●" in lines[2 * 2]
    assert lines[2 * 2].index("●") // 3 == 5


def test_nan_and_none_do_not_crash():
    signal = np.full((10, 10), np.nan, np.float32)
    signal[1, 1] = np.inf
    heatmap(signal)
    assert len(heatmap(None, shape=(4, 5)).plain.split("\n")) == 4 * 2 + 1


def test_status_panel_renders_counters():
    stats = SourceStats(good_frames=10, bad_frames=2, connected=True, last_error="crc")
    table = status_table(stats, 199.5, 25.0, 1, calibrating=False)
    console = Console(record=True, width=120)
    console.print(skin_panel(heatmap(np.zeros((10, 10))), table, "t", ["hello"]))
    out = console.export_text()
    assert "199.5 Hz" in out and "crc" in out and "hello" in out


def test_view_quits_on_q_as_run_does() -> None:
    import io

    from rich.console import Console

    keys = iter(["", "", "q"])
    console = Console(file=io.StringIO(), width=120)
    result = run_view("sim:speed=0,auto=0", seconds=30.0, fps=25.0, console=console,
                      read_keys=lambda: next(keys, "q"))  # fmt: skip
    assert result.seconds < 10.0  # q ended it, not the 30 s
    assert "q quits" in console.file.getvalue()


def test_a_live_screen_ends_its_line_when_not_on_a_terminal() -> None:
    import io

    from rich.console import Console
    from rich.text import Text

    console = Console(file=io.StringIO(), width=80, force_terminal=False)
    with live_screen(console, auto_refresh=False) as live:
        live.update(Text("simulated skin started"), refresh=True)
    console.print("wrote p01.wsrec")
    assert "startedwrote" not in console.file.getvalue()
    assert console.file.getvalue().rstrip().endswith("started\nwrote p01.wsrec")
