"""Recording stand-ins for ur_rtde's RTDEControlInterface and RTDEReceiveInterface."""

from __future__ import annotations

import numpy as np


class FakeControl:
    """Records every call the adapter makes to RTDEControlInterface."""

    def __init__(self) -> None:
        self.calls: list[tuple] = []
        self.connected = True
        self.accept = True
        self.async_progress = -1

    def _record(self, name: str, *args) -> bool:
        self.calls.append((name, *args))
        return self.accept

    def names(self) -> list[str]:
        return [call[0] for call in self.calls]

    def isConnected(self) -> bool:
        return self.connected

    def setWatchdog(self, min_frequency: float) -> bool:
        return self._record("setWatchdog", min_frequency)

    def kickWatchdog(self) -> bool:
        return self._record("kickWatchdog")

    def speedL(self, xd, acceleration, time) -> bool:
        return self._record("speedL", list(xd), acceleration, time)

    def speedStop(self, a) -> bool:
        return self._record("speedStop", a)

    def moveJ(self, q, speed, acceleration, asynchronous) -> bool:
        return self._record("moveJ", list(q), speed, acceleration, asynchronous)

    def moveL(self, pose, speed, acceleration, asynchronous) -> bool:
        return self._record("moveL", list(pose), speed, acceleration, asynchronous)

    def stopL(self, a) -> bool:
        return self._record("stopL", a)

    def getAsyncOperationProgress(self) -> int:
        return self.async_progress

    def stopScript(self) -> None:
        self._record("stopScript")

    def disconnect(self) -> None:
        self._record("disconnect")


class FakeReceive:
    """Serves fixed RTDE readings."""

    def __init__(self) -> None:
        self.q = [0.1, -1.2, 1.3, -1.6, -1.57, 0.0]
        self.tcp = [0.3, -0.1, 0.5, 0.0, np.pi, 0.0]
        self.speed = [0.0] * 6
        self.protective = False
        self.emergency = False
        self.disconnected = False

    def getActualQ(self):
        return self.q

    def getActualQd(self):
        return [0.0] * 6

    def getActualTCPPose(self):
        return self.tcp

    def getActualTCPSpeed(self):
        return self.speed

    def isProtectiveStopped(self) -> bool:
        return self.protective

    def isEmergencyStopped(self) -> bool:
        return self.emergency

    def disconnect(self) -> None:
        self.disconnected = True
