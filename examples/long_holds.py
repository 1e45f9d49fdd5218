"""Long holds: does a swipe held still keep its command until the finger lifts, on any skin?

Run: ``.venv/bin/python examples/long_holds.py [HOLD_S]`` (default 30 s).  For each skin
response from 0.1x to 3x it renders six swipes (up, down, left, right in turn), each
followed by a still hold of ``HOLD_S``, from the independent generator's people and skins
(``wovenskin.independent``, apart from the simulator the model was trained on), runs the
shipped model through the live pipeline and counts the holds whose one command lasted
until the lift.  A hold that ends early stops the arm while the user still holds.
"""

from __future__ import annotations

import sys

from wovenskin.independent import gesture_stream
from wovenskin.recognition.pipeline import (
    load_recognizer,
    pipeline_settings_for_model,
    run_pipeline,
)

GAINS = (0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 3.0)
SEEDS = range(1, 7)
DIRECTIONS = ("up", "down", "left", "right")


def main(hold_s: float) -> None:
    recognizer = load_recognizer(None, threads=1)
    settings = pipeline_settings_for_model(recognizer)
    for gain in GAINS:
        took = kept = 0
        for seed in SEEDS:
            request = f"swipe_{DIRECTIONS[seed % 4]}:held={hold_s:g}"
            stream = gesture_stream(request, seed, gain_scale=gain)
            commands = run_pipeline(stream, recognizer, settings).commands
            lift = stream.metadata["events"][0]["phases"]["lift_start_s"]
            started = [c for c in commands if c.gesture]
            if not started:
                continue
            took += 1
            ended = [c.t for c in commands if c.gesture is None and c.t > started[0].t]
            if len(started) == 1 and ended and ended[0] >= lift - 0.3:
                kept += 1
        print(f"skin {gain:g}x: {len(SEEDS)} held swipes, {took} took a command, "
              f"{kept} kept it until the lift")  # fmt: skip


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 30.0)
