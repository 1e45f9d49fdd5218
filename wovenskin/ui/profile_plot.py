"""The speed profile of a mapping as a table and a figure (``wovenskin profile``).

What a person gets from one gesture held for a while: the target speed and the way the
tool covers, translation and turn, computed from the mapping's
:class:`~wovenskin.control.profile.SpeedProfile` (the shaper's acceleration and jerk
limits add a few tens of milliseconds to each start; `wovenskin bench gestures` measures
the arm itself).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.profile import SpeedProfile

HOLD_TIMES_S = (0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 1.0, 1.5, 2.5)


def profile_rows(mapping: ActionMapping) -> list[tuple[float, float, float, float, float]]:
    """Per hold time (s): share of full speed, mm/s, mm covered, degrees turned."""
    settings = mapping.settings
    profile = settings.profile
    rows = []
    for held in HOLD_TIMES_S:
        way = profile.distance(held, settings.linear_speed) * 1000.0
        turn = math.degrees(profile.distance(held, settings.angular_speed))
        way = max(way, profile.nudge("translate") * 1000.0)
        turn = max(turn, math.degrees(profile.nudge("rotate")))
        fraction = profile.fraction(held)
        rows.append((held, fraction, fraction * settings.linear_speed * 1000.0, way, turn))
    return rows


def plot_profile(mapping: ActionMapping, path: str | Path, compare_constant: bool = True) -> Path:
    """Speed and way over hold time, graded beside the paper's constant profile."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    settings = mapping.settings
    times = np.linspace(0.0, 2.5, 501)
    profiles = [("this mapping (" + settings.profile.kind + ")", settings.profile)]
    if compare_constant and settings.profile.kind != "constant":
        profiles.append(("constant (the paper's)", SpeedProfile(kind="constant")))
    figure, (speed_axes, way_axes) = plt.subplots(1, 2, figsize=(9.0, 3.4))
    for label, profile in profiles:
        speed = [profile.fraction(t) * settings.linear_speed * 1000.0 for t in times]
        way = [
            max(profile.distance(t, settings.linear_speed), profile.nudge("translate")) * 1000.0
            for t in times
        ]
        speed_axes.plot(times, speed, label=label)
        way_axes.plot(times, way, label=label)
    speed_axes.set(
        xlabel="gesture held (s, from its command's start)", ylabel="target speed (mm/s)"
    )
    way_axes.set(xlabel="gesture held (s)", ylabel="way of the tool (mm)", yscale="log")
    way_axes.set_ylim(0.5, 200.0)
    for axes in (speed_axes, way_axes):
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize=8)
    figure.suptitle("One gesture, fine and coarse: the speed profile (translations)", fontsize=10)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=110)
    plt.close(figure)
    return path
