"""URRobot's calls checked against the real ``ur_rtde`` 1.6.5 modules (no arm, no network).

``test_robots_ur`` drives the adapter with stand-ins written beside it, which would go on
passing if a call were renamed or given the wrong arguments.  Here the stand-ins are made
from the real ``rtde_control.RTDEControlInterface`` and ``rtde_receive.RTDEReceiveInterface``
classes (installed by the ``dev`` extra; nothing is connected): a method exists on the
stand-in only if the real class has it, and every call is bound to the real pybind11
signatures (their docstrings: overloads, parameter names, defaults, types) before it is
answered with a value of the real return type.  The adapter's own factories construct
them, so the constructors are checked too.  A scan of ``robots/ur/robot.py`` then shows
every method it calls on an RTDE object was driven and checked.
"""

from __future__ import annotations

import ast
import numbers
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import wovenskin.robots.ur.robot as ur_robot
from wovenskin.robots.base import RobotError
from wovenskin.robots.ur import URRobot
from wovenskin.robots.ur.models import ur_model

rtde_control = pytest.importorskip("rtde_control", reason="ur_rtde (the dev extra) is needed")
rtde_receive = pytest.importorskip("rtde_receive", reason="ur_rtde (the dev extra) is needed")

REAL = {
    "control": rtde_control.RTDEControlInterface,
    "receive": rtde_receive.RTDEReceiveInterface,
}
_SIGNATURE = re.compile(r"^(?:\d+\. )?(\w+)\((.*)\) -> (.+)$")


@dataclass(frozen=True)
class Parameter:
    name: str
    annotation: str
    has_default: bool


@dataclass(frozen=True)
class Signature:
    parameters: tuple[Parameter, ...]  # without self
    returns: str

    def __str__(self) -> str:
        shown = ", ".join(f"{p.name}: {p.annotation}" + (" = ..." if p.has_default else "")
                          for p in self.parameters)  # fmt: skip
        return f"({shown}) -> {self.returns}"


def _split(text: str) -> list[str]:
    """Split a pybind11 parameter list at its top-level commas."""
    parts, depth, current = [], 0, ""
    for char in text:
        depth += char in "[(<"
        depth -= char in "])>"
        if char == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += char
    return [*parts, current.strip()] if current.strip() else parts


def signatures(cls: type, name: str) -> list[Signature]:
    """The pybind11 signatures (one per overload) of ``cls.name``, from its docstring."""
    found = []
    for line in (getattr(cls, name).__doc__ or "").splitlines():
        match = _SIGNATURE.match(line.strip())
        if not match or match.group(1) != name or match.group(2).startswith("*args"):
            continue
        parameters = []
        for part in _split(match.group(2))[1:]:  # [0] is self
            declared, _, default = part.partition(" = ")
            pname, _, annotation = declared.partition(": ")
            parameters.append(Parameter(pname, annotation, bool(default)))
        found.append(Signature(tuple(parameters), match.group(3).strip()))
    assert found, f"no signature found in the docstring of {cls.__name__}.{name}"
    return found


def _fits(value: Any, annotation: str) -> bool:
    """Whether ``value`` fits a parameter declared ``annotation``.  Stricter than
    pybind11's implicit conversions on purpose: a bool where a number is declared, or a
    number where a bool is, would be converted silently, and is a bug in the adapter."""
    if annotation == "float":
        return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)
    if annotation == "int":
        return isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_)
    if annotation == "bool":
        return isinstance(value, bool | np.bool_)
    if annotation == "str":
        return isinstance(value, str)
    if annotation.startswith("list[") and annotation.endswith("]"):
        inner = annotation[5:-1]
        sequence = isinstance(value, list | tuple) or (
            isinstance(value, np.ndarray) and value.ndim >= 1
        )
        return sequence and all(_fits(v, inner) for v in value)
    raise AssertionError(f"this test does not know the pybind11 type {annotation!r}")


def binds(signature: Signature, args: tuple, kwargs: dict) -> bool:
    """Whether ``(args, kwargs)`` bind to ``signature`` with fitting types."""
    parameters = signature.parameters
    if len(args) > len(parameters):
        return False
    given = dict(zip((p.name for p in parameters), args, strict=False))
    for key, value in kwargs.items():
        if key in given or key not in {p.name for p in parameters}:
            return False
        given[key] = value
    for p in parameters:
        if p.name not in given and not p.has_default:
            return False
        if p.name in given and not _fits(given[p.name], p.annotation):
            return False
    return True


def _answer(returns: str, canned: Any) -> Any:
    """A value of the real return type (``canned`` where the test gives one)."""
    if canned is not None:
        return canned
    return {"bool": True, "None": None, "int": -1, "float": 0.0, "list[float]": [0.0] * 6}[returns]


