"""The serial-arm factor types pass the factor contract (residual zero at the example, analytic Jacobians
equal central differences, there and away from it), and so does the hold factor of the identifiability
analysis; the residuals against hand-built cases."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.testing import FactorExample, check_factor_contract, check_factor_example
from fusionkit_plugins.serial_arm.diagnosis import hold_factor
from fusionkit_plugins.serial_arm.factors import FACTOR_TYPES, example_arm
from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses, pose_residuals, position_residuals
from fusionkit_plugins.serial_arm.kinematics import Layout, Parameters, marker_pose
from fusionkit.plugins import registry


@pytest.mark.parametrize("cls", FACTOR_TYPES, ids=lambda c: c.name)
def test_factor_contract(cls):
    check_factor_contract(cls, seeds=(0, 1, 2, 3))


def test_the_factor_types_are_registered_by_the_serial_arm_entry_point():
    provider = registry().provider
    assert {cls.name: provider[("factor_types", cls.name)] for cls in FACTOR_TYPES} == \
        {cls.name: "serial_arm" for cls in FACTOR_TYPES}


@pytest.mark.parametrize("vartype, value, axes", [
    ("pose3", gtsam.Pose3.Expmap(np.array([0.3, -0.2, 0.5, 1.0, 2.0, -1.0])), [2, 3]),
    ("pose3", gtsam.Pose3.Expmap(np.array([-1.0, 0.4, 0.1, 0.0, 0.5, 0.2])), [0, 1, 2, 3, 4, 5]),
    ("vector", np.array([0.1, -0.2, 0.3, 0.4]), [1, 3]),
    ("scalar", 0.25, [0]),
])
def test_hold_factor_contract(vartype, value, axes):
    values = gtsam.Values()
    values.insert(0, value)
    # at the hold's own 1e-9 sigma, central differences of the whitened error drown in round-off: check the model
    check_factor_example(FactorExample(hold_factor(0, vartype, value, axes, sigma=0.01), values), f"hold {vartype}")
    assert hold_factor(0, vartype, value, axes).dim() == len(axes)


def test_tool_residuals_are_the_marker_pose_and_position_errors():
    """With the base 1 m along x and the marker 0.1 m along the flange's z, the marker of the UR10 at q = 0
    sits where the URDF puts tool0 plus 0.1 m along tool0's z, shifted by the base."""
    rng = np.random.default_rng(0)
    chain, _, _ = example_arm(rng, "pose3")
    base = np.eye(4)
    base[0, 3] = 1.0
    marker = np.eye(4)
    marker[2, 3] = 0.1
    layout, p = Layout(True, "pose3"), Parameters(base, marker)
    q = np.zeros(chain.n)
    flange = chain.flange(q).T
    expected = flange[:3, 3] + flange[:3, 2] * 0.1 + [1.0, 0.0, 0.0]
    np.testing.assert_allclose(marker_pose(chain, layout, q, p)[0][:3, 3], expected, atol=1e-12)
    poses = marker_poses(chain, layout, q[None], p)
    np.testing.assert_allclose(position_residuals(poses, (expected + [0.0, 0.002, 0.0])[None])[0],
                               [[0.0, -0.002, 0.0]], atol=1e-12)
    measured = gtsam.Pose3(marker_pose(chain, layout, q, p)[0]).compose(gtsam.Pose3.Expmap(np.r_[0, 0, 0.01, 0, 0, 0]))
    np.testing.assert_allclose(pose_residuals(poses, measured.inverse().matrix()[None])[0], [[0, 0, -0.01, 0, 0, 0]],
                               atol=1e-12)


@pytest.mark.parametrize("tool", ["pose3", "point3"])
def test_batched_marker_poses_and_jacobians_equal_pinocchios_per_sample(tool):
    """batch.marker_poses (one numpy pass for all samples) against kinematics.marker_pose (Pinocchio per
    sample), with parameters shared by every sample and with per-sample (time-varying) ones."""
    rng = np.random.default_rng(5)
    chain, layout, p = example_arm(rng, tool)
    q = rng.uniform(-3, 3, (12, chain.n))
    offsets = [rng.normal(scale=0.1, size=12) for _ in p.offsets]
    placements = [rng.normal(scale=0.1, size=(12, len(axes))) for _, axes in layout.placements]
    for shared in (True, False):
        given = p if shared else Parameters(p.base, p.tool, offsets, placements)
        batched = marker_poses(chain, layout, q, given, jacobians=True)
        for i in range(len(q)):
            own = p if shared else Parameters(p.base, p.tool, np.array([o[i] for o in offsets]),
                                              [x[i] for x in placements])
            T, blocks = marker_pose(chain, layout, q[i], own, jacobians=True)
            np.testing.assert_allclose(batched.T[i], T, atol=1e-12)
            for a, b in zip(batched.blocks, blocks):
                np.testing.assert_allclose(a[i], b, atol=1e-12)
