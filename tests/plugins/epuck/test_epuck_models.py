"""The e-puck's IR sensor models are the published Gaussian sums (every coefficient, at the measured
distances), invert to distances with their sigmas, continue smoothly outside their range; the wall
map's ray distances and their Jacobians; the velocity model's right Jacobian and covariance."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from scipy.linalg import expm

from fusionkit_plugins.epuck.model import shipped_layout
from fusionkit_plugins.epuck.velocity import preintegrate
from fusionkit_plugins.epuck.walls import box_walls, ray_distances, segments_of

# the published fits, x in cm (mean reading; variance of the reading), typed in again from the table
MEAN = {0: [(4.44e17, -29.17, 5.191), (160.6, 1.405, 0.5652), (740.3, -3.62, 17.12)],
        1: [(2988, 0.242, 0.8989), (4.337e17, -167.8, 29)],
        2: [(4.608e17, -138, 24.81), (564.2, 0.7781, 0.3708), (-1.66e4, -2.881, 4.772)],
        3: [(5.477e17, -235.6, 40.68), (2473, 0.5422, 0.5808), (-163.4, 3.528, 1.124)],
        4: [(1704, -1.975, 2.962), (2919, 0.05792, 0.862), (1547, -76.91, 84.98)],
        5: [(4.677e17, -153, 27.33), (-871.3, 1.113, 1.111), (-5015, -0.3246, 4.108)],
        6: [(2739, 0.638, 0.6323), (0, -5.799, 0.6643), (4.452e17, -172.8, 29.93)],
        7: [(165.6, 2.237, 0.7756), (5168, -0.3407, 1.219), (3.235e17, -901.1, 154.6)]}
VAR = {0: [(146.4, 1.536, 1.27), (216.2, 5.904, 3.74)],
       1: [(120.6, 1.087, 0.2164), (12.19, 2.031, 1.15), (5.272e15, 140.7, 23.11)],
       2: [(177.4, 1.151, 0.2344), (27.74, 3.414, 3.659)],
       3: [(190.2, 1.105, 0.1507), (44.81, 1.722, 0.2611), (17.53, 5.346, 4.188)],
       4: [(13.1, 1.078, 0.2051), (8.922, 5.967, 1.104), (7.084, 2.246, 2.509)],
       5: [(30.3, 3.616, 0.9695), (7.202e15, 38.77, 5.504), (21.35, 0.4042, 1.385)],
       6: [(302, 0.8934, 0.4466), (-285.2, 0.8869, 0.4686), (9.893, -0.8852, 6.031)],
       7: [(0, -8.064, 1.207), (24.87, 5.204, 2.455), (14.03, 1.355, 0.8581)]}
MEASURED_CM = np.array([0.5, 1, 1.3, 1.6, 2, 3, 4, 5, 6, 7])


def published(terms, x_cm):
    return sum(a * np.exp(-((x_cm - b) / c) ** 2) for a, b, c in terms)


@pytest.fixture(scope="module")
def bank():
    return shipped_layout().bank


def test_the_shipped_models_equal_the_published_gaussian_sums_at_the_measured_distances(bank):
    d = np.repeat(MEASURED_CM[:, None] / 100.0, 8, axis=1)
    ev = bank.evaluate(d)
    for s in range(8):
        np.testing.assert_allclose(ev.mean[:, s], published(MEAN[s], MEASURED_CM), rtol=1e-12)
        np.testing.assert_allclose(ev.var[:, s], published(VAR[s], MEASURED_CM), rtol=1e-12)
    assert ev.mean[0, 1] == pytest.approx(3775.4, abs=0.1)  # IR1 at 0.5 cm, by hand from the table


def test_inverse_lookup_gives_the_distance_and_sigma_over_slope_and_nothing_out_of_range(bank):
    d = np.repeat(np.linspace(0.012, 0.068, 15)[:, None], 8, axis=1)
    z = bank.evaluate(d).mean
    back, sigma = bank.inverse(z)
    monotone = ~((np.arange(8) == 3) & (d > 0.041) & (d < 0.047))  # IR3's fit rises 4.3-4.5 cm
    np.testing.assert_allclose(back[monotone], d[monotone], atol=1e-8)
    h = 1e-7
    slope = (bank.evaluate(back + h).mean - bank.evaluate(back - h).mean) / (2 * h)
    np.testing.assert_allclose(sigma, np.sqrt(bank.evaluate(back).var) / np.abs(slope), rtol=1e-5)
    ambiguous = bank.inverse(np.full(8, 329.5))   # IR3 reads 329.5 at 4.3 and at 4.6 cm
    assert 0.042 < ambiguous[0][3] < 0.0435 and ambiguous[1][3] > 0.002
    below_far = bank.far_threshold - 1.0
    assert np.all(np.isnan(bank.inverse(below_far)[0]))


def test_models_continue_with_value_and_slope_outside_their_range_and_vanish_at_infinity(bank):
    for edge in (bank.d_min, bank.d_max):
        inside, outside = bank.evaluate(np.full(8, edge)), bank.evaluate(np.full(8, edge + 1e-9))
        np.testing.assert_allclose(outside.mean, inside.mean, rtol=1e-6)
        np.testing.assert_allclose(outside.dmean, inside.dmean, rtol=1e-4)
    far = bank.evaluate(np.full(8, np.inf))
    assert np.all(far.mean == 0) and np.all(far.dmean == 0) and np.all(far.var == bank.var_hi)
    assert np.all(bank.var_floor < bank.grid_var.min(axis=0)) and np.all(bank.rate_hi < 0)


def test_ray_distances_to_box_walls_and_none_when_the_ray_leaves_the_map():
    walls = box_walls(0.5, 0.4)
    pose = np.array([[0.1, 0.1, 0.0]] * 4)
    angle = np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])
    d = ray_distances(walls, pose, np.zeros((4, 2)), angle)
    np.testing.assert_allclose(d, [0.4, 0.3, 0.1, 0.1], atol=1e-12)
    one_wall = segments_of([[[1.0, -1.0], [1.0, 1.0]]], [])
    assert np.isinf(ray_distances(one_wall, pose[:1], np.zeros((1, 2)), np.array([np.pi])))[0]


def test_ray_distance_jacobian_equals_central_differences_on_the_pose2_manifold():
    rng = np.random.default_rng(4)
    walls = segments_of([], [[[0, 0], [0.5, 0], [0.5, 0.4], [0, 0.4]], [[0.15, 0.13], [0.35, 0.13], [0.35, 0.27]]])
    R = 40
    pose = np.column_stack([rng.uniform(0.05, 0.45, R), rng.uniform(0.03, 0.1, R), rng.uniform(-np.pi, np.pi, R)])
    mount, angle = rng.normal(0.0, 0.03, (R, 2)), rng.uniform(-np.pi, np.pi, R)
    d, H = ray_distances(walls, pose, mount, angle, jacobian=True)
    h = 1e-7
    for r in np.flatnonzero(np.isfinite(d)):
        X = gtsam.Pose2(*pose[r])
        for i in range(3):
            step = np.zeros(3)
            step[i] = h
            p, m = X.retract(step), X.retract(-step)
            dp = ray_distances(walls, np.array([[p.x(), p.y(), p.theta()]]), mount[r:r + 1], angle[r:r + 1])[0]
            dm = ray_distances(walls, np.array([[m.x(), m.y(), m.theta()]]), mount[r:r + 1], angle[r:r + 1])[0]
            assert H[r, i] == pytest.approx((dp - dm) / (2 * h), abs=1e-6)


def hat(tau):
    return np.array([[0.0, -tau[2], tau[0]], [tau[2], 0.0, tau[1]], [0.0, 0.0, 0.0]])


def vee(M):
    M = np.real(M)
    return np.array([M[0, 2], M[1, 2], M[1, 0]])


@pytest.mark.parametrize("angle", [0.0, 1e-9, 4e-4, 1.1e-3, 0.8])
def test_the_right_jacobian_the_velocity_model_uses_equals_gtsams_and_central_differences(angle):
    """The e-puck's covariance propagation uses fusionkit.api.se2.jr (series at small angles, closed form above)."""
    from fusionkit.api import se2
    tau = np.array([0.03, -0.01, angle])
    J = se2.jr(tau[None])[0]
    h = 1e-6  # Exp(tau)^-1 Exp(tau +- h e) = I +- h hat(Jr e) + O(h^2), the O(h^2) alike: central differences
    E = expm(hat(tau))
    numeric = np.column_stack([vee(np.linalg.solve(E, expm(hat(tau + e)) - expm(hat(tau - e))))
                               for e in np.eye(3) * h]) / (2 * h)
    np.testing.assert_allclose(J, numeric, atol=1e-9)
    if angle > 1e-5:  # GTSAM's ExpmapDerivative is first order below 1e-5 rad
        np.testing.assert_allclose(J, gtsam.Pose2.ExpmapDerivative(tau), atol=1e-12)


