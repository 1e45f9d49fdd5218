"""``wovenskin bench sim``: how much faster than real time the simulated skin renders.

Times :func:`~wovenskin.sim.stream.simulate_stream` on a whole stream, and the rendering
of single performances per gesture family (one-, two- and five-finger gestures, and the
large palm/forearm contacts of the invalid set), on one core.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from rich.table import Table

from wovenskin.bench.results import BenchResult
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.layout import SkinLayout
from wovenskin.training.timing import one_core

FAMILIES = {
    "one finger (swipe_up)": ("swipe_up", None),
    "two fingers (circle_cw_2f)": ("circle_cw_2f", None),
    "five fingers (pinch_in_5f)": ("pinch_in_5f", None),
    "palm (invalid)": ("invalid", "palm"),
    "forearm (invalid)": ("invalid", "forearm"),
}


@dataclass
class SimBenchResult(BenchResult):
    stream_seconds: float
    stream_x_realtime: float
    families: dict[str, float]

    def table(self) -> Table:
        table = Table(title="wovenskin bench sim: 10x10 skin at 200 Hz, one core")
        table.add_column("what")
        table.add_column("x real time", justify="right")
        stream = f"simulate_stream ({self.stream_seconds:g} s)"
        table.add_row(stream, f"{self.stream_x_realtime:.0f}")
        for name, ratio in self.families.items():
            table.add_row(f"render {name}", f"{ratio:.0f}")
        return table


def run_sim_benchmark(stream_seconds: float = 60.0, repeats: int = 10) -> SimBenchResult:
    layout = SkinLayout()
    with one_core():
        t0 = time.perf_counter()
        stream = simulate_stream(stream_seconds, seed=0, layout=layout)
        stream_x = (len(stream.t) / stream.sample_rate_hz) / (time.perf_counter() - t0)
        families = {}
        rng = np.random.default_rng(1)
        model = SkinModel(SkinPhysics.sample(rng), layout, seed=1)
        for name, (label, kind) in FAMILIES.items():
            simulated = spent = 0.0
            for _ in range(repeats):
                perf = perform(label, Person.sample(rng), rng, layout, invalid_kind=kind)
                t0 = time.perf_counter()
                model.render(perf.contacts, perf.n_frames, perf.bursts)
                spent += time.perf_counter() - t0
                simulated += perf.n_frames / model.sample_rate_hz
            families[name] = simulated / spent
    return SimBenchResult(stream_seconds, stream_x, families)
