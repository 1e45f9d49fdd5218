"""What a replay through ``ros2:`` did on the wire, checked against what the session meant.

The inputs are the stand-in Servo's log (:mod:`wovenskin.robots.ros2.standin`: every twist
received with its CDR bytes, the receiver's clocks and the arm's joints) and the session's
recording (``run --record``: the commands with their stream times, and per control tick the
commanded twist and the backend's clock ``robot_t``). Both processes read the same
``CLOCK_MONOTONIC``, so ``robot_t`` ties each tick's stream time to the receiver's clock.

- **decoding**: every twist's bytes decode with ``rosbags`` (an independent serialiser) as
  ``geometry_msgs/msg/TwistStamped`` and give the values the stand-in read;
- **stamps**: receive time minus header stamp, both on the system clock;
- **when**: a moving twist is sent only while a command acts (from its activation to its
  end, plus the nudge that completes a flick shorter than the mapping's minimum), placed
  by its stamp at the tick that sent it;
- **where**: a moving twist points along the mapped axis of the acting gesture, at the
  arm's pose when it arrived (cosine of the 6-vectors);
- **lift-off**: from the tick that ended a command on lift-off to the first zero twist
  received (and from the true lift-off, the label's end, which adds the recogniser's
  lift detection);
- **silence**: from the last joint state published to the first zero twist received, and
  that the arm moved no more after it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wovenskin.control.mapping import ActionMapping
from wovenskin.recognition.arbiter import LIFT_OFF
from wovenskin.recording.native import Recording
from wovenskin.robots.base import Pose
from wovenskin.robots.urdf import UrdfChain

ALIGNED_COSINE = 0.999
TICK_SLACK_S = 0.006  # one 200 Hz tick and a little: a twist's tick vs its command's time


@dataclass(frozen=True)
class Command:
    """One command of the session: its gesture, when it began and ended (stream time)."""

    gesture: str
    start_s: float
    end_s: float
    end_reason: str
    nudge_end_s: float  # when a flick's completing nudge ended (= end_s without one)


@dataclass
class WireReport:
    """The figures of one replay (see the module docstring)."""

    twists: int = 0
    decoded: int = 0  # decoded by rosbags to the values the stand-in read
    stamp_lag_ms: list[float] = field(default_factory=list)
    moving: int = 0
    moving_outside_commands: int = 0
    moving_in_nudges: int = 0
    aligned: int = 0
    misaligned: int = 0
    lift_offs: int = 0
    lift_to_zero_ms: list[float] = field(default_factory=list)  # lift-offs without a nudge
    nudge_lift_to_zero_ms: list[float] = field(default_factory=list)
    true_lift_to_zero_ms: list[float] = field(default_factory=list)
    rate_hz: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        def stats(values: list[float]) -> dict[str, float | None]:
            if not values:
                return {"n": 0, "median": None, "max": None}
            return {"n": len(values), "median": float(np.median(values)), "max": max(values)}

        return {
            "twists": self.twists,
            "decoded": self.decoded,
            "rate_hz": self.rate_hz,
            "stamp_lag_ms": stats(self.stamp_lag_ms),
            "moving": self.moving,
            "moving_outside_commands": self.moving_outside_commands,
            "moving_in_nudges": self.moving_in_nudges,
            "aligned": self.aligned,
            "misaligned": self.misaligned,
            "lift_offs": self.lift_offs,
            "lift_to_zero_ms": stats(self.lift_to_zero_ms),
            "nudge_lift_to_zero_ms": stats(self.nudge_lift_to_zero_ms),
            "true_lift_to_zero_ms": stats(self.true_lift_to_zero_ms),
        }


def session_ticks(recording: Recording) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stream time, backend clock and commanded twist of every recorded control tick."""
    robot = recording.annotations_of("robot")
    t = np.array([a.t for a in robot], dtype=float)
    robot_t = np.array([a.payload["robot_t"] for a in robot], dtype=float)
    twist = np.array([a.payload["twist_command"] for a in robot], dtype=float).reshape(-1, 6)
    return t, robot_t, twist


