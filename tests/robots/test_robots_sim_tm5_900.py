"""The TM5-900 constants and DH kinematics, and the MuJoCo model built from them."""

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mujoco_helpers import site_pose

from wovenskin.robots.sim import tm5_900
from wovenskin.robots.sim.tm5_900 import load_model

LIMITS = tm5_900.JOINT_LIMITS


@st.composite
def joint_vectors(draw: st.DrawFn) -> np.ndarray:
    fractions = draw(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))
    return LIMITS.lower + np.array(fractions) * (LIMITS.upper - LIMITS.lower)


@pytest.fixture(scope="module")
def model() -> mujoco.MjModel:
    return load_model()


def rotation_angle(a: np.ndarray, b: np.ndarray) -> float:
    cos = (np.trace(a.T @ b) - 1.0) / 2.0
    return float(np.arccos(np.clip(cos, -1.0, 1.0)))


@settings(max_examples=100, deadline=None)
@given(q=joint_vectors())
def test_mujoco_tcp_equals_dh_forward_kinematics(model: mujoco.MjModel, q: np.ndarray) -> None:
    expected = tm5_900.forward_kinematics(q)
    actual = site_pose(model, q, "tcp")
    assert np.linalg.norm(actual[:3, 3] - expected[:3, 3]) < 1e-6
    assert rotation_angle(actual[:3, :3], expected[:3, :3]) < 1e-6


@settings(max_examples=50, deadline=None)
@given(q=joint_vectors())
def test_mujoco_flange_equals_dh_frame_six(model: mujoco.MjModel, q: np.ndarray) -> None:
    expected = tm5_900.frame_transforms(q)[6]
    actual = site_pose(model, q, "flange")
    np.testing.assert_allclose(actual, expected, atol=1e-6)


def test_home_pose_follows_from_the_dh_table() -> None:
    """Upright at zero: the links stack up; d4, d6 and the tool reach out sideways."""
    dh = tm5_900.DH
    pose = tm5_900.forward_kinematics(tm5_900.HOME_Q)
    up = dh[0].d + dh[1].a + dh[2].a + dh[4].d
    sideways = dh[3].d - dh[5].d - tm5_900.TOOL_LENGTH
    np.testing.assert_allclose(pose[:3, 3], [0.0, sideways, up], atol=1e-12)


def test_initial_pose_is_in_front_with_the_tool_down() -> None:
    pose = tm5_900.forward_kinematics(tm5_900.INITIAL_Q)
    assert pose[0, 3] > 0.3 and pose[2, 3] > 0.1
    np.testing.assert_allclose(pose[:3, 2], [0.0, 0.0, -1.0], atol=1e-9)
    assert np.linalg.cond(tm5_900.jacobian(tm5_900.INITIAL_Q)) < 17.0


@settings(max_examples=50, deadline=None)
@given(q=joint_vectors())
def test_jacobian_matches_mujoco_and_finite_differences(
    model: mujoco.MjModel, q: np.ndarray
) -> None:
    jac = tm5_900.jacobian(q)
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    jacp, jacr = np.zeros((3, 6)), np.zeros((3, 6))
    mujoco.mj_jacSite(model, data, jacp, jacr, model.site("tcp").id)
    np.testing.assert_allclose(jac, np.vstack([jacp, jacr]), atol=1e-9)
    eps = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = eps
        ahead, behind = tm5_900.forward_kinematics(q + dq), tm5_900.forward_kinematics(q - dq)
        np.testing.assert_allclose(
            (ahead[:3, 3] - behind[:3, 3]) / (2 * eps), jac[:3, i], atol=1e-6
        )


def test_model_joint_ranges_equal_joint_limits(model: mujoco.MjModel) -> None:
    assert model.njnt == 6
    assert [model.joint(i).name for i in range(6)] == list(tm5_900.JOINT_NAMES)
    assert np.all(model.jnt_limited.astype(bool))
    np.testing.assert_allclose(model.jnt_range[:, 0], LIMITS.lower, atol=1e-12)
    np.testing.assert_allclose(model.jnt_range[:, 1], LIMITS.upper, atol=1e-12)


def test_joint_limits_are_the_published_ones() -> None:
    np.testing.assert_allclose(np.rad2deg(LIMITS.upper), [270, 180, 155, 180, 180, 270])
    np.testing.assert_allclose(LIMITS.lower, -LIMITS.upper)
    np.testing.assert_allclose(np.rad2deg(LIMITS.max_speed), [180, 180, 180, 225, 225, 225])


def test_model_has_skin_patch_gripper_and_keyframes(model: mujoco.MjModel) -> None:
    patch = model.geom("skin_patch")
    sizes_mm = sorted(2000 * patch.size)
    assert sizes_mm[1:] == pytest.approx([100.0, 140.0])
    assert model.body(patch.bodyid[0]).name == "link6"
    assert model.site("skin_patch").bodyid[0] == patch.bodyid[0]
    for finger in ("finger_left", "finger_right"):
        assert model.geom(finger).bodyid[0] > 0
    np.testing.assert_allclose(model.key("home").qpos, tm5_900.HOME_Q)
    np.testing.assert_allclose(model.key("initial").qpos, tm5_900.INITIAL_Q, atol=1e-12)


@pytest.mark.parametrize("bad", [np.zeros(5), np.zeros((6, 1)), np.array([np.nan] + [0.0] * 5)])
def test_kinematics_refuse_bad_joint_vectors(bad: np.ndarray) -> None:
    with pytest.raises(ValueError, match="joint vector"):
        tm5_900.forward_kinematics(bad)
    with pytest.raises(ValueError, match="joint vector"):
        tm5_900.jacobian(bad)
