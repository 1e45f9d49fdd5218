"""An attribute of a composite object that is one of its parts' own."""

from __future__ import annotations

from typing import Any


class Delegated:
    """A session attribute that is a part's own (``session.command_log`` is
    ``session.inputs.command_log``): read, and set where ``settable``."""

    def __init__(self, part: str, name: str, settable: bool = False) -> None:
        self.part, self.name, self.settable = part, name, settable

    def __get__(self, session: Any, owner: type | None = None) -> Any:
        if session is None:
            return self
        return getattr(getattr(session, self.part), self.name)

    def __set__(self, session: Any, value: Any) -> None:
        if not self.settable:
            raise AttributeError(f"set {self.name} on session.{self.part}")
        setattr(getattr(session, self.part), self.name, value)