class RealShaped:
    """A stand-in with only the real class's methods, each call bound to its signatures."""

    def __init__(self, kind: str, log: list, answers: dict[str, Any], *args, **kwargs) -> None:
        self._kind, self._log, self._answers = kind, log, answers
        self._call("__init__", args, kwargs)

    def _call(self, name: str, args: tuple, kwargs: dict) -> Any:
        real = REAL[self._kind]
        if not hasattr(real, name):
            self._log.append((self._kind, name, "missing"))
            raise AssertionError(f"{real.__name__} has no method {name}")
        for signature in signatures(real, name):
            if binds(signature, args, kwargs):
                self._log.append((self._kind, name, "ok"))
                return _answer(signature.returns, self._answers.get(name))
        shown = "; ".join(str(s) for s in signatures(real, name))
        self._log.append((self._kind, name, f"args {args!r} {kwargs!r} fit none of {shown}"))
        raise AssertionError(f"{real.__name__}.{name}{args!r} fits none of {shown}")

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return lambda *args, **kwargs: self._call(name, args, kwargs)


Q = [0.1, -1.2, 1.3, -1.6, -1.57, 0.0]


@pytest.fixture
def log(monkeypatch) -> list:
    """Replaces the real classes in the real modules: the adapter's factories build these."""
    calls: list = []
    flange = ur_model("ur5e").flange_pose(np.array(Q))  # the arm reports its flange as TCP
    tcp = [*flange[:3, 3].tolist(), *Rotation.from_matrix(flange[:3, :3]).as_rotvec().tolist()]
    answers = {
        "control": {},
        "receive": {
            "getActualQ": Q,
            "getActualTCPPose": tcp,
            "isEmergencyStopped": False,
            "isProtectiveStopped": False,
        },
    }
    for kind, module in (("control", rtde_control), ("receive", rtde_receive)):
        name = REAL[kind].__name__
        monkeypatch.setattr(
            module, name, lambda *a, _k=kind, **kw: RealShaped(_k, calls, answers[_k], *a, **kw)
        )
    return calls


def test_every_call_fits_the_real_ur_rtde_api(log) -> None:
    arm = URRobot("10.0.0.5", model="ur5e")  # the default factories import ur_rtde
    arm.connect()  # constructors, setWatchdog, getActualQ / getActualTCPPose
    arm.state()
    arm.send_twist(np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.02]))
    arm.move_to_joints(np.array(Q) + 0.05)  # speedStop after the twist, moveJ
    arm.state()  # getAsyncOperationProgress
    arm.send_twist(np.zeros(6))  # stopL ends the move
    arm.move_to_pose(arm.state().tcp, speed=0.05)  # moveL
    arm.stop()
    arm.disconnect()  # stopScript, both disconnects
    bad = [entry for entry in log if entry[2] != "ok"]
    assert not bad, bad


def test_a_refused_watchdog_releases_both_real_shaped_interfaces(log, monkeypatch) -> None:
    """The connect error path (``_release``) calls disconnect on both."""
    answers_false = {"setWatchdog": False}
    module, name = rtde_control, REAL["control"].__name__
    monkeypatch.setattr(module, name, lambda *a, **kw: RealShaped("control", log, answers_false,
                                                                  *a, **kw))  # fmt: skip
    with pytest.raises(RobotError, match="refused the RTDE watchdog"):
        URRobot("10.0.0.5").connect()
    assert [(kind, name) for kind, name, _ in log if name == "disconnect"] == [
        ("control", "disconnect"),
        ("receive", "disconnect"),
    ]
    assert all(status == "ok" for *_, status in log), log


def _called_on_rtde() -> dict[str, set[str]]:
    """Method names robot.py calls on an RTDE object, by which: ``control`` / ``receive``
    (local names and ``self._control`` / ``self._receive``) and ``interface`` (either)."""
    tree = ast.parse(Path(ur_robot.__file__).read_text(encoding="utf-8"))
    found: dict[str, set[str]] = {"control": set(), "receive": set(), "interface": set()}
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)):
            continue
        owner = node.func.value
        name = owner.id if isinstance(owner, ast.Name) else None
        if isinstance(owner, ast.Attribute) and isinstance(owner.value, ast.Name):
            name = owner.attr.removeprefix("_") if owner.value.id == "self" else None
        if name in found:
            found[name].add(node.func.attr)
    return found


def test_every_rtde_method_robot_py_names_exists_and_was_checked(log) -> None:
    test_every_call_fits_the_real_ur_rtde_api(log)
    checked = {(kind, name) for kind, name, _ in log}
    called = _called_on_rtde()
    assert called["control"] and called["receive"]  # the scan sees the adapter's calls
    for kind in ("control", "receive"):
        for name in sorted(called[kind]):
            assert hasattr(REAL[kind], name), f"{REAL[kind].__name__} has no {name}"
            assert (kind, name) in checked, f"{kind}.{name} is never driven by this test"
    for name in called["interface"]:
        assert all(hasattr(cls, name) for cls in REAL.values()), name


def test_the_installed_ur_rtde_is_the_pinned_one() -> None:
    from importlib.metadata import version

    assert version("ur_rtde") == "1.6.5"
