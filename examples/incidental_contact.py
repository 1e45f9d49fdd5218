"""Incidental contact only: commands a minute on streams with no gesture in them.

Run: ``.venv/bin/python examples/incidental_contact.py [SEED ...]`` (default seeds 900 901).
For each seed it renders 120 s of invalid touches only from both generators -- the
independent one (palms, taps, grasps, brushes, rubs, scribbles, three-finger slides,
four-finger rests: ``wovenskin.independent``) and the
simulator (those plus scribbles, three- and four-finger touches, forearms, noise bursts:
``wovenskin.sim``) -- runs the shipped model through the live pipeline with each reader
and prints every command (each one a robot motion nobody asked for) by the kind of touch.
"""

from __future__ import annotations

import collections
import sys

from wovenskin.independent import mixed_stream
from wovenskin.recognition.pipeline import (
    load_recognizer,
    pipeline_settings_for_model,
    run_pipeline,
)
from wovenskin.sim.stream import simulate_stream

SECONDS = 120.0


def commands_by_kind(stream, recognizer, reader: str) -> collections.Counter:
    """The commands the pipeline issued on ``stream``, by the kind of touch they fell in."""
    settings = pipeline_settings_for_model(recognizer, reader=reader)
    result = run_pipeline(stream, recognizer, settings)
    found: collections.Counter = collections.Counter()
    events = list(
        zip(stream.event_start_s, stream.event_end_s, stream.metadata["events"], strict=True)
    )
    for command in result.commands:
        if not command.gesture:
            continue
        inside = (e for a, b, e in events if a <= command.t <= b + 0.1)
        event = next(inside, None)
        kind = "no touch" if event is None else event.get("invalid_kind") or event.get("kind")
        found[(kind, command.gesture)] += 1
    return found


def main(seeds: list[int]) -> None:
    recognizer = load_recognizer()
    generators = {
        "independent": lambda s: mixed_stream(SECONDS, s, invalid_fraction=1.0),
        "simulator": lambda s: simulate_stream(SECONDS, s, invalid_fraction=1.0),
    }
    for name, make in generators.items():
        streams = [make(s) for s in seeds]
        minutes = len(streams) * SECONDS / 60
        for reader in ("touch", "window"):
            found = sum((commands_by_kind(st, recognizer, reader) for st in streams),
                        collections.Counter())  # fmt: skip
            total = sum(found.values())
            print(f"{name}, {reader} reader: {total} commands in {minutes:g} min "
                  f"({total / minutes:.2f} a minute)")  # fmt: skip
            for (kind, gesture), n in sorted(found.items()):
                print(f"  {kind} -> {gesture}: {n}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [900, 901])
