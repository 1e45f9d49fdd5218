"""What a control session writes into its recording, and the predictions views show.

:class:`SessionRecording` is the part of :class:`~wovenskin.control.session.ControlSession`
that starts and stops a ``.wsrec`` recording while the session runs and, per block and
tick, keeps the recogniser's latest probabilities (and its hesitation,
:func:`~wovenskin.control.session_state.unsure_line`) for the views and writes them and
the robot's state as annotations.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from wovenskin.control.session_state import UNSURE_HOLD_S, min_probability_of, unsure_line
from wovenskin.recording.writer import RecordingWriter


class SessionRecording:
    """Recording and predictions of :class:`~wovenskin.control.session.ControlSession`."""

    @property
    def recording(self) -> bool:
        return self.recorder is not None

    def start_recording(self, path: str | Path, overwrite: bool = False) -> Path:
        """Write raw frames, predictions, commands, robot state and stops to ``path``
        (``.wsrec``) from now on; ``FileExistsError`` unless ``overwrite``."""
        if self.recorder is not None:
            raise RuntimeError(f"already recording to {self.recorder.path}")
        settings = {"conditioning": self.live_skin.config.to_dict(), **self.recording_context}
        recorder = RecordingWriter(
            path, self.live_skin.info, {"skin_source": "live"}, settings, overwrite=overwrite
        )
        self.recorder = recorder
        self.live_skin.recorder = recorder
        self._message(f"recording to {recorder.path}")
        return Path(recorder.path)

    def stop_recording(self) -> Path | None:
        """Close the recording (every frame so far is on disk); returns its path."""
        recorder, self.recorder = self.recorder, None
        self.live_skin.recorder = None
        if recorder is None:
            return None
        recorder.close()
        self._message(f"recording saved: {recorder.path}")
        return Path(recorder.path)

    def _record_predictions(self, t: float) -> None:
        probabilities = getattr(self.pipeline, "latest_probabilities", None)
        if probabilities is None:
            return
        probabilities = np.asarray(probabilities, dtype=np.float32)
        self.state.probabilities = probabilities
        if probabilities.size and self.state.class_names:
            k = int(np.argmax(probabilities))
            self.state.top = (self.state.class_names[k], float(probabilities[k]))
            self._note_unsure(t, probabilities)
        if self.recorder is not None:
            top, p = self.state.top
            payload = {"top": top, "p": p, "probabilities": probabilities}
            self.recorder.add_annotation("predictions", t, payload)

    def _note_unsure(self, t: float, probabilities: np.ndarray) -> None:
        """Keep the recogniser's hesitation for the views: while fingers are on the skin
        and no command runs, the two likeliest gestures when the best one is at least
        :data:`UNSURE_FLOOR` but would not fire (below the model's ``min_probability``,
        or ``invalid`` ranks first).  The line stays :data:`UNSURE_HOLD_S` after the touch,
        so a user sees how the gesture was read and can draw it better."""
        names = self.state.class_names
        if self.state.gesture is not None:
            self.state.unsure, self.state.unsure_t = "", None
            return
        line = unsure_line(probabilities, names, min_probability_of(self.pipeline))
        contacts = getattr(getattr(self.live_skin, "state", None), "contacts", None)
        if line and contacts:
            self.state.unsure, self.state.unsure_t = line, t
        elif self.state.unsure_t is not None and t - self.state.unsure_t > UNSURE_HOLD_S:
            self.state.unsure, self.state.unsure_t = "", None

    def _record_robot(self, t: float) -> None:
        robot = self.state.robot
        assert robot is not None
        payload = {
            "q": np.asarray(robot.q, dtype=np.float64),
            "tcp": np.asarray(robot.tcp.position, dtype=np.float64),
            "quat": np.asarray(robot.tcp.quat, dtype=np.float64),
            "tcp_speed": robot.tcp_speed,
            "twist_command": np.asarray(self.state.twist, dtype=np.float64),
            "gesture": self.state.gesture,
            "robot_t": float(robot.t),  # the backend's clock: ties stream time to the arm's
        }
        self.recorder.add_annotation("robot", t, payload)
