"""The UR e-series DH tables and the MuJoCo models built from them."""

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mujoco_helpers import site_pose

from wovenskin.robots.ur.models import UR_MODELS, ur_model

ANGLES = st.lists(st.floats(-2 * np.pi, 2 * np.pi), min_size=6, max_size=6).map(np.array)


@pytest.fixture(scope="module")
def built() -> dict[str, mujoco.MjModel]:
    return {name: arm.mujoco_model() for name, arm in UR_MODELS.items()}


@pytest.mark.parametrize("name", sorted(UR_MODELS))
@settings(max_examples=40, deadline=None)
@given(q=ANGLES)
def test_the_mujoco_flange_equals_the_dh_chain(built, name: str, q: np.ndarray) -> None:
    expected = UR_MODELS[name].flange_pose(q)
    np.testing.assert_allclose(site_pose(built[name], q, "flange"), expected, atol=1e-9)


def test_the_ur5e_at_zero_is_where_the_controller_says() -> None:
    """All joints at zero: the arm lies stretched along -x (a2 + a3), the wrist offsets
    d4 + d6 along -y, d1 - d5 up; the flange's z points along -y."""
    pose = ur_model("ur5e").flange_pose(np.zeros(6))
    np.testing.assert_allclose(pose[:3, 3], [-0.8172, -0.2329, 0.0628], atol=1e-9)
    np.testing.assert_allclose(pose[:3, 2], [0.0, -1.0, 0.0], atol=1e-12)


def test_the_skin_patch_sits_on_the_last_link_before_the_flange(built) -> None:
    for name, model in built.items():
        q = np.random.default_rng(7).uniform(-3, 3, 6)
        flange = site_pose(model, q, "flange")
        patch = site_pose(model, q, "skin_patch")
        along = (patch[:3, 3] - flange[:3, 3]) @ flange[:3, 2]
        assert -0.06 < along < -0.04, name  # centred 50 mm before the flange
        np.testing.assert_allclose(patch[:3, 2], flange[:3, 2], atol=1e-9)  # columns: tool axis
        assert abs(patch[:3, 1] @ flange[:3, 2]) < 1e-9  # its normal points away from the axis


def test_data_sheet_speeds_and_unknown_names() -> None:
    assert np.rad2deg(ur_model("UR10e").limits.max_speed[0]) == pytest.approx(120.0)
    assert np.rad2deg(ur_model("ur3e").limits.max_speed[5]) == pytest.approx(360.0)
    with pytest.raises(ValueError, match="unknown UR model 'ur99'"):
        ur_model("ur99")
