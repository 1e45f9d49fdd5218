"""One frame of the dashboard: a running session's state as a JSON-ready dict.

:func:`build_snapshot` reads a :class:`~wovenskin.control.session.ControlSession` (its
skin, recogniser, safety layer and robot state) and the runner's own bookkeeping
(:class:`Timeline`, latencies) and returns plain lists, numbers and strings.  It runs on the
session's thread, so everything it reads is consistent (the heatmap's frame, its contacts
and the recogniser's tracks are all of the newest frame read); the server only serialises it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wovenskin.ui.dashboard.scene import ArmScene

SIGNAL_FULL_SCALE = 0.3  # relative change drawn at the brightest colour (as the terminal view)
TIMELINE_S = 30.0  # how much history the page's timeline shows


@dataclass
class TimelineEntry:
    t: float  # session time, s
    kind: str  # "command" (name None: the command ended) or "stop"
    name: str | None
    detail: str = ""

    def to_dict(self) -> dict:
        return {"t": round(self.t, 3), "kind": self.kind, "name": self.name, "detail": self.detail}


@dataclass
class Timeline:
    """Command changes and stops of the last :data:`TIMELINE_S` seconds."""

    entries: deque = field(default_factory=lambda: deque(maxlen=400))

    def add(self, entry: TimelineEntry) -> None:
        self.entries.append(entry)

    def recent(self, now: float) -> list[dict]:
        return [e.to_dict() for e in self.entries if e.t >= now - TIMELINE_S]


def _floats(values: Any, digits: int = 4) -> list[float]:
    array = np.nan_to_num(np.asarray(values, dtype=np.float64).reshape(-1), nan=0.0)
    return [round(float(v), digits) for v in array]


def tracks_part(session: Any) -> list[dict]:
    """The recogniser's live contact tracks, in channel units as the contacts (rows down,
    columns across, channel centres at integers; velocities in channels per second)."""
    tracks = getattr(getattr(session, "pipeline", None), "tracks", None)
    if tracks is None:  # a pipeline that tracks nothing
        return []
    info = session.live_skin.info
    rate, row_mm, col_mm = float(info.sample_rate_hz), info.row_pitch_mm, info.col_pitch_mm
    return [
        {
            "id": int(track.id),
            "row": round(track.y / row_mm, 3),
            "col": round(track.x / col_mm, 3),
            "v_row": round(track.vy * rate / row_mm, 2),
            "v_col": round(track.vx * rate / col_mm, 2),
            "speed_mm_s": round(track.speed_mm_s(rate), 1),
            "travel_mm": round(float(track.travel), 1),
            "merged": bool(track.merged),
        }
        for track in tracks()
    ]


def skin_part(session: Any, source_spec: str, virtual: bool) -> dict:
    """The heatmap, contacts, the recogniser's tracks and stream health."""
    live = session.live_skin
    state = live.state
    info = live.info
    stats = live.stats()
    rows, cols = info.rows, info.cols
    signal = state.signal if state.signal is not None else np.zeros((rows, cols))
    contacts = [
        {
            "row": round(float(c.row), 3),
            "col": round(float(c.col), 3),
            "size": int(c.size),
            "peak": round(float(c.peak), 4),
        }
        for c in state.contacts
    ]
    return {
        "rows": rows,
        "cols": cols,
        "row_pitch_mm": info.row_pitch_mm,
        "col_pitch_mm": info.col_pitch_mm,
        "signal": _floats(signal),
        "full_scale": SIGNAL_FULL_SCALE,
        "contacts": contacts,
        "tracks": tracks_part(session),
        "fps": round(float(state.frame_rate_hz), 1),
        "calibrating": bool(state.calibrating),
        "stalled": bool(state.stalled or stats.stalled),
        "ended": bool(state.ended),
        "source": source_spec,
        "virtual": virtual,
        "counters": {
            "good": stats.good_frames,
            "bad": stats.bad_frames,
            "dropped": stats.dropped_frames,
            "reconnects": stats.reconnects,
            "session_errors": session.state.errors,
        },
        "last_error": stats.last_error or session.state.last_error,
    }


