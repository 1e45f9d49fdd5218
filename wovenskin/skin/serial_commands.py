"""Host commands to a serial skin and their acknowledgements (``docs/protocol.md``).

:class:`CommandLink` numbers the commands a :class:`~wovenskin.skin.serial_source.
SerialSkinSource` sends (start, stop, recalibrate, get_info), encodes them, and matches the
device's ACKs to them: a command not acknowledged within :data:`ACK_TIMEOUT_S`, or refused,
becomes one line for the source to report. ``GET_INFO`` is answered by an INFO, not an
ACK. Not thread-safe on its own: the source calls it under its lock.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

from wovenskin.skin.messages import AckMessage, AckStatus, CommandId, CommandMessage
from wovenskin.skin.protocol import encode_message

ACK_TIMEOUT_S = 1.0
SEQ_MASK = 0xFFFFFFFF


class CommandLink:
    """The commands waiting to go out, and those waiting for their ACK."""

    def __init__(self) -> None:
        self._outgoing: deque[CommandId] = deque()
        self._seq = 0
        self._awaiting: dict[int, tuple[str, float]] = {}  # seq -> (name, sent at)
        self.acks: deque[AckMessage] = deque(maxlen=64)  # the latest ACKs, for callers

    def queue(self, command: CommandId) -> None:
        """Send ``command`` with the next batch."""
        self._outgoing.append(command)

    def queue_first(self, commands: Iterable[CommandId]) -> None:
        """Send ``commands`` before anything queued (a fresh connection's GET_INFO, START)."""
        self._outgoing.extendleft(list(commands)[::-1])

    def take(self, now: float, device_time_us: int) -> list[bytes]:
        """The wire bytes of every queued command; their ACKs are awaited from ``now``."""
        outgoing = []
        while self._outgoing:
            command = self._outgoing.popleft()
            seq, self._seq = self._seq, (self._seq + 1) & SEQ_MASK
            outgoing.append(encode_message(CommandMessage(seq, device_time_us, command)))
            if command != CommandId.GET_INFO:
                self._awaiting[seq] = (command.name.lower(), now)
        return outgoing

    def overdue(self, now: float) -> list[str]:
        """One line for each command whose ACK is later than :data:`ACK_TIMEOUT_S`."""
        late = [seq for seq, (_, sent) in self._awaiting.items() if now - sent > ACK_TIMEOUT_S]
        return [
            f"device did not acknowledge {self._awaiting.pop(seq)[0]!r} within "
            f"{ACK_TIMEOUT_S:.1f} s"
            for seq in late
        ]

    def acknowledged(self, ack: AckMessage) -> str | None:
        """Match ``ack`` to its command; one line when the device refused it."""
        self.acks.append(ack)
        try:
            default_name = CommandId(ack.command).name.lower()
        except ValueError:
            default_name = f"command {ack.command}"
        name, _ = self._awaiting.pop(ack.seq, (default_name, 0.0))
        if ack.ok:
            return None
        try:
            status = AckStatus(ack.status).name.lower().replace("_", " ")
        except ValueError:
            status = f"error {ack.status}"
        return f"device refused {name!r}: {status}"

    def forget_awaited(self) -> None:
        """The connection was lost: no ACK of what was sent will come."""
        self._awaiting.clear()
