"""The packaged mapping file, ``default_mapping.toml``: the one home of the motion defaults.

Its ``[motion]``, ``[motion.profile]`` and ``[poses]`` values are the field defaults of
:class:`~wovenskin.control.mapping.MotionSettings` and
:class:`~wovenskin.control.profile.SpeedProfile` and the poses' ``hold_to_run``, in the
file's units (angles in degrees; :mod:`~wovenskin.control.mapping` turns them into
radians).  A key a user's mapping file leaves out therefore takes the value written in the
packaged file, and no module writes those values again (``docs/settings.md``).
"""

from __future__ import annotations

import tomllib
from importlib import resources
from typing import Any

DEFAULT_MAPPING_FILE = "default_mapping.toml"


def packaged_mapping_text() -> str:
    """The text of the packaged ``default_mapping.toml``."""
    return resources.files(__package__).joinpath(DEFAULT_MAPPING_FILE).read_text(encoding="utf-8")


_TABLES: dict[str, Any] = tomllib.loads(packaged_mapping_text())

MOTION: dict[str, Any] = {k: v for k, v in _TABLES["motion"].items() if k != "profile"}
"""The packaged ``[motion]`` table without its profile (angles in degrees)."""

PROFILE: dict[str, Any] = dict(_TABLES["motion"]["profile"])
"""The packaged ``[motion.profile]`` table."""

HOLD_TO_RUN: bool = bool(_TABLES["poses"]["hold_to_run"])
"""The packaged ``poses.hold_to_run``."""