def recognition_part(session: Any) -> dict:
    state = session.state
    probabilities = state.probabilities
    classes = list(state.class_names)
    p = _floats(probabilities, 3) if probabilities is not None else [0.0] * len(classes)
    since = state.gesture_since
    return {
        "classes": classes,
        "p": p,
        "top": [state.top[0], round(float(state.top[1]), 3)],
        "command": state.gesture,
        "command_for_s": round(session.now - since, 2) if state.gesture and since else 0.0,
        "action": state.action,
        "unsure": getattr(state, "unsure", ""),
        "motion": motion_part(session),
    }


def motion_part(session: Any) -> dict:
    """How fast the arm moves now (mm/s, deg/s), as the arm measures it (its TCP twist:
    a pose move such as going home is no twist command, yet the arm moves), and, while a
    gesture's command runs, its speed profile's share of full speed (control/profile.py).
    With no arm state yet, the commanded twist."""
    robot = getattr(session.state, "robot", None)
    measured = getattr(robot, "tcp_twist", None)
    twist = np.asarray(
        measured if measured is not None else getattr(session.state, "twist", np.zeros(6)),
        dtype=float,
    )
    motion = getattr(session, "gesture_motion", None)
    fraction = None
    if motion is not None and session.state.gesture is not None:
        fraction = round(float(motion.speed_fraction(float(session.now))), 3)
    return {
        "linear_mm_s": round(1000.0 * float(np.linalg.norm(twist[:3])), 1),
        "angular_deg_s": round(float(np.degrees(np.linalg.norm(twist[3:]))), 1),
        "fraction": fraction,
        "nudging": bool(motion is not None and motion.nudging),
    }


def robot_part(session: Any, robot_spec: str, scene: ArmScene | None) -> dict:
    state = session.state.robot
    out: dict[str, Any] = {"spec": robot_spec, "connected": state is not None}
    if state is None:
        return out
    rotation = state.tcp.rotation()
    out.update(
        q=_floats(state.q, 5),
        tcp={
            "pos": _floats(state.tcp.position, 5),
            "quat": _floats(state.tcp.quat, 5),
            "x_axis": _floats(rotation[:, 0], 4),
            "z_axis": _floats(rotation[:, 2], 4),
        },
        tcp_speed=round(float(state.tcp_speed), 4),
        twist=_floats(session.state.twist, 4),
        moving=bool(state.moving),
        fault=state.fault,
    )
    if scene is not None:
        try:
            out["geoms"] = scene.poses(state.q)
            out["skin_corners"] = scene.skin_corners(session.live_skin.info.layout)
        except ValueError:
            pass
    return out


def build_snapshot(
    session: Any,
    *,
    seq: int,
    source_spec: str,
    robot_spec: str,
    scene: ArmScene | None,
    timeline: Timeline,
    virtual: bool,
    extras: dict,
) -> dict:
    """The whole page state (see the module docstring)."""
    safety = session.safety
    stops = [
        {"t": round(s.t, 3), "source": s.source, "reason": s.reason} for s in safety.stops[-5:]
    ]
    return {
        "type": "state",
        "seq": seq,
        "t": round(float(session.now), 3),
        "skin": skin_part(session, source_spec, virtual),
        "recognition": recognition_part(session),
        "robot": robot_part(session, robot_spec, scene),
        "safety": {
            "stopped": bool(safety.stopped),
            "user_stopped": bool(session.user_stopped),
            "stops": stops,
            "holding": list(session.holding()) if hasattr(session, "holding") else [],
        },
        "timeline": timeline.recent(float(session.now)),
        "messages": list(session.state.messages),
        "recording": str(session.recorder.path) if session.recorder is not None else None,
        "speed_scale": session.speed_scale,
        **extras,
    }
