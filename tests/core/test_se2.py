"""fusionkit.se2 (SE(2) for N planar poses at once) against GTSAM's Pose2, and its Jacobians against central
differences, down to turn angles of 1e-12 rad (below se2.SMALL the closed forms are Taylor series)."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit import se2

RNG = np.random.default_rng(11)
TWISTS = np.column_stack([RNG.normal(size=(400, 2)),
                          np.concatenate([RNG.uniform(-np.pi, np.pi, 300), 10 ** RNG.uniform(-12, -3, 100)])])


def _xyt(p: gtsam.Pose2) -> list[float]:
    return [p.x(), p.y(), p.theta()]


def test_exp_log_compose_between_inverse_and_adjoint_are_gtsams_pose2():
    """GTSAM's Pose2 Expmap and Logmap divide by the angle down to 1e-10 rad and lose digits there: compared
    above 0.01 rad; below, Log(Exp(d)) = d."""
    poses = [gtsam.Pose2.Expmap(d) for d in TWISTS]
    arrays = np.array([_xyt(p) for p in poses])
    turning = np.abs(TWISTS[:, 2]) > 0.01
    assert np.abs(se2.exp(TWISTS[turning]) - arrays[turning]).max() < 1e-12
    logs = np.array([gtsam.Pose2.Logmap(p) for p in poses])
    assert np.abs(se2.log(arrays[turning]) - logs[turning]).max() < 1e-10
    assert np.abs(se2.log(se2.exp(TWISTS[~turning])) - TWISTS[~turning]).max() < 1e-15
    assert np.abs(se2.adjoint(arrays) - np.array([p.AdjointMap() for p in poses])).max() < 1e-15
    a, b = arrays[:200], arrays[200:]
    composed = se2.compose(a, b)
    reference = np.array([_xyt(p.compose(q)) for p, q in zip(poses[:200], poses[200:])])
    assert np.abs(composed[:, :2] - reference[:, :2]).max() < 1e-14
    assert np.abs(np.sin(composed[:, 2] - reference[:, 2])).max() < 1e-14  # composed angles are not wrapped
    relative = np.array([_xyt(p.between(q)) for p, q in zip(poses[:200], poses[200:])])
    assert np.abs(se2.between(a, b)[:, :2] - relative[:, :2]).max() < 1e-14
    assert np.abs(se2.log(se2.compose(se2.inverse(a), a))).max() < 1e-15


def test_jr_and_jr_inv_match_central_differences_down_to_tiny_angles():
    """Exp(d + e) = Exp(d) Exp(Jr e) and Log(X Exp(e)) = Log(X) + Jr^-1 e to first order, column by column
    (GTSAM's own Pose2 LogmapDerivative loses digits below 1e-4 rad: compared with it above 0.1 rad only)."""
    h = 1e-6
    X = se2.exp(TWISTS)
    for j in range(3):
        e = np.zeros_like(TWISTS)
        e[:, j] = h
        jr_column = (se2.log(se2.between(X, se2.exp(TWISTS + e))) - se2.log(se2.between(X, se2.exp(TWISTS - e)))) / (2 * h)
        inv_column = (se2.log(se2.compose(X, se2.exp(e))) - se2.log(se2.compose(X, se2.exp(-e)))) / (2 * h)
        assert np.abs(se2.jr(TWISTS)[:, :, j] - jr_column).max() < 1e-8
        assert np.abs(se2.jr_inv(TWISTS)[:, :, j] - inv_column).max() < 1e-8
    large = np.abs(TWISTS[:, 2]) > 0.1
    reference = np.array([gtsam.Pose2.LogmapDerivative(gtsam.Pose2.Expmap(d)) for d in TWISTS[large]])
    assert np.abs(se2.jr_inv(TWISTS[large]) - reference).max() < 1e-12
    assert np.abs(se2.jr(TWISTS) @ se2.jr_inv(TWISTS) - np.eye(3)).max() < 1e-12


def _pairs(rng, turns):
    a = np.column_stack([rng.normal(size=(len(turns), 2)) * 3, rng.uniform(-np.pi, np.pi, len(turns))])
    return a, np.column_stack([rng.normal(size=(len(turns), 2)) * 3, a[:, 2] + turns])


def test_log_of_between_equals_gtsam_logmap_up_to_near_pi_turns():
    rng = np.random.default_rng(5)
    a, b = _pairs(rng, np.concatenate([rng.uniform(-3.1, 3.1, 200), np.pi - 10 ** rng.uniform(-9, -3, 50)]))
    theirs = np.array([gtsam.Pose2.Logmap(gtsam.Pose2(*p).between(gtsam.Pose2(*q))) for p, q in zip(a, b)])
    np.testing.assert_allclose(se2.log(se2.between(a, b)), theirs, atol=1e-9)


def test_log_of_tiny_turns_is_the_first_order_series():
    """Where GTSAM's own Logmap loses digits to cancellation (turns of 1e-14 to 1e-6 rad)."""
    rng = np.random.default_rng(6)
    a, b = _pairs(rng, 10 ** rng.uniform(-14, -6, 100) * rng.choice([-1, 1], 100))
    relative = [gtsam.Pose2(*p).between(gtsam.Pose2(*q)) for p, q in zip(a, b)]
    t = np.array([[r.x(), r.y()] for r in relative])
    w = np.array([r.theta() for r in relative])
    expected = np.column_stack([t[:, 0] + 0.5 * w * t[:, 1], t[:, 1] - 0.5 * w * t[:, 0], w])
    np.testing.assert_allclose(se2.log(se2.between(a, b)), expected, atol=1e-12)
