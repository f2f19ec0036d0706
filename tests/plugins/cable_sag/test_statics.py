"""Statics through the reference cable (thesis eqs. 5.5-5.11), the static simulator built on it
(inverse and forward problems), and its validation against an independent lumped-mass chain."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fusionkit_plugins.cable_sag.model import shipped_robot
from fusionkit_plugins.cable_sag.static_solver import StaticsError, forward_pose, inverse_pose
from fusionkit_plugins.cable_sag.statics import equilibrium
from research.lumped_mass import chain_end, lumped_forward_pose

LARGE = shipped_robot("cdpr_large")
SMALL = shipped_robot("cdpr_small")


def _theta_function(R, t, f, pulleys, robot):
    def fn(theta):
        eq = equilibrium(R @ Rotation.from_rotvec(theta[:3]).as_matrix(), t + theta[3:6], f + theta[6:8],
                         pulleys + theta[8:].reshape(-1, 3), robot)
        return np.concatenate([eq.length, eq.height_error])
    return fn


@pytest.mark.parametrize("robot, pulleys", [LARGE, SMALL], ids=["large", "small"])
def test_jacobians_match_central_differences(robot, pulleys):
    rng = np.random.default_rng(3)
    R = Rotation.from_rotvec(rng.normal(size=3) * 0.02).as_matrix()
    t = pulleys.mean(axis=0) * [1, 1, 0] + [0.3, -0.2, pulleys[0, 2] - 15.0]
    f = np.array([robot.weight, robot.weight / 4])
    eq = equilibrium(R, t, f, pulleys, robot, jacobian=True)
    analytic = np.vstack([eq.d_length, eq.d_height])
    fn = _theta_function(R, t, f, pulleys, robot)
    h = 1e-6
    numeric = np.column_stack([(fn(h * e) - fn(-h * e)) / (2 * h) for e in np.eye(robot.dim)])
    assert np.abs(analytic - numeric).max() < 1e-6 * max(1.0, np.abs(numeric).max())


def test_forces_balance_the_weight():
    """Sum of cable forces and of their moments about the end-effector equals gravity's."""
    robot, pulleys = LARGE
    pose = inverse_pose(np.array([10.0, -7.0, 5.0]), pulleys, robot, yaw=0.02)
    r = robot.attachments @ pose.R.T
    d = r + pose.t - pulleys
    s = np.column_stack([d[:, :2] / np.linalg.norm(d[:, :2], axis=1)[:, None], np.zeros(4)])
    forces = -pose.state.H[:, None] * s + pose.state.V[:, None] * [0.0, 0.0, 1.0]
    gravity = np.array([0.0, 0.0, -robot.weight])
    assert np.abs(forces.sum(axis=0) + gravity).max() < 1e-9 * robot.weight
    moment = np.cross(r, forces).sum(axis=0) + np.cross(pose.R @ robot.com, gravity)
    assert np.abs(moment).max() < 1e-9 * robot.weight
    assert np.abs(pose.state.height_error).max() < 1e-8 and np.all(pose.state.H > 0)


@pytest.mark.parametrize("robot, pulleys, t", [(*LARGE, [10.0, -7.0, 5.0]), (*SMALL, [0.4, -1.5, -8.0])],
                         ids=["large", "small"])
def test_forward_recovers_the_inverse_pose_to_1e_8_and_forces_to_1e_6(robot, pulleys, t):
    pose = inverse_pose(np.array(t), pulleys, robot, yaw=0.01)
    guess_t = pose.t + [0.3, -0.2, 0.1]
    back = forward_pose(pose.state.length, pulleys, robot, np.eye(3), guess_t)
    assert np.abs(back.t - pose.t).max() < 1e-8
    assert np.abs(back.R - pose.R).max() < 1e-9
    assert np.abs(back.forces - pose.forces).max() < 1e-6 * pose.forces.max()


def test_a_pose_outside_the_static_workspace_is_refused():
    robot, pulleys = LARGE
    with pytest.raises(StaticsError):
        inverse_pose(np.array([118.0, 100.0, 0.0]), pulleys, robot)  # in a corner: cables slacken


def test_chain_converges_to_the_catenary_at_second_order():
    robot, pulleys = LARGE
    pose = inverse_pose(np.array([10.0, -7.0, 5.0]), pulleys, robot)
    H, V, length = pose.state.H[0], pose.state.V[0], pose.state.length[0]
    errors = [np.hypot(*np.subtract(chain_end(H, V, length, robot.cable_weight, n),
                                    (pose.state.span[0], pose.state.rise[0]))) for n in (200, 2000)]
    assert errors[1] < 2e-6 and errors[0] / errors[1] == pytest.approx(100, rel=0.05)


@pytest.mark.parametrize("robot, pulleys, t", [(*LARGE, [10.0, -7.0, 5.0]), (*SMALL, [0.4, -1.5, -8.0])],
                         ids=["large", "small"])
def test_lumped_mass_robot_agrees_with_the_catenary_simulator_to_1e_6(robot, pulleys, t):
    """The whole robot with 2000-link chains, solved by a general root finder from a guess 0.5 m
    and 5 % off: pose within 1e-6 m, tensions within 1e-6 (measured 2e-7 m, 8e-8)."""
    pose = inverse_pose(np.array(t), pulleys, robot, yaw=0.01)
    forces0 = np.column_stack([pose.state.H, pose.state.V]) * 1.05
    R, t_lumped, H, V = lumped_forward_pose(pose.state.length, pulleys, robot, np.eye(3),
                                            pose.t + [0.5, -0.3, 0.2], forces0)
    assert np.abs(t_lumped - pose.t).max() < 1e-6
    assert np.abs(R - pose.R).max() < 1e-6
    assert np.abs(np.hypot(H, V) / pose.forces - 1).max() < 1e-6
