"""UWB factor pieces: the planar and scaled range residual (contract: exact Jacobians), the native
path and the custom path agree, wheel odometry integrates arcs exactly, and the shared range-origin
fit works in 2-D."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.api import gaussian
from fusionkit.geometry import fit_range_origin, range_factor
from fusionkit.testing import FactorExample, check_factor_example
from fusionkit_plugins.uwb.factors import scaled_range_factor


@pytest.mark.parametrize("seed", range(3))
def test_planar_range_with_bias_and_scale_meets_the_contract(seed):
    rng = np.random.default_rng(seed)
    pose = gtsam.Pose2(*rng.normal(size=3))
    b, a = rng.normal(size=3) * 0.2, rng.normal(size=3) * 5
    bias, alpha = float(rng.normal() * 0.1), float(rng.normal() * 0.01)
    tag = np.concatenate([pose.transformFrom(b[:2]), b[2:]])
    z = (1 + alpha) * float(np.linalg.norm(tag - a)) + bias
    values = gtsam.Values()
    values.insert(0, pose)
    values.insert(1, a)
    values.insert(2, bias)
    values.insert(3, alpha)
    check_factor_example(FactorExample(scaled_range_factor(0, 1, 2, 3, b, z, gaussian([0.05]), planar=True), values),
                         "planar scaled range", rng=rng)


def test_planar_world_range_with_scale_meets_the_contract():
    rng = np.random.default_rng(4)
    pose = gtsam.Pose2(*rng.normal(size=3))
    b, a = rng.normal(size=3) * 0.2, rng.normal(size=2) * 5
    z = 1.01 * float(np.linalg.norm(pose.transformFrom(b[:2]) - a)) + 0.1
    values = gtsam.Values()
    values.insert(0, pose)
    values.insert(1, a)
    values.insert(2, 0.1)
    values.insert(3, 0.01)
    factor = scaled_range_factor(0, 1, 2, 3, b, z, gaussian([0.05]), planar=True, planar_anchor=True)
    check_factor_example(FactorExample(factor, values), "planar-world scaled range", rng=rng)


@pytest.mark.parametrize("planar", [False, True])
def test_native_and_custom_range_paths_agree_to_1e_12_without_scale_error(planar):
    """Without a scale error the range is GTSAM's native range+bias factor (shared with the rigid
    cables); the custom path with alpha = 0 gives the same residual."""
    rng = np.random.default_rng(7)
    b = np.array([0.1, 0.05, 0.0])
    values = gtsam.Values()
    if planar:
        values.insert(0, gtsam.Pose2(1.0, 2.0, 0.4))
        values.insert(1, np.array([6.0, -1.0]))
        values.insert(11, np.array([6.0, -1.0, 0.0]))
        mount = gtsam.Pose2(b[0], b[1], 0.0)
    else:
        values.insert(0, gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3) * 0.3), rng.normal(size=3)))
        values.insert(1, np.array([6.0, -1.0, 2.5]))
        values.insert(11, np.array([6.0, -1.0, 2.5]))
        mount = gtsam.Pose3(gtsam.Rot3(), b)
    values.insert(2, 0.12)
    values.insert(3, 0.0)
    native = range_factor(0, 1, 7.3, gaussian([0.05]), mount, 2)
    custom = scaled_range_factor(0, 11, 2, 3, b, 7.3, gaussian([0.05]), planar=planar)
    assert native.unwhitenedError(values) == pytest.approx(custom.unwhitenedError(values), abs=1e-12)


def test_range_origin_fit_in_the_plane_is_exact_and_refuses_a_line():
    rng = np.random.default_rng(2)
    q = rng.uniform(0, 8, (60, 2))
    a, c = np.array([10.0, -2.0]), 0.13
    a_hat, c_hat, rms = fit_range_origin(q, np.linalg.norm(q - a, axis=1) + c)
    assert np.abs(a_hat - a).max() < 1e-9 and abs(c_hat - c) < 1e-9 and rms < 1e-9
    with pytest.raises(ValueError, match="do not span 2-D"):
        fit_range_origin(np.column_stack([np.linspace(0, 1, 20), np.zeros(20)]), np.ones(20))
