"""The page's commands: what each ``{"cmd": name, ...}`` from the dashboard does.

:data:`COMMANDS` names every command a page may send (the runner refuses others when they
are submitted); :func:`carry_out` carries one out on the session thread, between steps:
the arm's stop and resume, poses, recording, speed, the simulated person, the skin, robot,
task and interface, the gripper, trials, questionnaires, the plan and the adapt panel.
A command that cannot be carried out raises; the runner reports it as one line in the
page's messages and goes on.
"""

from __future__ import annotations

from datetime import datetime
from typing import TYPE_CHECKING

from wovenskin.control.session import ControlSession
from wovenskin.errors import ConfigError
from wovenskin.tasks import TASKS
from wovenskin.ui.dashboard.adapt_flow import BLOCKED_WHILE_RECORDING
from wovenskin.ui.dashboard.plan import next_step
from wovenskin.ui.dashboard.questionnaire import record_answers
from wovenskin.ui.dashboard.teleop import check_interface

if TYPE_CHECKING:
    from wovenskin.ui.dashboard.runner import DashboardRunner

COMMANDS = (
    "stop",
    "resume",
    "calibrate",
    "home",
    "initial",
    "set_initial",
    "record",
    "speed",
    "perform",
    "autoplay",
    "switch",
    "task",
    "interface",
    "gripper",
    "trial",
    "questionnaire",
    "plan",
    "adapt",
)
"""The commands a page may send (``note`` comes from :meth:`DashboardRunner.note` only)."""


def carry_out(runner: DashboardRunner, command: dict) -> None:
    """Carry out one page command on the session thread; a ConfigError (or another
    exception) for one that cannot be, which the runner reports as one line."""
    session = runner.session
    assert session is not None
    name = command["cmd"]
    if runner.adapt.recording_now and name in BLOCKED_WHILE_RECORDING:
        raise ConfigError("recording for adapt: the arm stays held until it ends (or Cancel)")
    if name == "stop":
        session.emergency_stop("stop button")
    elif name == "resume":
        session.resume()
    elif name == "calibrate":
        session.live_skin.recalibrate()
        session.state.messages.append("recalibrating: keep hands off the skin")
    elif name in ("home", "initial"):
        session.go_to_pose(name)
    elif name == "set_initial":
        session.store_pose("initial")
    elif name == "record":
        if command.get("on", not session.recording):
            if not session.recording:
                stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
                runner.record_dir.mkdir(parents=True, exist_ok=True)
                session.start_recording(runner.record_dir / f"dashboard-{stamp}.wsrec")
        else:
            session.stop_recording()
    elif name == "speed":
        session.set_speed_scale(float(command.get("value", 1.0)))
    elif name == "perform":
        source = runner._sim_source()
        if source is None:
            raise ConfigError("only the simulated skin can perform gestures")
        source.perform(str(command.get("gesture", "")))
        session.state.messages.append(f"the simulated person performs {command['gesture']}")
    elif name == "autoplay":
        source = runner._sim_source()
        if source is None:
            raise ConfigError("only the simulated skin has a simulated person")
        source.autonomous = bool(command.get("on", True))
    elif name == "note":  # from note(), never from a page
        session.state.messages.append(command["text"])
    elif name == "switch":
        runner._switch(
            str(command.get("skin") or runner.skin_spec),
            str(command.get("robot") or runner.robot_spec),
            runner.task_name,
        )
    elif name == "task":
        task = command.get("task")
        runner._switch(runner.skin_spec, runner.robot_spec, checked_task(task))
    elif name == "interface":
        if runner.study.running:
            raise ConfigError("a trial is running: end it before changing the interface")
        runner.inputs.choose(check_interface(command.get("interface")), session)
        if (scale := runner.inputs.speed()) is not None:
            session.set_speed_scale(scale)
        session.state.messages.append(f"interface: {runner.inputs.interface}")
    elif name == "gripper":
        runner.inputs.gripper(session)
    elif name == "trial":
        _trial(runner, session, str(command.get("op")), command.get("participant"))
    elif name == "plan":  # the page's participant changed: where they stand
        runner.plan = next_step(runner.study.study_dir, command.get("participant"))
    elif name == "questionnaire":
        session.state.messages.append(record_answers(runner.study.study_dir, command))
    elif name == "adapt":
        runner.adapt.command(runner, session, command)


def _trial(runner: DashboardRunner, session: ControlSession, op: str, participant: object) -> None:
    """Start a trial or end the running one (``op``: its outcome); the plan moves on."""
    t = float(session.now)
    if op == "start":
        line = runner.study.start(session, runner.task, runner.inputs.interface, participant, t)
    else:
        line = runner.study.end(t, op)
    session.state.messages.append(line)
    runner._replan(participant)


def checked_task(task: object) -> str | None:
    """A task name of the registry, or ``None`` for none (``"none"`` or empty)."""
    if task in (None, "", "none"):
        return None
    if task not in TASKS:
        raise ConfigError(f"unknown task {str(task)[:40]!r}; known: none, {', '.join(TASKS)}")
    return str(task)