def book_sampler(v, w, dt, alpha, n, rng):
    """Probabilistic Robotics' sample_motion_model_velocity from the origin, written as in the book."""
    s_v, s_w, s_g = (alpha[0] * abs(v) + alpha[1] * abs(w), alpha[2] * abs(v) + alpha[3] * abs(w),
                     alpha[4] * abs(v) + alpha[5] * abs(w))
    vh, wh, gh = v + rng.normal(0, s_v, n), w + rng.normal(0, s_w, n), rng.normal(0, s_g, n)
    r = vh / wh
    return np.column_stack([r * np.sin(wh * dt), r - r * np.cos(wh * dt), wh * dt + gh * dt])


@pytest.mark.parametrize("w", [0.7, 1e-9])
def test_preintegrated_mean_and_covariance_match_the_books_sampler(w):
    """20000 draws of the book's sampler (arcs v/w sin, ...) against the arc Exp(v dt, 0, w dt) and
    Jr M Jr^T + gamma: covariance within 5 %, straight line included (w = 1e-9)."""
    rng = np.random.default_rng(0)
    alpha = np.array([0.045, 8.8e-5, 0.0959, 0.118, 0.01, 0.02])
    v, dt = 0.05, 0.5
    mean, cov = preintegrate(np.array([v]), np.array([w]), np.array([dt]), alpha)
    draws = book_sampler(v, w, dt, alpha, 20000, rng)
    xi = np.array([gtsam.Pose2.Logmap(mean.between(gtsam.Pose2(*p))) for p in draws])
    assert np.allclose(xi.mean(axis=0), 0.0, atol=3 * np.sqrt(np.diag(cov) / 2e4) + 1e-12)
    sample = np.cov(xi.T)
    scale = np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    assert np.max(np.abs(sample - cov) / scale) < 0.05
