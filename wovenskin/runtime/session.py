"""Opening a robot-control session: skin source, conditioning, recogniser, arbiter, mapping,
safety and robot wired together."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.poses import PoseStore
from wovenskin.control.safety import SafetyLimits
from wovenskin.control.session import ControlSession, SessionSettings
from wovenskin.control.trace import TraceWriter
from wovenskin.io import to_jsonable
from wovenskin.recognition.pipeline import (
    LivePipeline,
    PipelineSettings,
    arbiter_settings_for_model,
    conditioning_for_model,
    load_recognizer,
)
from wovenskin.recording.native import RecordingWriter
from wovenskin.robots.base import Robot
from wovenskin.robots.registry import make_robot
from wovenskin.runtime.sources import open_source, parse_spec
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.live_skin import LiveSkin


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
    pipeline_settings: Any = None,
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
    kind, _, options = parse_spec(skin)
    overrides = {"speed": 0} if fast_replay and kind == "replay" and "speed" not in options else {}
    for key, value in (source_options or {}).items():
        if key not in options:
            overrides[key] = value
    source = open_source(skin, **overrides)
    backend = make_robot(robot) if isinstance(robot, str) else robot
    conditioning = conditioning_for_model(recognizer)
    recorder = None
    context = {
        "session": {
            "robot": robot if isinstance(robot, str) else type(robot).__name__,
            "model": str(getattr(recognizer, "checkpoint_dir", model)),
            "mapping": str(mapping) if mapping is not None else "default",
            "limits": to_jsonable(asdict(limits or SafetyLimits())),
        },
    }
    if record is not None:
        used = conditioning or ConditioningConfig(sample_rate_hz=source.info.sample_rate_hz)
        recorded_settings = {"conditioning": used.to_dict(), **context}
        recorder = RecordingWriter(
            record, source.info, {"skin_source": skin}, recorded_settings, overwrite=overwrite
        )
    live_skin = LiveSkin(source, conditioning, on_message=on_message, recorder=recorder)
    if pipeline_settings is None:  # the execution rules recommended for this model
        pipeline_settings = PipelineSettings(arbiter=arbiter_settings_for_model(recognizer))
    pipeline = LivePipeline.for_live_skin(live_skin, recognizer, pipeline_settings)
    as_fast_as_read = str({**options, **overrides}.get("speed", "")) in ("0", "0.0")
    if as_fast_as_read and type(backend).step is not Robot.step:
        settings = replace(settings or SessionSettings(), wall_clock_stalls=False)
    session = ControlSession(
        live_skin,
        pipeline,
        backend,
        action_mapping,
        limits=limits,
        poses=pose_store,
        settings=settings,
        trace=trace,
        recorder=recorder,
        on_message=on_message,
        on_tick=on_tick,
    )
    session.recording_context = context
    return session
