"""The RCM arm's forward kinematics: thesis eq. 3.7 and the authors' code convention at hand-computed
points, the two agree after the documented frame change (and the two shipped descriptions are the
same arm), the closed-form inverse kinematics inverts them, and the factors' Jacobians in both
conventions meet the contract."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.api import robot_description_data
from fusionkit.testing import FactorExample, check_factor_example
from fusionkit_plugins.arash.factors import tool_position_factor, tool_to_tool_factor
from fusionkit_plugins.arash.kinematics import (CODE_R_THESIS, code_from_thesis, code_point_from_thesis,
                                                inverse_kinematics, tip_position)
from fusionkit_plugins.arash.model import JOINTS, PARAMETERS
from fusionkit_plugins.arash.residuals import tool_position_residual, tool_to_tool_residual

HALF_PI = np.pi / 2


def eq_3_7(q, k):
    """Thesis eq. 3.7 as printed (m): x, y, z of the tool tip."""
    phi, psi, d = q
    alpha, theta, l_1234 = k
    c, s = np.cos, np.sin
    return np.array([c(theta) * (l_1234 + d * c(alpha + psi)) - d * s(theta) * c(phi) * s(alpha + psi),
                     s(theta) * (l_1234 + d * c(alpha + psi)) + d * c(theta) * c(phi) * s(alpha + psi),
                     d * s(phi) * s(alpha + psi)])


def authors_code(q, k):
    """The authors' calibration code's forward kinematics as published (mm)."""
    phi, psi, d = q
    alpha, theta, length = k
    c, s = np.cos, np.sin
    b = alpha + psi
    return np.array([length * s(theta) - d * (c(b) * s(theta) + s(b) * c(phi) * c(theta)),
                     -d * s(b) * s(phi),
                     length * c(theta) - d * (c(b) * c(theta) - s(b) * c(phi) * s(theta))])


@pytest.mark.parametrize("q, k, tip", [
    ([0.0, 0.0, 0.01], [0.0, 0.0, 0.3], [0.31, 0.0, 0.0]),                     # all angles zero: along x
    ([0.0, np.pi / 6, 0.02], [np.pi / 3, HALF_PI, 0.3], [-0.02, 0.3, 0.0]),     # theta 90 deg, beta 90 deg
    ([HALF_PI, 0.0, -0.01], [HALF_PI, 0.0, 0.347], [0.347, 0.0, -0.01]),        # phi 90 deg: the tool along z
])
def test_thesis_forward_kinematics_equals_eq_3_7_at_hand_computed_points(q, k, tip):
    np.testing.assert_allclose(tip_position(q, k, "thesis"), tip, atol=1e-15)
    np.testing.assert_allclose(eq_3_7(q, k), tip, atol=1e-15)


@pytest.mark.parametrize("q, k, tip", [
    ([0.0, 0.0, 10.0], [0.0, 0.0, 300.0], [0.0, 0.0, 290.0]),
    ([0.0, np.pi / 6, 10.0], [np.pi / 3, HALF_PI, 300.0], [300.0, 0.0, 10.0]),
    ([HALF_PI, 0.0, 10.0], [HALF_PI, 0.0, 347.0], [0.0, -10.0, 347.0]),  # = 1000 M (0.347, 0, -0.01) above
])
def test_authors_code_forward_kinematics_at_hand_computed_points(q, k, tip):
    np.testing.assert_allclose(tip_position(q, k, "authors_code"), tip, atol=1e-12)


def random_joints_and_parameters(rng, n):
    """Joints over the whole range (d of either sign) and parameters around ARASH:ASiST's, thesis (m)."""
    q = np.column_stack([rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-0.05, 0.05, n)])
    k = np.column_stack([rng.uniform(0.0, 1.5, n), rng.uniform(-1.5, 1.5, n), rng.uniform(0.1, 0.6, n)])
    return q, k


def test_both_conventions_give_the_same_tip_after_the_frame_change():
    q, k = random_joints_and_parameters(np.random.default_rng(0), 200)
    thesis = tip_position(q, k, "thesis")
    np.testing.assert_allclose(thesis, [eq_3_7(a, b) for a, b in zip(q, k)], atol=1e-15)
    q_code, k_code = code_from_thesis(q, k)
    code = tip_position(q_code, k_code, "authors_code")
    np.testing.assert_allclose(code, [authors_code(a, b) for a, b in zip(q_code, k_code)], atol=1e-12)
    np.testing.assert_allclose(code, code_point_from_thesis(thesis), atol=1e-11)  # mm, 1e-14 relative
    np.testing.assert_allclose(code, 1000.0 * thesis @ CODE_R_THESIS.T, atol=1e-11)
    assert np.linalg.det(CODE_R_THESIS) == pytest.approx(1.0)  # a rotation: no mirror between the frames


