"""Pouring: particles start in the cup; a tilt over the container delivers, beside it spills."""

import json

import mujoco
import numpy as np
import pytest

from wovenskin.tasks.pour import CONTAINER_XY, CUP_XY, N_PARTICLES, PourTask, particle_layout


@pytest.fixture(scope="module")
def task():
    return PourTask()


def test_particles_start_in_the_cup(task):
    task.reset(0)
    state = task.state()
    assert state.in_cup == N_PARTICLES == state.total
    assert state.spilled == state.delivered == state.airborne == 0
    assert np.linalg.norm(state.cup_position[:2] - CUP_XY) < 0.02
    assert not task.succeeded() and not task.failed()
    assert np.all(np.isfinite(task.physics.data.qpos))
    json.dumps(task.to_dict())


def test_a_resting_cup_sleeps_and_the_arm_stays_awake(task):
    """A cup of particles at rest costs little (MuJoCo's sleeping islands); the arm, which
    is moved every step, never sleeps."""
    task.reset(2)
    physics = task.physics
    q = physics.data.qpos[physics.arm_qpos].copy()
    physics.advance(q, q, 1.0)
    model, data = physics.model, physics.data
    arm_tree = model.body_treeid[model.body("link1").id]
    assert data.tree_awake[arm_tree] == 1
    cup_tree = model.body_treeid[model.body("cup").id]
    assert data.tree_awake[cup_tree] == 0
    assert int(np.sum(data.tree_awake)) <= 5  # the arm, and perhaps a few still settling
    assert task.state().in_cup == N_PARTICLES


def test_particle_layout_fits_in_the_cup():
    layout = particle_layout(np.random.default_rng(0))
    assert layout.shape == (N_PARTICLES, 3)
    gaps = np.linalg.norm(layout[:, None] - layout[None], axis=2) + np.eye(N_PARTICLES)
    assert gaps.min() > 0.0099  # no two spheres overlap


def test_reset_is_deterministic_per_seed(task):
    task.reset(4)
    first = task.physics.data.qpos.copy()
    task.reset(4)
    np.testing.assert_array_equal(task.physics.data.qpos, first)


def _carry_and_tilt(
    task, xy, height=0.15, tilt=np.radians(135), move_s=1.5, tilt_s=1.5, hold_s=1.5
):
    """Drive the cup along a smooth path (its free joint set with consistent velocities):
    up and over ``xy``, then turned about x so its rim points to -y."""
    model, data = task.physics.model, task.physics.data
    joint = model.joint("cup")
    adr, dof = int(joint.qposadr[0]), int(joint.dofadr[0])
    start = data.qpos[adr : adr + 3].copy()
    goal = np.array([xy[0], xy[1], height])
    dt = model.opt.timestep
    for k in range(round((move_s + tilt_s + hold_s) / dt)):
        t = k * dt
        s = min(t / move_s, 1.0)
        u, du = 0.5 - 0.5 * np.cos(np.pi * s), 0.5 * np.pi / move_s * np.sin(np.pi * s)
        r = min(max(t - move_s, 0.0) / tilt_s, 1.0)
        angle = tilt * (0.5 - 0.5 * np.cos(np.pi * r))
        rate = tilt * 0.5 * np.pi / tilt_s * np.sin(np.pi * r) if 0.0 < r < 1.0 else 0.0
        data.qpos[adr : adr + 3] = start + (goal - start) * u
        data.qpos[adr + 3 : adr + 7] = [np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0]
        data.qvel[dof : dof + 3] = (goal - start) * (du if s < 1.0 else 0.0)
        data.qvel[dof + 3 : dof + 6] = [rate, 0.0, 0.0]
        mujoco.mj_step(model, data)


@pytest.mark.slow
def test_tilt_over_the_container_delivers(task):
    task.reset(1)
    _carry_and_tilt(task, (CONTAINER_XY[0], CONTAINER_XY[1] + 0.05))
    state = task.state()
    assert state.delivered >= 95 and state.spilled == 0
    assert task.succeeded() and not task.failed()


@pytest.mark.slow
def test_tilt_beside_the_container_spills(task):
    task.reset(1)
    _carry_and_tilt(task, CUP_XY)
    state = task.state()
    assert state.spilled > 50 and state.delivered == 0
    assert task.failed() and not task.succeeded()
