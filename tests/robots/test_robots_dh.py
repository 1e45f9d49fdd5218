"""Standard DH kinematics and the MJCF written from a DH table."""

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.robots.dh import DHLink, LinkLook, chain_frames, dh_transform, mjcf_from_dh

FINITE = st.floats(-1.0, 1.0)
ROWS = st.lists(
    st.builds(DHLink, d=FINITE, a=FINITE, alpha=st.floats(-np.pi, np.pi),
              theta_offset=st.floats(-np.pi, np.pi)),
    min_size=1, max_size=7,
)  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(table=ROWS, seed=st.integers(0, 2**31))
def test_a_model_written_from_any_table_has_the_tables_flange(table, seed) -> None:
    n = len(table)
    xml = mjcf_from_dh("arm", table, [-4.0] * n, [4.0] * n, LinkLook([0.03] * n))
    model = mujoco.MjModel.from_xml_string(xml)
    q = np.random.default_rng(seed).uniform(-3, 3, n)
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    site = model.site("flange").id
    expected = chain_frames(table, q)[-1]
    np.testing.assert_allclose(data.site_xpos[site], expected[:3, 3], atol=1e-9)
    np.testing.assert_allclose(data.site_xmat[site].reshape(3, 3), expected[:3, :3], atol=1e-9)


def test_one_row_is_rz_tz_tx_rx() -> None:
    link = DHLink(d=0.2, a=0.3, alpha=np.pi / 2, theta_offset=0.0)
    transform = dh_transform(link, np.pi / 2)
    np.testing.assert_allclose(transform[:3, 3], [0.0, 0.3, 0.2], atol=1e-12)
    np.testing.assert_allclose(transform[:3, 2], [1.0, 0.0, 0.0], atol=1e-12)


def test_bad_joint_vectors_and_tables_are_refused() -> None:
    table = [DHLink(0.1, 0.0, 0.0, 0.0)] * 2
    with pytest.raises(ValueError, match="expected 2 joint angles"):
        chain_frames(table, [0.0])
    with pytest.raises(ValueError, match="non-finite"):
        chain_frames(table, [0.0, np.nan])
    with pytest.raises(ValueError, match="one value per DH row"):
        mjcf_from_dh("arm", table, [0.0], [1.0], LinkLook([0.03, 0.03]))
