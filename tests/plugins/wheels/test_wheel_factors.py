"""The wheel factors' models (plugins/wheels/residuals.py, preintegration.py) against hand-computed cases and
GTSAM's own Pose2 maps; the factor contract for every wheels factor type."""

from __future__ import annotations

import math
import warnings

import gtsam
import numpy as np
import pytest

from fusionkit.plugins import registry
from fusionkit.api import gaussian
from fusionkit.testing import check_factor_contract
from fusionkit.testing.jacobians import numerical_jacobians
from fusionkit_plugins.wheels.factors import encoder_factor
from fusionkit_plugins.wheels.preintegration import preintegrate
from fusionkit_plugins.wheels.residuals import Arc, encoder_residual, gyro_residual, lateral_residual, over_read

WHEEL_FACTORS = ("wheels.encoder", "wheels.gyro", "wheels.nonholonomic", "wheels.preintegrated")


@pytest.mark.parametrize("name", WHEEL_FACTORS)
def test_every_wheel_factor_meets_the_contract_over_ten_seeds(name):
    check_factor_contract(registry().get("factor_types", name), seeds=tuple(range(10)))


def test_arc_forward_and_lateral_travel_are_gtsams_pose2_logmap():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = gtsam.Pose2(*rng.normal(size=3))
        b = a.compose(gtsam.Pose2(*rng.normal(scale=[0.1, 0.1, 1.0])))
        arc = Arc((a.x(), a.y(), a.theta()), (b.x(), b.y(), b.theta()))
        xi = gtsam.Pose2.Logmap(a.between(b))
        np.testing.assert_allclose([arc.forward, arc.lateral, arc.w], xi, atol=1e-12)


def test_encoders_on_an_arc_turn_by_their_own_travel_over_their_radius():
    """An arc of 0.2 m at the midpoint turning 0.4 rad, axle 0.3 m: the left wheel (y = +0.15) travels
    0.2 - 0.15 * 0.4 = 0.14 m, the right one 0.26 m; radius 0.05 m."""
    a = (1.0, 2.0, 0.5)
    end = gtsam.Pose2(*a).compose(gtsam.Pose2.Expmap(np.array([0.2, 0.0, 0.4])))
    b = (end.x(), end.y(), end.theta())
    assert encoder_residual(a, b, 0.05, 0.15, 0.14 / 0.05)[0] == pytest.approx(0.0, abs=1e-12)
    assert encoder_residual(a, b, 0.05, -0.15, 0.26 / 0.05)[0] == pytest.approx(0.0, abs=1e-12)
    assert encoder_residual(a, b, 0.05, 0.0, 0.2 / 0.05 + 0.1)[0] == pytest.approx(-0.1, abs=1e-12)
    assert lateral_residual(a, b)[0] == pytest.approx(0.0, abs=1e-12)


def test_sideways_step_is_the_lateral_residual():
    assert lateral_residual((0.0, 0.0, math.pi / 2), (-0.01, 0.0, math.pi / 2))[0] == pytest.approx(0.01)


def test_gyro_predicts_its_reading_from_the_turn_scale_and_bias():
    """Turn 0.1 rad in 0.5 s with bias 0.02 rad/s, scale 1.25: the reading integrates to (0.1 - 0.01) / 1.25."""
    e, _ = gyro_residual((0.0, 0.0, 3.1), (0.0, 0.0, 3.1 + 0.1 - 2 * math.pi), 1.25, 0.02, 0.072, 0.5)
    assert e == pytest.approx(0.0, abs=1e-12)


def test_over_read_loss_is_gaussian_below_the_motion_and_cauchy_above():
    sigma, k = 0.01, 3.0
    assert over_read(0.05, sigma, 1, k) == (0.05, 1.0)       # predicted turn above the reading: under-read
    assert over_read(-0.05, sigma, 0, k) == (-0.05, 1.0)     # a wheel at rest cannot over-run
    r, w = over_read(-0.05, sigma, 1, k)                     # reading 5 sigma beyond the motion
    assert (r / sigma) ** 2 / 2 == pytest.approx(k ** 2 / 2 * math.log1p(25 / k ** 2))
    h = 1e-7
    assert w == pytest.approx((over_read(-0.05 + h, sigma, 1, k)[0] - over_read(-0.05 - h, sigma, 1, k)[0]) / (2 * h),
                              rel=1e-6)
    assert over_read(-1e-9, sigma, 1, k)[0] == pytest.approx(-1e-9)  # continuous at zero


@pytest.mark.parametrize("u", [0.5, 1.0 - 1e-9, 1.0 + 1e-9, 7.0, 1e10, 1e160, 1e300])
def test_over_read_stays_finite_and_exact_without_numpy_warnings_far_beyond_the_motion(u):
    """An encoder reading u sigmas beyond the motion (u = 1e160: an incremental solve gone astray) with a numpy
    sigma, as the factors pass it: (u / k)^2 overflowed there (RuntimeWarning, residual inf, weight 0)."""
    sigma, k = np.float64(0.0075), 3.0
    e = -u * float(sigma)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r, w = over_read(e, sigma, 1, k)
        h = 1e-6 * abs(e)
        numeric = (over_read(e + h, sigma, 1, k)[0] - over_read(e - h, sigma, 1, k)[0]) / (2 * h)
    assert math.isfinite(r) and r < 0 and 0.0 < w <= 1.0
    assert (r / sigma) ** 2 / 2 == pytest.approx(k ** 2 * (math.log(u / k) + 0.5 * math.log1p((k / u) ** 2)), rel=1e-12)
    assert w == pytest.approx(numeric, rel=1e-6)


