"""Commands for ROS 2 without a ROS install: the stand-in for MoveIt Servo."""

from __future__ import annotations

from pathlib import Path

import typer

from wovenskin.cli.app import HELP_STYLE, app, err_console, user_errors
from wovenskin.errors import ConfigError

ros2_app = typer.Typer(
    help="ROS 2 without a ROS install (wovenskin[ros2]): a stand-in MoveIt Servo.",
    no_args_is_help=True,
    rich_markup_mode=HELP_STYLE,
)
app.add_typer(ros2_app, name="ros2")


@ros2_app.command("servo-standin")
@user_errors
def servo_standin(
    domain: int = typer.Option(
        None, min=0, max=232, help="ROS domain id (default: ROS_DOMAIN_ID, else 0)."
    ),
    twist: str = typer.Option("/servo_node/delta_twist_cmds", help="TwistStamped topic taken."),
    joints: str = typer.Option("/joint_states", help="JointState topic published."),
    servo: str = typer.Option("/servo_node", help="Node name of its switch_command_type."),
    rate: float = typer.Option(
        100.0, min=1.0, max=1000.0, help="Integration and joint-state rate, Hz (10-1000)."
    ),
    urdf: Path = typer.Option(None, help="The arm's URDF (default: the packaged TM5-900)."),
    base: str = typer.Option(None, help="The URDF's base link (with --urdf)."),
    tip: str = typer.Option(None, help="The URDF's tip link, Servo's ee_frame (with --urdf)."),
    log: Path = typer.Option(None, help="Write every twist received as a JSON line here."),
    seconds: float = typer.Option(
        None, min=0.01, max=604800, help="Stop after this long (default: Ctrl-C)."
    ),
    silence_after: float = typer.Option(
        None,
        min=0.0,
        max=86400.0,
        help="Stop publishing joint states this long after the arm starts moving.",
    ),
    any_mode: bool = typer.Option(
        False, "--any-mode", help="Follow twists without a switch_command_type call first."
    ),
) -> None:
    """Stand in for MoveIt Servo and the arm's driver: follow twists, publish joint states."""
    import contextlib
    import signal

    from wovenskin.robots.ros2.standin import StandinServo, StandinSettings
    from wovenskin.robots.sim import tm5_900
    from wovenskin.robots.urdf import load_urdf_chain

    if not 10.0 <= rate <= 1000.0:
        raise ConfigError(f"--rate must be 10-1000 Hz, got {rate}")
    if urdf is None:
        chain = tm5_900.urdf_chain()
    elif base is None or tip is None:
        raise ConfigError("--urdf needs --base and --tip")
    else:
        chain = load_urdf_chain(urdf, base, tip)
    settings = StandinSettings(
        twist_topic=twist, joints_topic=joints, servo=servo, rate_hz=rate,
        require_twist_mode=not any_mode, silence_after_s=silence_after,
    )  # fmt: skip
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a terminate ends it cleanly
    with contextlib.ExitStack() as stack:
        out = stack.enter_context(log.open("w", encoding="utf-8")) if log is not None else None
        standin = StandinServo(chain, tm5_900.INITIAL_Q, settings, domain=domain, log=out)
        stack.callback(standin.close)
        print(f"ready: stand-in Servo on ROS 2 domain {standin.node.domain_id}", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            standin.run(seconds)
        err_console.print(f"{standin.received} twists received", highlight=False)
