"""Script lines as the fake Techman controller reads them: one function call and its arguments."""

from __future__ import annotations

import re

import numpy as np

CALL = re.compile(r"^([A-Za-z_]\w*)\((.*)\)$")
NUMBER = re.compile(r"^[-+]?(\d+(\.\d*)?|\.\d+)$")


class ScriptError(Exception):
    """A script line the controller refuses (answered ``ERROR;line``)."""


def _split_args(text: str) -> list[str]:
    """``text`` split at the commas outside quotes and parentheses."""
    parts, depth, current, quoted = [], 0, [], False
    for char in text:
        if char == '"':
            quoted = not quoted
        elif not quoted and char == "(":
            depth += 1
        elif not quoted and char == ")":
            depth -= 1
        if char == "," and not quoted and depth == 0:
            parts.append("".join(current))
            current = []
        else:
            current.append(char)
    parts.append("".join(current))
    return parts


def parse_args(text: str) -> list[object]:
    """A call's argument text as values: quoted strings, ``true``/``false`` and numbers."""
    if not text.strip():
        return []
    args: list[object] = []
    for raw in _split_args(text):
        item = raw.strip()
        if len(item) >= 2 and item[0] == item[-1] == '"':
            args.append(item[1:-1])
        elif item in ("true", "false"):
            args.append(item == "true")
        elif NUMBER.match(item):
            args.append(float(item))
        else:
            raise ScriptError(f"bad argument {item!r}")
    return args


def numbers(args: list[object], count: int, name: str) -> np.ndarray:
    """Exactly ``count`` numeric arguments of function ``name``, as floats."""
    if len(args) != count or not all(isinstance(a, float) for a in args):
        raise ScriptError(f"{name} takes {count} numbers, got {len(args)} arguments")
    return np.array(args, dtype=float)
