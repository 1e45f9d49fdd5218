"""wovenskin.errors: user errors share one root and keep the builtin each refines."""

from __future__ import annotations

from wovenskin.errors import ConfigError, DataError, DeviceError, WovenskinError
from wovenskin.outputs import OutputExistsError
from wovenskin.recording.untrusted import FormatError
from wovenskin.robots.base import RobotError
from wovenskin.skin.messages import ProtocolError
from wovenskin.specs import SpecError


def test_the_project_errors_share_the_root_and_their_builtins() -> None:
    assert issubclass(ConfigError, ValueError) and issubclass(DataError, ValueError)
    assert issubclass(DeviceError, ConnectionError)
    for error in (ConfigError, DataError, DeviceError, OutputExistsError, FormatError,
                  RobotError, ProtocolError, SpecError):  # fmt: skip
        assert issubclass(error, WovenskinError), error
    assert issubclass(OutputExistsError, FileExistsError) and issubclass(RobotError, RuntimeError)
