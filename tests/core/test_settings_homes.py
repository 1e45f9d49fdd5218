"""The motion defaults live once, in the packaged mapping file (issue 25, "Settings").

``default_mapping.toml`` is the one home of the swipe speed and the other ``[motion]``,
``[motion.profile]`` and ``[poses]`` values: :class:`MotionSettings` and
:class:`SpeedProfile` take their defaults from it and never write them again.
"""

from __future__ import annotations

import ast
import inspect
import math

import wovenskin.control.mapping as mapping_module
import wovenskin.control.profile as profile_module
from wovenskin.control.mapping import ActionMapping, MotionSettings, PoseAction
from wovenskin.control.mapping_defaults import HOLD_TO_RUN, MOTION, PROFILE
from wovenskin.control.profile import SpeedProfile


def test_the_settings_defaults_are_the_packaged_files_values() -> None:
    packaged = ActionMapping.load()
    assert MotionSettings() == packaged.settings
    assert SpeedProfile() == packaged.settings.profile
    assert ActionMapping().settings == packaged.settings
    assert MotionSettings().linear_speed == MOTION["linear_speed"]  # the swipe speed
    assert MotionSettings().angular_speed == math.radians(MOTION["angular_speed"])
    assert SpeedProfile().to_dict() == PROFILE
    assert PoseAction("home").hold_to_run is HOLD_TO_RUN is packaged.hold_to_run


def test_a_mapping_file_without_motion_takes_the_packaged_values() -> None:
    bare = ActionMapping.from_text('[gestures]\nswipe_up = "translate +z"\n', "bare.toml")
    assert bare.settings == ActionMapping.load().settings
    assert bare.hold_to_run is HOLD_TO_RUN


def test_an_edited_speed_in_a_mapping_file_reaches_the_settings() -> None:
    faster = ActionMapping.from_text("[motion]\nlinear_speed = 0.08\n", "fast.toml")
    assert faster.settings.linear_speed == 0.08
    assert faster.settings.angular_speed == MotionSettings().angular_speed


def _literal_field_defaults(module, class_name: str) -> list[str]:
    """The fields of ``class_name`` whose default is written as a literal number or string."""
    tree = ast.parse(inspect.getsource(module))
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == class_name)
    literal = []
    for node in cls.body:
        if isinstance(node, ast.AnnAssign) and node.value is not None:
            value = node.value
            if isinstance(value, ast.Call) and value.args:  # math.radians(15.0)
                value = value.args[0]
            if isinstance(value, ast.Constant) and isinstance(value.value, int | float | str):
                literal.append(ast.unparse(node))
    return literal


def test_no_motion_default_is_written_again_in_code() -> None:
    assert _literal_field_defaults(mapping_module, "MotionSettings") == []
    assert _literal_field_defaults(profile_module, "SpeedProfile") == []
