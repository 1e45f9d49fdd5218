"""``wovenskin dataset``: a window data set from simulation or from labelled streams.

The command imports its library code when it runs, so ``wovenskin --help`` stays instant.
"""

from __future__ import annotations

from pathlib import Path

import typer

from wovenskin.cli.app import app, console, user_errors
from wovenskin.cli.app import given as _given
from wovenskin.errors import ConfigError


@app.command()
@user_errors
def dataset(
    out: Path = typer.Option(..., help="Directory of the window data set to write."),
    streams: list[Path] = typer.Option(
        None,
        help="Labelled streams (.npz) or recordings (.wsrec) to window instead of "
        "simulating: --streams A.npz B.npz ...",
    ),
    more_streams: list[Path] = typer.Argument(None, help="More streams (after --streams)."),
    recordings: int = typer.Option(
        None, min=1, max=100000, help="Simulated recordings, new people (default 140)."
    ),
    windows: int = typer.Option(
        None, min=1, max=10000000, help="Gesture windows per recording (default 1000)."
    ),
    invalid_windows: int = typer.Option(
        None, min=0, max=10000000, help="Invalid windows per recording (default 400)."
    ),
    seconds: float = typer.Option(
        None, min=0.1, max=3600, help="Seconds per simulated recording (default 120)."
    ),
    recipe: str = typer.Option(
        None,
        help="stream: windows at every position, labelled by what they show; "
        "overlay: the paper's augmentation (gesture slices on background noise). Default: stream.",
    ),
    seed: int = typer.Option(
        0, min=0, max=2**32 - 1, help="Random seed: the same seed gives the same files."
    ),
    workers: int = typer.Option(None, min=1, max=256, help="Worker processes (default 2)."),
    dtype: str = typer.Option(None, help="Windows stored as float16 or float32 (default float16)."),
    rows: int = typer.Option(
        None, min=1, max=64, help="Simulated skin rows (default 10; streams bring theirs)."
    ),
    cols: int = typer.Option(None, min=1, max=64, help="Simulated skin columns (default 10)."),
    overwrite: bool = typer.Option(False, help="Replace an existing data set."),
) -> None:
    """Build a window data set from simulation or labelled streams."""
    from wovenskin.cli.app import dataset_progress
    from wovenskin.skin.layout import DEFAULT_COLS, DEFAULT_ROWS, SkinLayout
    from wovenskin.training.datasets import build_dataset_from_streams, generate_sim_dataset
    from wovenskin.training.report import DatasetSummary
    from wovenskin.training.window_settings import WindowSettings

    settings = WindowSettings(**_given(recipe=recipe))
    files = [*(streams or []), *(more_streams or [])]
    if files and (rows is not None or cols is not None):
        raise ConfigError("--rows/--cols set a simulated skin's grid; streams bring their own")
    grid = (DEFAULT_ROWS if rows is None else rows, DEFAULT_COLS if cols is None else cols)
    layout = SkinLayout(*grid).check_supported(where="--rows/--cols")
    bar, update = dataset_progress(console, "windowing streams" if files else "simulating")
    given = _given(  # unset: the builders' defaults (training/datasets/writer.py, sim.py)
        windows_per_recording=windows, invalid_windows_per_recording=invalid_windows,
        workers=workers, dtype=dtype,
    )  # fmt: skip
    sim = _given(n_recordings=recordings, seconds_per_recording=seconds)
    with bar:
        if files:
            ds = build_dataset_from_streams(
                out, files, seed=seed, progress=update, overwrite=overwrite, settings=settings,
                **given,
            )  # fmt: skip
        else:
            ds = generate_sim_dataset(
                out, seed=seed, progress=update, overwrite=overwrite, settings=settings,
                layout=layout, **given, **sim,
            )  # fmt: skip
    summary = DatasetSummary.of(ds)
    console.print(summary.table(ds.class_names))
    console.print(summary.describe(), highlight=False, soft_wrap=True)
