"""motion.constant_velocity on Pose2 states: the vectorized relative-pose log equals GTSAM's
Pose2.Logmap(a.between(b)) for ordinary and near-pi turns, and for tiny ones (where GTSAM's own formula
loses digits to cancellation) its first-order series; the contract suite checks the planar factor's
Jacobians against central differences through GTSAM's retract."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit_plugins.pose.residuals import _se2_between_log


def _pairs(rng, turns):
    a = np.column_stack([rng.normal(size=(len(turns), 2)) * 3, rng.uniform(-np.pi, np.pi, len(turns))])
    return a, np.column_stack([rng.normal(size=(len(turns), 2)) * 3, a[:, 2] + turns])


def test_se2_between_log_equals_gtsam_logmap_up_to_near_pi_turns():
    rng = np.random.default_rng(5)
    a, b = _pairs(rng, np.concatenate([rng.uniform(-3.1, 3.1, 200), np.pi - 10 ** rng.uniform(-9, -3, 50)]))
    theirs = np.array([gtsam.Pose2.Logmap(gtsam.Pose2(*p).between(gtsam.Pose2(*q))) for p, q in zip(a, b)])
    np.testing.assert_allclose(_se2_between_log(a, b), theirs, atol=1e-9)


def test_se2_between_log_of_tiny_turns_is_the_first_order_series():
    rng = np.random.default_rng(6)
    a, b = _pairs(rng, 10 ** rng.uniform(-14, -6, 100) * rng.choice([-1, 1], 100))
    relative = [gtsam.Pose2(*p).between(gtsam.Pose2(*q)) for p, q in zip(a, b)]
    t = np.array([[r.x(), r.y()] for r in relative])
    w = np.array([r.theta() for r in relative])
    expected = np.column_stack([t[:, 0] + 0.5 * w * t[:, 1], t[:, 1] - 0.5 * w * t[:, 0], w])
    np.testing.assert_allclose(_se2_between_log(a, b), expected, atol=1e-12)