def test_encoder_factor_far_from_its_reading_raises_no_warning_and_its_jacobians_match_differences():
    """The whole wheels.encoder factor (over_read on, numpy sigma) with the second pose 1e158 m away: finite
    whitened error, no RuntimeWarning, analytic Jacobians equal central differences."""
    sigma = np.float64(0.0075)
    values = gtsam.Values()
    for key, v in enumerate((gtsam.Pose2(0.0, 0.0, 0.1), gtsam.Pose2(1e158, 2e157, 0.3), 0.05, 0.4)):
        values.insert(key, v)
    factor = encoder_factor([0, 1, 2, 3], 0.5, 1.0, gaussian([sigma]), sigma, 3.0, -1, True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        error = factor.whitenedError(values)
        analytic = factor.linearize(values).jacobian()[0]
        numeric = np.hstack(numerical_jacobians(factor, values, step=1e-6))
    assert np.all(np.isfinite(error)) and np.all(np.isfinite(analytic))
    np.testing.assert_allclose(analytic, numeric, rtol=1e-5, atol=1e-9)


def _composed(window, left, right, theta):
    r_l, r_r, axle = theta
    out = [gtsam.Pose2() for _ in range(window.max() + 1)]
    for f, b, a in zip(window, left, right):
        d, turn = 0.5 * (r_r * a + r_l * b), (r_r * a - r_l * b) / axle
        out[f] = out[f].compose(gtsam.Pose2.Expmap(np.array([d, 0.0, turn])))
    return out


def test_preintegrated_windows_are_the_composed_arcs_with_their_jacobian():
    rng = np.random.default_rng(1)
    window = np.repeat(np.arange(3), [4, 1, 6])
    left, right = rng.uniform(-1, 3, 11), rng.uniform(-1, 3, 11)
    theta = np.array([0.04, 0.041, 0.25])
    pre = preintegrate(window, left, right, np.full(11, 0.05), theta, 1e-3, 1e-3)
    exact = _composed(window, left, right, theta)
    np.testing.assert_allclose(pre.delta, [[p.x(), p.y(), p.theta()] for p in exact], atol=1e-14)
    h = 1e-7
    for c in range(3):
        up, down = theta.copy(), theta.copy()
        up[c] += h
        down[c] -= h
        numeric = [(gtsam.Pose2.Logmap(e.between(u)) - gtsam.Pose2.Logmap(e.between(d))) / (2 * h)
                   for e, u, d in zip(exact, _composed(window, left, right, up), _composed(window, left, right, down))]
        np.testing.assert_allclose(pre.jacobian[:, :, c], numeric, atol=1e-7)


@pytest.mark.parametrize("factors, position, heading", [((0.97, 1.0, 1.0), 5e-5, 1e-9),
                                                          ((1.01, 0.99, 1.01), 1e-4, 2e-4)])
def test_first_order_intrinsics_update_stays_close_to_the_exact_composition(factors, position, heading):
    """A 10-sample window of a turning robot (0.15 m, 0.14 rad): one radius 3 % off its preintegration
    point (a worn tyre) moves the window's end by less than 5e-5 of its travel; all three intrinsics 1 % off
    in opposite directions, by less than 1e-4 and 2e-4 rad."""
    n = 10
    window, left, right = np.zeros(n, dtype=int), np.full(n, 0.33), np.full(n, 0.42)
    nominal = np.array([0.04, 0.04, 0.25])
    pre = preintegrate(window, left, right, np.full(n, 0.05), nominal, 1e-3, 1e-3)
    theta = nominal * np.array(factors)
    approx = gtsam.Pose2(*pre.delta[0]).compose(gtsam.Pose2.Expmap(pre.jacobian[0] @ (theta - nominal)))
    exact = _composed(window, left, right, theta)[0]
    error = gtsam.Pose2.Logmap(exact.between(approx))
    assert np.linalg.norm(error[:2]) < position * np.hypot(exact.x(), exact.y())
    assert abs(error[2]) < heading


def test_preintegrated_covariance_matches_monte_carlo_of_the_per_sample_noise():
    rng = np.random.default_rng(2)
    n, sigma, lateral, dt = 8, 2e-3, 1e-3, 0.05
    left, right = rng.uniform(0.5, 2.0, n), rng.uniform(0.5, 2.0, n)
    r_l, r_r, axle = 0.04, 0.04, 0.25
    pre = preintegrate(np.zeros(n, dtype=int), left, right, np.full(n, dt), (r_l, r_r, axle), sigma, lateral)
    mean = gtsam.Pose2(*pre.delta[0])
    d, turn = 0.5 * (r_r * right + r_l * left), (r_r * right - r_l * left) / axle
    noise = rng.normal(size=(4000, n, 3)) * np.sqrt(dt) * [sigma, sigma, lateral]
    samples = []
    for draw in noise:
        pose = gtsam.Pose2()
        for s in range(n):
            n_r, n_l, n_y = draw[s]
            pose = pose.compose(gtsam.Pose2.Expmap(np.array([d[s] + 0.5 * (n_r + n_l), n_y, turn[s] + (n_r - n_l) / axle])))
        samples.append(gtsam.Pose2.Logmap(mean.between(pose)))
    sampled = np.cov(np.array(samples).T)
    np.testing.assert_allclose(np.sqrt(np.diag(sampled)), np.sqrt(np.diag(pre.covariance[0])), rtol=0.05)
