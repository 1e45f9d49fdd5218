"""What holds the arm back now, one line each, for the views (the dashboard, the terminal)."""

from __future__ import annotations

from typing import Any

import numpy as np

from wovenskin.control.safety import SafetyLayer
from wovenskin.control.session_state import SessionState


def holding(
    safety: SafetyLayer, state: SessionState, robot: Any, user_stop: bool, key_held: bool
) -> tuple[str, ...]:
    """The safety layer's report (a latched stop with how it ends, the speed cap, a
    workspace box face, a joint margin) and a simulated arm's own slow-down near a
    singularity or a joint's speed limit while a twist runs; empty when nothing holds it.
    ``user_stop``: the stop key holds the arm; ``key_held``: an input (a key, a button) is
    held."""
    held = list(safety.limiting)
    if safety.stopped:
        if user_stop:
            return ("STOP pressed: Resume (or space) to move again",)
        if state.gesture is not None:
            held.append("lift your fingers: it resumes once the skin streams again")
        elif key_held:
            held.append("release the key or button: it resumes once the skin streams again")
        else:
            held.append("resumes by itself once the skin streams again")
        return tuple(held)
    if not state.action.startswith("twist"):
        return ()
    info = getattr(robot, "ik_info", None)
    scale = float(getattr(info, "scale", 1.0))
    why = getattr(info, "limited_by", None)
    if why and scale < 0.999 and np.any(state.twist):
        held.append(f"{why}: the arm moves at {scale:.0%} of the command")
    return tuple(held)