def session_commands(recording: Recording) -> list[Command]:
    """The skin's commands of a recorded session, with their nudges."""
    t, _, twist = session_ticks(recording)
    moving = np.any(twist != 0.0, axis=1)
    commands: list[Command] = []
    active: tuple[str, float] | None = None
    for note in recording.annotations_of("commands"):
        gesture = note.payload.get("gesture")
        if active is not None:
            name, start = active
            end = float(note.t)
            after = np.flatnonzero((t >= end) & ~moving)  # the first tick at rest after it
            rest = float(t[after[0]]) if len(after) else end
            nudge_end = rest if note.payload.get("reason") == LIFT_OFF else end
            commands.append(Command(name, start, end, str(note.payload.get("reason")), nudge_end))
        active = (gesture, float(note.t)) if gesture is not None else None
    return commands


def wire_report(
    log: list[dict[str, Any]],
    recording: Recording,
    chain: UrdfChain,
    mapping: ActionMapping,
    true_lifts_s: list[float] = (),
) -> WireReport:
    """Check the stand-in's log of one replay against the session's recording."""
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    report = WireReport()
    twists = [r for r in log if r["event"] == "twist"]
    report.twists = len(twists)
    tick_t, tick_clock, _ = session_ticks(recording)
    offset = float(np.median(tick_clock - tick_t))  # receiver's monotonic s = stream s + offset
    order = np.argsort(tick_clock, kind="stable")
    clock_sorted, t_by_clock = tick_clock[order], tick_t[order]

    def sent_at(record: dict[str, Any]) -> float:
        """The stream time of the tick that sent a twist: the first tick whose backend
        clock is at or after the twist's stamp (a tick publishes, then reads the robot).
        The stamp is on the system clock; the receiver's pair of clocks at receipt turns it
        into the monotonic one. Receipt time would not do: on a loaded machine a twist can
        arrive several ticks later, while a session that fell behind real time catches up."""
        mono = (record["stamp_ns"] - (record["wall_ns"] - record["mono_ns"])) * 1e-9
        k = int(np.searchsorted(clock_sorted, mono, side="left"))
        return float(t_by_clock[k]) if k < len(t_by_clock) else mono - offset

    commands = session_commands(recording)
    received_mono = np.array([r["mono_ns"] * 1e-9 for r in twists])
    if len(received_mono) > 1:
        report.rate_hz = (len(received_mono) - 1) / float(received_mono[-1] - received_mono[0])
    for record in twists:
        message = typestore.deserialize_cdr(
            bytes.fromhex(record["cdr"]), "geometry_msgs/msg/TwistStamped"
        )
        sent = message.twist
        values = [sent.linear.x, sent.linear.y, sent.linear.z, sent.angular.x, sent.angular.y,
                  sent.angular.z]  # fmt: skip
        report.decoded += values == record["twist"]
        report.stamp_lag_ms.append((record["wall_ns"] - record["stamp_ns"]) * 1e-6)
        twist = np.array(record["twist"], dtype=float)
        if not np.any(twist):
            continue
        report.moving += 1
        q = np.array(record["q"], dtype=float)
        frame = record["frame_id"]
        if frame != chain.base_link:
            rotation = chain.link_pose(q, frame)[:3, :3]
            twist = np.concatenate([rotation @ twist[:3], rotation @ twist[3:]])
        _classify(report, twist, sent_at(record), q, commands, chain, mapping)
    _lift_offs(report, commands, tick_t, tick_clock, received_mono, twists, true_lifts_s)
    return report