def test_the_two_shipped_descriptions_are_the_same_arm_after_the_frame_change():
    thesis, code = robot_description_data("arash_asist"), robot_description_data("arash_asist_mm")
    assert (thesis["convention"], code["convention"]) == ("thesis", "authors_code")
    k = np.array([thesis["parameters"][p]["value"] for p in PARAMETERS])
    sigma = np.array([thesis["parameters"][p]["sigma"] for p in PARAMETERS])
    limits = np.array([thesis["joint_limits"][j] for j in JOINTS]).T  # rows: lo, hi
    _, k_code = code_from_thesis(np.zeros(3), k)
    _, sigma_code = code_from_thesis(np.zeros(3), sigma)
    limits_code = np.sort(code_from_thesis(limits, np.zeros(3))[0], axis=0)  # d flips sign: lo and hi swap
    np.testing.assert_allclose([code["parameters"][p]["value"] for p in PARAMETERS], k_code)
    np.testing.assert_allclose([code["parameters"][p]["sigma"] for p in PARAMETERS], sigma_code)
    np.testing.assert_allclose(np.array([code["joint_limits"][j] for j in JOINTS]).T, limits_code, atol=1e-12)


def test_inverse_kinematics_returns_the_joints_inside_the_parallelogram_range():
    rng = np.random.default_rng(1)
    q, k = random_joints_and_parameters(rng, 300)
    q[:, 1] = rng.uniform(0.1, 3.0, 300) - k[:, 0]   # sin(alpha + psi) > 0
    q[:, 2] = -np.abs(q[:, 2]) - 1e-3                 # d < 0
    q[:, 0] = rng.uniform(-3.0, 3.0, 300)
    back = inverse_kinematics(tip_position(q, k, "thesis"), k, -1.0)
    np.testing.assert_allclose(back, q, atol=1e-9)


@pytest.mark.parametrize("convention", ["thesis", "authors_code"])
@pytest.mark.parametrize("seed", range(3))
def test_tool_factors_meet_the_contract_in_both_conventions(convention, seed):
    rng = np.random.default_rng(seed)
    scale = 1.0 if convention == "thesis" else 1000.0
    q = [np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), scale * rng.uniform(-0.03, 0.03)]) for _ in range(2)]
    k = [np.array([rng.uniform(0.3, 1.2), rng.uniform(0.3, 1.2), scale * rng.uniform(0.2, 0.5)]) for _ in range(2)]
    base = gtsam.Pose3.Expmap(np.concatenate([rng.normal(size=3), scale * rng.normal(size=3)]))
    values = gtsam.Values()
    for key, value in enumerate([q[0], *map(float, k[0]), q[1], *map(float, k[1]), base]):
        values.insert(key, value)
    z = tool_position_residual(q[0], k[0], np.zeros(3), convention)
    noise = gtsam.noiseModel.Isotropic.Sigma(3, 0.1 * scale)
    check_factor_example(FactorExample(tool_position_factor(0, [1, 2, 3], z, convention, noise), values),
                         f"rcm.tool_position/{convention}")
    z = tool_to_tool_residual(q[0], k[0], q[1], k[1], base, np.zeros(3), convention)
    check_factor_example(FactorExample(tool_to_tool_factor(0, [1, 2, 3], 4, [5, 6, 7], 8, z, convention, noise),
                                       values), f"rcm.tool_to_tool/{convention}")


def test_a_tip_measurement_off_by_a_known_vector_gives_that_residual():
    q, k = np.array([0.2, 0.1, -0.015]), np.array([0.87, 0.73, 0.347])
    offset = np.array([1e-4, -2e-4, 3e-4])
    z = eq_3_7(q, k) + offset
    np.testing.assert_allclose(tool_position_residual(q, k, z, "thesis"), -offset, atol=1e-15)
    base = gtsam.Pose3(gtsam.Rot3.Rz(np.pi), np.array([0.5, 0.4, 0.0]))
    qb = np.array([-0.1, 0.3, -0.012])
    seen = base.transformFrom(eq_3_7(qb, k))  # b's tip in a's frame
    np.testing.assert_allclose(tool_to_tool_residual(q, k, qb, k, base, seen - eq_3_7(q, k) + offset, "thesis"),
                               -offset, atol=1e-15)
