"""Helpers for tests that read poses off MuJoCo models."""

import mujoco
import numpy as np


def site_pose(model: mujoco.MjModel, q: np.ndarray, name: str) -> np.ndarray:
    """The 4x4 world pose of site ``name`` at joint positions ``q``."""
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    pose = np.eye(4)
    pose[:3, :3] = data.site_xmat[model.site(name).id].reshape(3, 3)
    pose[:3, 3] = data.site_xpos[model.site(name).id]
    return pose
