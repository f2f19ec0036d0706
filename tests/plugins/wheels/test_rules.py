"""The rule-based baselines (plugins/wheels/rules.py) on hand-built wheel speeds where each rule's
branch is known: a wheel over- or under-reading by a known amount, a stuck robot, an offset gyro,
an impact on the gyro. 'Exact' means the end pose equals the fault-free one to 1e-12."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit_plugins.wheels import rules
from fusionkit_plugins.wheels.rules import WheelSteps

A, DT, N = 0.3, 0.05, 60
FAULT = slice(20, 40)


def truth(n: int = N) -> tuple[np.ndarray, np.ndarray]:
    """A smooth path: speed 0.2..0.3 m/s, turn rate -0.5..0.5 rad/s (not 0 at the first step)."""
    k = np.arange(n)
    return 0.25 + 0.05 * np.sin(0.1 * k), 0.5 * np.sin(0.07 * k + 0.3)


def steps(v, omega, offset: float = 0.0, gyro=None, left=0.0, right=0.0, middle=0.0) -> WheelSteps:
    """Wheel-contact speeds of the true motion (a wheel at lateral position y rolls at v - omega y) plus
    per-wheel reading errors (m/s: scalars or arrays); the gyro reads the truth unless given."""
    return WheelSteps(np.full(len(v), DT), v - omega * A / 2 + left, v + omega * A / 2 + right, A,
                      middle=v - omega * offset + middle, gyro=omega if gyro is None else gyro,
                      passive_offset=offset)


def fault(amount: float) -> np.ndarray:
    e = np.zeros(N)
    e[FAULT] = amount
    return e


def exact(poses: np.ndarray, reference: np.ndarray) -> bool:
    return bool(np.allclose(poses[-1], reference[-1], rtol=0.0, atol=1e-12))


def test_integrate_equals_composed_pose2_exponentials():
    v, w, dt = np.array([0.3, 0.2, 0.0, 0.1]), np.array([1.0, -2.0, 0.5, 0.0]), np.array([0.5, 0.7, 0.2, 0.3])
    pose = gtsam.Pose2(1.0, 2.0, 0.3)
    for vk, wk, h in zip(v, w, dt):
        pose = pose.compose(gtsam.Pose2.Expmap(np.array([vk * h, 0.0, wk * h])))
    end = rules.arc_path(v, w, dt, (1.0, 2.0, 0.3))[-1]
    np.testing.assert_allclose(end, [pose.x(), pose.y(), pose.theta()], atol=1e-14)


@pytest.mark.parametrize("offset", [0.0, 0.04])
def test_fault_free_every_rule_gives_the_true_path_to_1e12(offset):
    v, w = truth()
    clean = steps(v, w, offset)
    reference = rules.arc_path(v, w, clean.dt)
    for poses in (rules.odometry(clean), rules.gyrodometry(clean),
                  rules.gyrodometry(clean, reconstruct=True, initial_rate=w[0]),
                  rules.first_version(clean), rules.minimal_gyro(clean),
                  rules.final_version(clean, initial_rate=w[0], initial_speed=v[0])):
        np.testing.assert_allclose(poses, reference, rtol=0.0, atol=1e-12)


@pytest.mark.parametrize("offset", [0.0, 0.04])
def test_left_wheel_over_reads_minimal_gyro_and_final_take_right_and_middle_exactly(offset):
    """V_mid < V_RL; the gyro agrees with omega_RM only: both rules use right + middle wheel."""
    v, w = truth()
    faulty, reference = steps(v, w, offset, left=fault(0.05)), rules.arc_path(v, w, np.full(N, DT))
    assert exact(rules.minimal_gyro(faulty), reference)
    assert exact(rules.final_version(faulty), reference)
    assert exact(rules.first_version(faulty), reference)  # V_M and a perfect gyro
    assert np.hypot(*(rules.odometry(faulty)[-1, :2] - reference[-1, :2])) > 0.01
    assert np.hypot(*(rules.gyrodometry(faulty)[-1, :2] - reference[-1, :2])) > 0.01  # V_RL is wrong


def test_left_wheel_under_reads_only_the_final_version_is_exact():
    """V_mid > V_RL: eq. 2 and the minimal-gyro rule assume real speed <= encoder speed and take V_RL;
    the final version tests the 'left wheel under-reads' hypothesis against the gyro."""
    v, w = truth()
    faulty, reference = steps(v, w, left=fault(-0.05)), rules.arc_path(v, w, np.full(N, DT))
    assert exact(rules.final_version(faulty), reference)
    for rule in (rules.first_version, rules.minimal_gyro):
        assert np.hypot(*(rule(faulty)[-1, :2] - reference[-1, :2])) > 0.005


def test_passive_wheel_over_reads_final_version_takes_the_driven_wheels_exactly():
    """A bump under the passive wheel: V_mid jumps above V_RL and above the last accepted speed by more
    than dv_thres, so omega_RL (confirmed by the gyro) comes with V_RL."""
    v, w = truth()
    faulty, reference = steps(v, w, middle=fault(0.05)), rules.arc_path(v, w, np.full(N, DT))
    assert exact(rules.final_version(faulty), reference)
    assert exact(rules.minimal_gyro(faulty), reference)


def test_stuck_robot_speed_is_the_passive_wheels_zero():
    """Driven wheels spin at 0.2 m/s, the passive wheel and the gyro read 0: V = V_M = 0, omega = 0."""
    zero = np.zeros(N)
    stuck = steps(zero, zero, left=0.2, right=0.2)
    for rule in (rules.first_version, rules.minimal_gyro, rules.final_version):
        np.testing.assert_array_equal(rule(stuck), np.zeros((N + 1, 3)))
    v, omega, _ = rules.final_version_rates(stuck)
    np.testing.assert_array_equal(v, zero)
    assert rules.odometry(stuck)[-1, 0] == pytest.approx(0.2 * N * DT)


def test_robot_stuck_while_driving_final_version_stops_with_the_passive_wheel():
    """After 1 s at 0.25 m/s the robot stops dead while its driven wheels keep turning: the final
    version never suspects the passive wheel of under-reading, so V = V_M = 0 from then on."""
    v, w = np.where(np.arange(N) < 20, 0.25, 0.0), np.zeros(N)
    stuck = steps(v, w, left=0.25 - v, right=0.25 - v)
    assert exact(rules.final_version(stuck, initial_speed=0.25), rules.arc_path(v, w, np.full(N, DT)))


def test_offset_gyro_reconstruction_gives_the_true_rate_after_the_first_accepted_step():
    """Gyro = truth + 0.3 rad/s. From step 20 both driven wheels over-read by different amounts, so no
    wheel pair agrees with the gyro (phase 2): omega is the reconstructed gyro, V the passive wheel."""
    v, w = truth()
    faulty = steps(v, w, gyro=w + 0.3, left=fault(0.05), right=fault(0.12))
    _, omega, g = rules.final_version_rates(faulty)
    np.testing.assert_allclose(g[1:], w[1:], rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(omega, w, rtol=0.0, atol=1e-12)
    reference = rules.arc_path(v, w, np.full(N, DT))
    assert exact(rules.final_version(faulty), reference)
    raw = rules.gyrodometry(steps(v, w, gyro=w + 0.3))  # the offset gyro always "disagrees"
    assert abs(raw[-1, 2] - reference[-1, 2]) == pytest.approx(0.3 * N * DT, abs=1e-9)
    assert rules.gyrodometry(steps(v, w, gyro=w + 0.3), reconstruct=True, initial_rate=w[0])[-1, 2] == \
        pytest.approx(reference[-1, 2], abs=1e-12)


def test_gyro_impact_takes_the_wheel_rate_closest_to_the_previous_one():
    """A 2 rad/s spike on the gyro at step 15: the changes into and out of it exceed d_omega_thres, so
    the reconstruction takes the wheels' rate there; without the threshold it carries the spike."""
    v, w = truth()
    gyro = w.copy()
    gyro[15] += 2.0
    spiked = steps(v, w, gyro=gyro)
    _, _, g = rules.final_version_rates(spiked, initial_rate=w[0])
    np.testing.assert_allclose(g[15:17], w[15:17], atol=1e-12)
    _, _, g_free = rules.final_version_rates(spiked, d_omega_thres=np.inf, initial_rate=w[0])
    assert g_free[15] == pytest.approx(w[15] + 2.0, abs=1e-12)


def test_rules_needing_the_passive_wheel_or_the_gyro_say_which_is_missing():
    v, w = truth()
    plain = WheelSteps(np.full(N, DT), v - w * A / 2, v + w * A / 2, A)
    with pytest.raises(ValueError, match="middle and gyro"):
        rules.final_version(plain)
    with pytest.raises(ValueError, match="gyro"):
        rules.gyrodometry(plain)
