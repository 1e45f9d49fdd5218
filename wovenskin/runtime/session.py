"""Opening a robot-control session: the live chain (:mod:`wovenskin.runtime.pipeline`) with
mapping, safety and robot, optionally on a study task's scene and with inputs beside the skin."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace
from pathlib import Path
from typing import Any

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.poses import PoseStore
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.control.session import ControlSession
from wovenskin.control.session_inputs import CommandInput
from wovenskin.control.session_state import SessionSettings
from wovenskin.control.trace import TraceWriter
from wovenskin.errors import ConfigError
from wovenskin.io import to_jsonable
from wovenskin.recognition.pipeline import PipelineSettings, load_recognizer
from wovenskin.robots.base import Robot
from wovenskin.robots.registry import make_robot
from wovenskin.runtime.pipeline import open_live_pipeline
from wovenskin.runtime.sources import skin_spec
from wovenskin.skin.source import SkinSource
from wovenskin.tasks import WORKSPACE_LOWER, WORKSPACE_UPPER, Task, make_task

FAST_SPEEDS = ("0", "0.0")  # a source's speed option meaning "as fast as read"


def open_session(
    skin: str | SkinSource = "sim",
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
    task: str | Task | None = None,
    inputs: Iterable[CommandInput] = (),
) -> ControlSession:
    """Wire skin, conditioning, recogniser, arbiter, mapping, safety and robot.

    ``skin``: ``sim``, ``serial:PORT`` or ``replay:FILE`` (``fast_replay`` plays a replay
    as fast as possible unless its spec sets ``speed``, on a simulated arm only: an arm that
    moves on its own gets the stream in real time); ``robot``: ``sim``, ``tm:HOST``,
    ``ur:HOST`` or a backend object; ``model``: a checkpoint directory (default: the
    shipped model) unless a ``recognizer`` object is given; ``pipeline_settings``: the
    execution rules (default: the model's recommended arbiter settings); ``record``: a
    ``.wsrec`` path for the skin frames, predictions, commands and robot state;
    ``source_options``: spec options to add where the spec does not set them.

    ``skin`` may be a source object (a simulated operator's skin), read as fast as it
    delivers.  ``skin`` ``none`` is no skin (idle frames keep the clock: keyboard or pendant only).
    ``task`` (a name such as ``pick_place`` or a :class:`~wovenskin.tasks.Task`) puts the
    simulated arm in that task's scene: the robot is ``task.robot()`` (``robot`` must be
    ``sim``), the limits default to the tasks' workspace box, and the session's ``task``
    attribute holds it (``None`` without a task).  ``inputs`` are polled every tick
    beside the skin (:meth:`~wovenskin.control.session.ControlSession.add_input`).
    """
    scene = task_for_session(task, robot)
    if scene is not None:
        robot = scene.robot()
        if limits is None:
            limits = task_limits()
    recognizer = recognizer if recognizer is not None else load_recognizer(model)
    action_mapping = ActionMapping.load(mapping)
    pose_store = PoseStore.load(poses)
    backend = make_robot(robot) if isinstance(robot, str) else robot
    simulated = type(backend).step is not Robot.step  # a real arm moves in real time only
    defaults: dict[str, Any] = {}
    if fast_replay and simulated and isinstance(skin, str) and skin_spec(skin).kind == "replay":
        defaults["speed"] = 0
    defaults.update(source_options or {})
    chain = open_live_pipeline(
        skin,
        recognizer=recognizer,
        settings=pipeline_settings,
        on_message=on_message,
        defaults=defaults,
    )
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
    if as_fast_as_read and simulated:
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
    if scene is not None:
        context["session"]["task"] = scene.name
    session.recording_context = context
    session.task = scene  # type: ignore[attr-defined]  # the session's scene, if any
    for source in inputs:
        session.add_input(source)
    note = _unrecognised_note(action_mapping, session.state.class_names)
    if note:  # a custom gesture mapped before a model learnt it: say so, once
        session.state.messages.append(note)
        if on_message is not None:
            on_message(note)
    return session


def _unrecognised_note(mapping: ActionMapping, class_names: tuple[str, ...]) -> str:
    """One line naming the mapped gestures the model does not recognise ("" if none)."""
    missing = [name for name in mapping.actions if class_names and name not in class_names]
    if not missing:
        return ""
    return (
        f"mapping: the model does not recognise {', '.join(map(repr, missing))}; adapt it on "
        "recordings of them (docs/custom-gestures.md)"
    )


def task_for_session(task: str | Task | None, robot: str | Robot) -> Task | None:
    """The task a session runs on (``None`` for none); a task with a robot other than
    ``sim`` is one :class:`ConfigError` line: tasks run on the simulated arm."""
    if task is None:
        return None
    if not (isinstance(robot, str) and robot.strip().lower() == "sim"):
        name = robot if isinstance(robot, str) else type(robot).__name__
        raise ConfigError(
            f"robot {name!r} with a task: tasks run on the simulated arm (use --robot sim)"
        )
    return make_task(task) if isinstance(task, str) else task


def task_limits() -> SafetyLimits:
    """The default safety limits on a task's scene: the tasks' workspace box, low enough
    for the gripper to reach the table."""
    return SafetyLimits(
        workspace_lower=WORKSPACE_LOWER.copy(), workspace_upper=WORKSPACE_UPPER.copy()
    )
