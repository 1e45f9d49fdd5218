"""Tests of the skin-registered mapping (``motion.frame = "skin"``): a swipe moves the tool
the way the finger moved on the skin patch as it is mounted on the simulated TM5-900."""

from __future__ import annotations

import io
from importlib import resources

import mujoco
import numpy as np
import pytest
from stand_ins import ContactMeans

from wovenskin.control.mapping import (
    SKIN_RIGHT_IN_TOOL,
    SKIN_UP_IN_TOOL,
    ActionMapping,
    MotionSettings,
)
from wovenskin.control.trace import TraceWriter
from wovenskin.errors import ConfigError
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.robots.base import Pose
from wovenskin.robots.sim.tm5_900 import (
    INITIAL_Q,
    SKIN_RIGHT_AXIS,
    SKIN_SITE,
    SKIN_UP_AXIS,
    load_model,
)
from wovenskin.runtime.session import open_session
from wovenskin.sim.stream import simulate_stream


def skin_mapping_file(tmp_path) -> str:
    """The packaged mapping with ``frame = "skin"``."""
    packaged = resources.files("wovenskin.control").joinpath("default_mapping.toml")
    body = packaged.read_text(encoding="utf-8").replace('frame = "tool"', 'frame = "skin"')
    path = tmp_path / "skin.toml"
    path.write_text(body, encoding="utf-8")
    return str(path)


def patch_axes_in_world(q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The skin's up and right axes in the world, and the TCP's rotation, at joints ``q``."""
    model = load_model()
    data = mujoco.MjData(model)
    data.qpos[:6] = q
    mujoco.mj_forward(model, data)
    site = data.site_xmat[model.site(SKIN_SITE).id].reshape(3, 3)
    tcp = data.site_xmat[model.site("tcp").id].reshape(3, 3)
    return site @ SKIN_UP_AXIS, site @ SKIN_RIGHT_AXIS, tcp


@pytest.mark.parametrize("q", [INITIAL_Q, np.array([0.3, -0.4, 1.2, 0.2, 1.0, -0.7])])
def test_the_default_patch_axes_are_those_of_the_models_skin_patch_site(q) -> None:
    up, right, tcp = patch_axes_in_world(np.asarray(q, dtype=float))
    assert tcp @ np.array(SKIN_UP_IN_TOOL) == pytest.approx(up, abs=1e-9)
    assert tcp @ np.array(SKIN_RIGHT_IN_TOOL) == pytest.approx(right, abs=1e-9)


def test_skin_frame_twists_follow_the_finger_on_the_patch() -> None:
    mapping = ActionMapping.from_text('[motion]\nframe = "skin"\n' + _GESTURES)
    quat = np.zeros(4)
    up, right, tcp_rotation = patch_axes_in_world(np.asarray(INITIAL_Q, dtype=float))
    mujoco.mju_mat2Quat(quat, tcp_rotation.reshape(-1))
    tcp = Pose(np.zeros(3), quat)
    speed = mapping.settings.linear_speed
    assert mapping.target_twist("swipe_right", tcp)[:3] == pytest.approx(speed * right)
    assert mapping.target_twist("swipe_up", tcp)[:3] == pytest.approx(speed * up)
    normal = np.cross(right, up)  # the patch's outward normal: push moves the tool away
    assert mapping.target_twist("push", tcp)[:3] == pytest.approx(-speed * normal)
    rotation = mapping.settings.skin_rotation()
    assert rotation.T @ rotation == pytest.approx(np.eye(3)) and np.linalg.det(rotation) > 0


def test_patch_axes_are_read_and_checked_from_the_file() -> None:
    text = '[motion]\nframe = "skin"\nskin_up = [0, 0, 2]\nskin_right = [0, 1, 0]\n'
    settings = ActionMapping.from_text(text).settings
    assert settings.skin_up == (0.0, 0.0, 1.0) and settings.skin_right == (0.0, 1.0, 0.0)
    for bad, key in (
        ("skin_up = [1, 0, 0]\nskin_right = [1, 1, 0]", "perpendicular"),
        ("skin_up = [0, 0, 0]", "skin_up"),
        ('skin_right = "z"', "skin_right"),
    ):
        with pytest.raises(ConfigError, match=key):
            ActionMapping.from_text(f"[motion]\n{bad}\n", "m.toml")
    with pytest.raises(ConfigError, match="frame"):
        MotionSettings(frame="patch")  # type: ignore[arg-type]


@pytest.mark.parametrize("how", ["mapping file", "session override"])
def test_a_swipe_right_moves_the_tcp_along_the_patchs_columns(tmp_path, how) -> None:
    """``[motion] frame = "skin"`` in the mapping, or the session's ``gesture_frame`` (the
    dashboard's skin_registered interface) over the default tool-frame mapping."""
    stream = simulate_stream(6.0, seed=3, gestures=["swipe_right"], invalid_fraction=0.0)
    path = tmp_path / "swipe.npz"
    write_labelled_stream(path, stream)
    mapping = skin_mapping_file(tmp_path) if how == "mapping file" else None
    session = open_session(
        f"replay:{path}", "sim", recognizer=ContactMeans("swipe_right"), fast_replay=True,
        trace=TraceWriter(io.StringIO()), poses=tmp_path / "poses.toml", mapping=mapping,
    )  # fmt: skip
    if how == "session override":
        session.gesture_frame = "skin"
    session.start()
    start_q = np.asarray(session.robot.state().q, dtype=float)
    start = np.asarray(session.robot.state().tcp.position, dtype=float)
    session.run()
    session.close()
    moved = np.asarray(session.state.robot.tcp.position, dtype=float) - start
    _, right, _ = patch_axes_in_world(start_q)
    assert session.command_count >= 1
    assert np.linalg.norm(moved) > 0.005
    assert moved @ right > 0.98 * np.linalg.norm(moved)


_GESTURES = """
[gestures]
swipe_up = "translate +z"
swipe_right = "translate +y"
push = "translate -x"
"""