def _classify(
    report: WireReport,
    twist: np.ndarray,
    stream_s: float,
    q: np.ndarray,
    commands: list[Command],
    chain: UrdfChain,
    mapping: ActionMapping,
) -> None:
    """Count a moving twist as inside a command (aligned or not), in a nudge, or outside."""
    for command in commands:
        if command.start_s - TICK_SLACK_S <= stream_s <= command.end_s + TICK_SLACK_S:
            tcp = Pose.from_transform(chain.forward(q))
            wanted = mapping.target_twist(command.gesture, tcp)
            cosine = float(
                np.dot(wanted, twist) / (np.linalg.norm(wanted) * np.linalg.norm(twist) or 1.0)
            )
            if cosine >= ALIGNED_COSINE:
                report.aligned += 1
            else:
                report.misaligned += 1
            return
        if command.end_s < stream_s <= command.nudge_end_s + TICK_SLACK_S:
            report.moving_in_nudges += 1
            return
    report.moving_outside_commands += 1


def _lift_offs(
    report: WireReport,
    commands: list[Command],
    tick_t: np.ndarray,
    tick_clock: np.ndarray,
    received_mono: np.ndarray,
    twists: list[dict[str, Any]],
    true_lifts_s: list[float],
) -> None:
    zero = np.array([not any(r["twist"]) for r in twists], dtype=bool)

    def first_zero_after(clock: float) -> float | None:
        later = np.flatnonzero((received_mono >= clock) & zero)
        return float(received_mono[later[0]]) if len(later) else None

    def at_rest(clock: float) -> bool:
        """Whether the last twist received before ``clock`` was zero (or there was none)."""
        before = np.flatnonzero(received_mono < clock)
        return not len(before) or bool(zero[before[-1]])

    def clock_at(stream_s: float) -> float:
        """The backend clock of the tick before ``stream_s`` (when that tick ended)."""
        i = max(int(np.searchsorted(tick_t, stream_s)) - 1, 0)
        return float(tick_clock[i])

    for command in commands:
        if command.end_reason != LIFT_OFF:
            continue
        start = clock_at(command.end_s)
        if at_rest(start):
            continue  # nothing moved (a pose gesture with no stored pose): nothing to stop
        report.lift_offs += 1
        arrived = first_zero_after(start)
        if arrived is None:
            continue
        nudged = command.nudge_end_s > command.end_s + TICK_SLACK_S
        target = report.nudge_lift_to_zero_ms if nudged else report.lift_to_zero_ms
        target.append(1000.0 * (arrived - start))
    for lift in true_lifts_s:
        start = clock_at(lift)
        if at_rest(start):
            continue
        arrived = first_zero_after(start)
        if arrived is not None:
            report.true_lift_to_zero_ms.append(1000.0 * (arrived - start))


@dataclass(frozen=True)
class SilenceReport:
    """What happened when the joint states stopped while the arm moved."""

    stopped_at_ns: int | None
    to_zero_ms: float | None  # last joint state -> first zero twist received
    moving_after_zero: int  # moving twists received after that zero twist
    moved_after_zero_rad: float  # how far the joints went after it

    def to_dict(self) -> dict[str, Any]:
        return {
            "to_zero_ms": self.to_zero_ms,
            "moving_after_zero": self.moving_after_zero,
            "moved_after_zero_rad": self.moved_after_zero_rad,
        }


def silence_report(log: list[dict[str, Any]]) -> SilenceReport:
    """How the client stopped the arm after the stand-in's joint states stopped."""
    stopped = next((r["wall_ns"] for r in log if r["event"] == "joint_states_stopped"), None)
    end = next((r for r in log if r["event"] == "end"), None)
    if stopped is None:
        return SilenceReport(None, None, 0, 0.0)
    after = [r for r in log if r["event"] == "twist" and r["wall_ns"] >= stopped]
    first_zero = next((r for r in after if not any(r["twist"])), None)
    if first_zero is None:
        return SilenceReport(stopped, None, sum(any(r["twist"]) for r in after), float("nan"))
    later = [r for r in after if r["wall_ns"] > first_zero["wall_ns"]]
    moving = sum(any(r["twist"]) for r in later)
    final_q = np.array(end["q"] if end is not None else first_zero["q"], dtype=float)
    moved = float(np.max(np.abs(final_q - np.array(first_zero["q"], dtype=float))))
    return SilenceReport(stopped, (first_zero["wall_ns"] - stopped) * 1e-6, moving, moved)
