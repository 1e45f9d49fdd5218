"""Opening a robot-control session: the live chain (:mod:`wovenskin.runtime.pipeline`) with
mapping, safety and robot."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.poses import PoseStore
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.control.session import ControlSession
from wovenskin.control.session_state import SessionSettings
from wovenskin.control.trace import TraceWriter
from wovenskin.io import to_jsonable
from wovenskin.recognition.pipeline import PipelineSettings, load_recognizer
from wovenskin.robots.base import Robot
from wovenskin.robots.registry import make_robot
from wovenskin.runtime.pipeline import open_live_pipeline
from wovenskin.runtime.sources import skin_spec

FAST_SPEEDS = ("0", "0.0")  # a source's speed option meaning "as fast as read"


def open_session(
    skin: str = "sim",
    robot: str | Robot = "sim",
    model: str | Path | None = None,
    *,
    fast_replay: bool = False,
    mapping: str | Path | None = None,
    poses: str | Path | None = None,
    limits: SafetyLimits | None = None,
    trace: TraceWriter | None = None,
    record: str | Path | None = None,
    overwrite: bool = False,
    recognizer: Any = None,
    pipeline_settings: PipelineSettings | None = None,
    settings: SessionSettings | None = None,
    on_message: Callable[[str], None] | None = None,
    on_tick: Callable[[ControlSession], None] | None = None,
    source_options: dict[str, Any] | None = None,
) -> ControlSession:
    """Wire skin, conditioning, recogniser, arbiter, mapping, safety and robot.

    ``skin``: ``sim``, ``serial:PORT`` or ``replay:FILE`` (``fast_replay`` plays a replay
    as fast as possible unless its spec sets ``speed``); ``robot``: ``sim``, ``tm:HOST``,
    ``ur:HOST`` or a backend object; ``model``: a checkpoint directory (default: the
    shipped model) unless a ``recognizer`` object is given; ``pipeline_settings``: the
    execution rules (default: the model's recommended arbiter settings); ``record``: a
    ``.wsrec`` path for the skin frames, predictions, commands and robot state;
    ``source_options``: spec options to add where the spec does not set them.
    """
    recognizer = recognizer if recognizer is not None else load_recognizer(model)
    action_mapping = ActionMapping.load(mapping)
    pose_store = PoseStore.load(poses)
    defaults: dict[str, Any] = {}
    if fast_replay and skin_spec(skin).kind == "replay":
        defaults["speed"] = 0
    defaults.update(source_options or {})
    chain = open_live_pipeline(
        skin,
        recognizer=recognizer,
        settings=pipeline_settings,
        on_message=on_message,
        defaults=defaults,
    )
    backend = make_robot(robot) if isinstance(robot, str) else robot
    context = {
        "session": {
            "robot": robot if isinstance(robot, str) else type(robot).__name__,
            "model": str(getattr(recognizer, "checkpoint_dir", model)),
            "mapping": str(mapping) if mapping is not None else "default",
            "limits": to_jsonable(limits or SafetyLimits()),
        },
    }
    if record is not None:  # once the robot is built too: a bad robot spec leaves no file
        chain.record(record, overwrite=overwrite, settings=context)
    as_fast_as_read = chain.spec.options.get("speed") in FAST_SPEEDS
    if as_fast_as_read and type(backend).step is not Robot.step:
        settings = replace(settings or SessionSettings(), wall_clock_stalls=False)
    session = ControlSession(
        chain.live_skin,
        chain.pipeline,
        backend,
        action_mapping,
        limits=limits,
        poses=pose_store,
        settings=settings,
        trace=trace,
        recorder=chain.recorder,
        on_message=on_message,
        on_tick=on_tick,
    )
    session.recording_context = context
    return session
