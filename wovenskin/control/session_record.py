"""A control session's recording: started and stopped while it runs, and the notes its
parts write into it (commands, inputs, predictions, robot state, stops).

:class:`SessionRecorder` holds the ``.wsrec`` writer (the one the ``LiveSkin`` also writes
raw frames into) or none; :meth:`SessionRecorder.note` writes an annotation when a
recording runs and does nothing otherwise, so no part has to ask.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.control.session_state import SessionState
from wovenskin.recording.writer import RecordingWriter


class SessionRecorder:
    """The session's recording, if one runs (see the module docstring)."""

    def __init__(
        self, live_skin: Any, writer: Any = None, say: Callable[[str], None] = print
    ) -> None:
        self._live_skin = live_skin
        self.writer = writer
        self.context: dict[str, Any] = {}  # what a recording started later writes as settings
        self._say = say

    @property
    def active(self) -> bool:
        return self.writer is not None

    def start(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write raw frames, predictions, commands, robot state and stops to ``path``
        (``.wsrec``) from now on; ``FileExistsError`` unless ``overwrite``."""
        if self.writer is not None:
            raise RuntimeError(f"already recording to {self.writer.path}")
        settings = {"conditioning": self._live_skin.config.to_dict(), **self.context}
        writer = RecordingWriter(
            path, self._live_skin.info, {"skin_source": "live"}, settings, overwrite=overwrite
        )
        self.writer = writer
        self._live_skin.recorder = writer
        self._say(f"recording to {writer.path}")
        return Path(writer.path)

    def stop(self) -> Path | None:
        """Close the recording (every frame so far is on disk); returns its path."""
        writer, self.writer = self.writer, None
        self._live_skin.recorder = None
        if writer is None:
            return None
        writer.close()
        self._say(f"recording saved: {writer.path}")
        return Path(writer.path)

    def note(self, stream: str, t: float, payload: Any) -> None:
        """Annotate the recording at session time ``t``, when one runs."""
        if self.writer is not None:
            self.writer.add_annotation(stream, float(t), payload)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()


def robot_payload(state: SessionState) -> dict[str, Any]:
    """What a tick records of the robot: joints, TCP pose and speed, the commanded twist,
    the gesture, and the backend's clock (which ties stream time to the arm's)."""
    robot = state.robot
    assert robot is not None
    return {
        "q": np.asarray(robot.q, dtype=np.float64),
        "tcp": np.asarray(robot.tcp.position, dtype=np.float64),
        "quat": np.asarray(robot.tcp.quat, dtype=np.float64),
        "tcp_speed": robot.tcp_speed,
        "twist_command": np.asarray(state.twist, dtype=np.float64),
        "gesture": state.gesture,
        "robot_t": float(robot.t),
    }
