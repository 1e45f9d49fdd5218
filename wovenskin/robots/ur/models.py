"""Kinematic models of the Universal Robots e-series arms: DH tables, limits, MuJoCo models.

The DH tables are the ones Universal Robots publishes for kinematics (standard DH, all
``theta`` offsets zero; frame 0 is the controller's base frame, frame 6 the tool flange),
so :meth:`URModel.flange_pose` at the joints ``getActualQ`` reports is the flange pose the
controller reports with a zero TCP offset.  :meth:`URModel.mujoco_model` builds a MuJoCo
model of the arm from the same table (:func:`~wovenskin.robots.dh.mjcf_from_dh`) with the
skin patch on the last link, for the dashboard's 3D view of a real UR arm; the tests check
that its flange equals the DH chain.  Joint speed limits are the data sheets' maxima.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.robots.base import JointLimits
from wovenskin.robots.dh import DHLink, LinkLook, chain_frames, mjcf_from_dh

_HALF_PI = np.pi / 2
SKIN_SITE = "skin_patch"
# In the skin_patch site's frame (as on the TM5-900): x is the skin's "up" (toward row 0),
# z (the tool axis) its "right" (toward higher columns), y the outward normal.
SKIN_UP_AXIS = np.array([1.0, 0.0, 0.0])
SKIN_RIGHT_AXIS = np.array([0.0, 0.0, 1.0])


def _table(d1: float, a2: float, a3: float, d4: float, d5: float, d6: float) -> tuple[DHLink, ...]:
    return (
        DHLink(d=d1, a=0.0, alpha=_HALF_PI, theta_offset=0.0),
        DHLink(d=0.0, a=a2, alpha=0.0, theta_offset=0.0),
        DHLink(d=0.0, a=a3, alpha=0.0, theta_offset=0.0),
        DHLink(d=d4, a=0.0, alpha=_HALF_PI, theta_offset=0.0),
        DHLink(d=d5, a=0.0, alpha=-_HALF_PI, theta_offset=0.0),
        DHLink(d=d6, a=0.0, alpha=0.0, theta_offset=0.0),
    )


@dataclass(frozen=True)
class URModel:
    """One e-series arm: its DH table, data-sheet joint speeds and drawing radii."""

    name: str
    dh: tuple[DHLink, ...]
    max_speed_deg: tuple[float, ...]
    radii: tuple[float, ...]  # m, the drawn links, one per joint

    @property
    def limits(self) -> JointLimits:
        """+-360 deg on every joint (the controller's range) and the data sheet's speeds."""
        return JointLimits(
            lower=np.full(6, -2 * np.pi),
            upper=np.full(6, 2 * np.pi),
            max_speed=np.deg2rad(np.asarray(self.max_speed_deg, dtype=float)),
        )

    def frames(self, q: np.ndarray) -> list[np.ndarray]:
        """Base <- DH frame i, i = 0..6."""
        return chain_frames(self.dh, q)

    def flange_pose(self, q: np.ndarray) -> np.ndarray:
        """Base <- flange (4x4) at joints ``q``."""
        return self.frames(q)[-1]

    def mjcf(self) -> str:
        """The MJCF text of the arm with a 140 x 100 mm skin patch on its last link."""
        d6 = self.dh[5].d
        r = self.radii[5]
        centre = d6 - 0.05  # the patch spans the last 100 mm before the flange
        end_link = f"""
<geom name="end_link" type="cylinder" size="{r:.4g} 0.05" pos="0 0 {centre:.4g}"
      rgba="0.85 0.85 0.88 1"/>
<geom name="skin_patch" type="box" size="0.07 0.002 0.05" pos="0 {r + 0.002:.4g} {centre:.4g}"
      rgba="0.95 0.55 0.2 1"/>
<site name="{SKIN_SITE}" type="box" size="0.07 0.002 0.05" pos="0 {r + 0.002:.4g} {centre:.4g}"/>
"""
        limits = self.limits
        return mjcf_from_dh(
            self.name, self.dh, limits.lower, limits.upper, LinkLook(self.radii), end_link
        )

    def mujoco_model(self) -> mujoco.MjModel:
        return mujoco.MjModel.from_xml_string(self.mjcf())


UR_MODELS: dict[str, URModel] = {
    model.name: model
    for model in (
        URModel(
            "ur3e",
            _table(0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921),
            (180.0, 180.0, 180.0, 360.0, 360.0, 360.0),
            (0.045, 0.04, 0.035, 0.03, 0.03, 0.03),
        ),
        URModel(
            "ur5e",
            _table(0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996),
            (180.0,) * 6,
            (0.06, 0.055, 0.045, 0.038, 0.038, 0.038),
        ),
        URModel(
            "ur10e",
            _table(0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655),
            (120.0, 120.0, 180.0, 180.0, 180.0, 180.0),
            (0.075, 0.065, 0.055, 0.045, 0.045, 0.045),
        ),
        URModel(
            "ur16e",
            _table(0.1807, -0.4784, -0.36, 0.17415, 0.11985, 0.11655),
            (120.0, 120.0, 180.0, 180.0, 180.0, 180.0),
            (0.075, 0.07, 0.06, 0.045, 0.045, 0.045),
        ),
    )
}
DEFAULT_DISPLAY_MODEL = "ur5e"  # drawn when the spec names no model


def ur_model(name: str) -> URModel:
    """The model called ``name`` (``ur3e``, ``ur5e``, ``ur10e``, ``ur16e``); ValueError if none."""
    key = name.strip().lower()
    if key not in UR_MODELS:
        raise ConfigError(f"unknown UR model {name!r}; known: {', '.join(UR_MODELS)}")
    return UR_MODELS[key]
