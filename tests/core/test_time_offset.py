"""Time offsets between streams (fusionkit/time_offset): the shifted factor's Jacobians, the curve through the
states, the offset recovered in batch and fixed-lag solves (across a state boundary too), the first guess
from the data, and one located error line for a misconfigured `time_offset:`."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.cli.main import main
from fusionkit.config.loader import load_config
from fusionkit.graph.noise import gaussian
from fusionkit.graph.variables import POINT3, POSE2, POSE3, ROT3, SCALAR, VELOCITY3, vector_type
from fusionkit.pipeline import estimate
from fusionkit.testing.contract import FactorExample, check_factor_example
from fusionkit.time_offset.guess import correlate, motion_signal
from fusionkit.time_offset.interpolation import Shift, Timing, interpolate, shifted_factor
from fusionkit.data.stream import Stream

TYPES = (POSE3, POSE2, ROT3, SCALAR, POINT3, vector_type(4))


def random_value(vt, rng):
    if vt is POSE3:
        return gtsam.Pose3.Expmap(rng.normal(size=6))
    if vt is POSE2:
        return gtsam.Pose2(*rng.normal(size=3))
    if vt is ROT3:
        return gtsam.Rot3.Expmap(rng.normal(size=3))
    return float(rng.normal()) if vt is SCALAR else rng.normal(size=vt.dim)


def shifted_prior(vt, window_t, stamp, delta, rho, rng):
    """A prior on the state at the sample's time, shifted onto a window of random states (keys 0..),
    offset key 10, rate key 11; values at which its residual is zero."""
    states = [random_value(vt, rng) for _ in window_t]
    timing = Timing(stamp, 0.0, np.asarray(window_t, float))
    at = interpolate(vt, timing.window_t, states, timing.tau(delta, rho or 0.0))
    values = gtsam.Values()
    for i, x in enumerate(states):
        values.insert(i, x)
    values.insert(10, delta)
    if rho is not None:
        values.insert(11, rho)
    types = {**{i: vt for i in range(len(states))}, 10: SCALAR, 11: SCALAR}
    shift = Shift(99, vt, timing, tuple(range(len(states))), 10, None if rho is None else 11)
    return shifted_factor(vt.prior(99, at, gaussian([0.1] * vt.dim)), [shift], types.__getitem__), values


@pytest.mark.parametrize("vt", TYPES, ids=lambda vt: vt.name)
def test_shifted_factor_jacobians_match_central_differences_for_every_pair_and_window(vt):
    rng = np.random.default_rng(3)
    for window_t in ([0.0, 0.1, 0.25, 0.3], [0.0, 0.1], [0.0, 0.1, 0.25]):
        for stamp in (0.02, 0.12, 0.21):  # tau in the first, middle and last pair (with delta 0.05)
            for rho in (None, 0.01):
                factor, values = shifted_prior(vt, window_t, stamp, 0.05, rho, rng)
                check_factor_example(FactorExample(factor, values, 0.01), f"{vt.name} {window_t} {stamp}", rng=rng)


def shifted_prior_with_velocities(window_t, stamp, delta, pair, rng):
    """shifted_prior for Pose3 states with the world-frame velocities (keys 20, 21) of states pair, pair + 1."""
    states = [random_value(POSE3, rng) for _ in window_t]
    velocities = [rng.normal(size=3) for _ in range(2)]
    timing = Timing(stamp, 0.0, np.asarray(window_t, float))
    at = interpolate(POSE3, timing.window_t, states, timing.tau(delta), velocities, pair)
    values = gtsam.Values()
    for i, x in enumerate(states):
        values.insert(i, x)
    values.insert(20, velocities[0])
    values.insert(21, velocities[1])
    values.insert(10, delta)
    types = {**{i: POSE3 for i in range(len(states))}, 20: VELOCITY3, 21: VELOCITY3, 10: SCALAR}
    shift = Shift(99, POSE3, timing, tuple(range(len(states))), 10, None, (20, 21), pair)
    return shifted_factor(POSE3.prior(99, at, gaussian([0.1] * 6)), [shift], types.__getitem__), values


def test_shifted_factor_with_state_velocities_has_jacobians_matching_central_differences():
    """Every pair the sample may fall in, with the velocities of the same or of another pair (the offset
    moved the sample out of its build-time pair)."""
    rng = np.random.default_rng(13)
    for window_t in ([0.0, 0.1, 0.25, 0.3], [0.0, 0.1], [0.0, 0.1, 0.25]):
        for stamp in (0.02, 0.12, 0.21):
            for pair in range(len(window_t) - 1):
                factor, values = shifted_prior_with_velocities(window_t, stamp, 0.05, pair, rng)
                assert len(factor.keys()) == len(window_t) + 3  # states, two velocities, offset
                check_factor_example(FactorExample(factor, values, 0.01), f"velocities {window_t} {stamp} {pair}",
                                     rng=rng)


def test_with_state_velocities_a_constant_acceleration_path_is_interpolated_exactly():
    """p(t) = p0 + v0 t + a t^2 / 2 is cubic: the Hermite curve through positions and true velocities
    reproduces it to rounding, where the finite-difference tangents of the plain curve miss by O(h^2 a)."""
    t = np.array([0.0, 0.1, 0.2, 0.3])
    p0, v0, a = np.array([1.0, -2.0, 0.5]), np.array([0.3, 1.0, -0.2]), np.array([4.0, -3.0, 9.0])
    rot = [gtsam.Rot3.Expmap(np.array([0.1, 0.2, 0.3]) * ti) for ti in t]
    states = [gtsam.Pose3(r, p0 + v0 * ti + 0.5 * a * ti ** 2) for r, ti in zip(rot, t)]
    velocities = [v0 + a * ti for ti in t]
    tau = 0.137
    truth = p0 + v0 * tau + 0.5 * a * tau ** 2
    with_v = interpolate(POSE3, t, states, tau, velocities[1:3], pair=1).translation()
    without = interpolate(POSE3, t, states, tau).translation()
    assert np.abs(with_v - truth).max() < 1e-12
    assert np.abs(without - truth).max() > 1e-5


def test_shifted_native_range_factor_keeps_its_other_variables_and_noise():
    """A native factor with variables of its own (pulley point3, offset double) besides the shifted pose."""
    rng = np.random.default_rng(4)
    window_t = np.array([0.0, 0.05, 0.1, 0.15])
    states = [gtsam.Pose3.Expmap(rng.normal(size=6) * 0.3) for _ in window_t]
    timing = Timing(0.06, 0.0, window_t)
    pose = interpolate(POSE3, window_t, states, timing.tau(-0.02))
    pulley, l0, mount = rng.normal(size=3) * 3, 0.4, gtsam.Pose3(gtsam.Rot3(), rng.normal(size=3) * 0.2)
    z = float(np.linalg.norm(pose.transformFrom(mount.translation()) - pulley)) + l0
    inner = gtsam.RangeFactorWithTransformBias3D(99, 20, 21, z, gaussian([0.001]), mount)
    values = gtsam.Values()
    for i, x in enumerate(states):
        values.insert(i, x)
    values.insert(10, -0.02)
    values.insert(20, pulley)
    values.insert(21, l0)
    types = {**{i: POSE3 for i in range(4)}, 10: SCALAR, 20: POINT3, 21: SCALAR}
    factor = shifted_factor(inner, [Shift(99, POSE3, timing, (0, 1, 2, 3), 10)], types.__getitem__)
    assert list(factor.keys()) == [20, 21, 0, 1, 2, 3, 10]
    assert np.allclose(factor.noiseModel().sigmas(), [0.001])
    check_factor_example(FactorExample(factor, values, 0.01), "range", rng=rng)
    assert not values.exists(99)  # the curve's point is never left in the caller's values


def test_curve_passes_through_the_states_and_its_velocity_is_continuous_across_them():
    rng = np.random.default_rng(5)
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.45])
    twist = rng.normal(size=6)
    states = [gtsam.Pose3.Expmap(twist * ti + 0.02 * rng.normal(size=6)) for ti in t]
    eps = 1e-6
    for i in (1, 2, 3):
        at = interpolate(POSE3, t, states, t[i])
        assert np.abs(gtsam.Pose3.Logmap(at.between(states[i]))).max() < 1e-12
        left = gtsam.Pose3.Logmap(interpolate(POSE3, t, states, t[i] - eps).between(at)) / eps
        right = gtsam.Pose3.Logmap(at.between(interpolate(POSE3, t, states, t[i] + eps))) / eps
        assert np.abs(left - right).max() < 1e-2 * np.abs(left).max()  # a geodesic polyline jumps by O(1)


def test_residual_is_continuous_where_the_offset_moves_a_sample_into_the_next_pair():
    factor, values = shifted_prior(POSE3, [0.0, 0.1, 0.2, 0.3], 0.05, 0.05, None, np.random.default_rng(6))
    below, above = gtsam.Values(values), gtsam.Values(values)
    below.update(10, 0.05 - 1e-9)  # tau just below the state at 0.1: pair (0, 1)
    above.update(10, 0.05 + 1e-9)  # just above: pair (1, 2)
    assert np.abs(factor.unwhitenedError(below) - factor.unwhitenedError(above)).max() < 1e-6
    jac_below = factor.linearize(below).jacobian()[0]
    jac_above = factor.linearize(above).jacobian()[0]
    assert np.abs(jac_below[:, 18:24]).max() == 0 and np.abs(jac_above[:, 18:24]).max() > 0  # state 3's block


# ---------------------------------------------------------------- the offset in a graph

RATE, MOCAP_EVERY, DURATION = 20.0, 4, 6.0


def trajectory(t: np.ndarray) -> list[gtsam.Pose3]:
    pos = np.column_stack([np.sin(1.3 * t), 0.5 * np.sin(2.1 * t), 0.2 * t])
    return [gtsam.Pose3(gtsam.Rot3.Ypr(0.5 * np.sin(ti), 0.1 * np.sin(2 * ti), 0.0), p) for ti, p in zip(t, pos)]


def offset_config(workspace, lag: float, solver: dict, seed: int = 0) -> dict:
    """Odometry at 20 Hz clocks the states; motion capture at 5 Hz stamped by a clock offset by `lag`
    (its sample stamped t shows the pose at t + lag); 1 mm / 1 mrad noise on each increment and each pose."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(DURATION * RATE)) / RATE
    truth = trajectory(t)
    odom = [truth[0]]
    for a, b in zip(truth[:-1], truth[1:]):  # increments with 1 mm / 1 mrad noise each
        odom.append(odom[-1].compose(a.between(b)).compose(gtsam.Pose3.Expmap(rng.normal(size=6) * 1e-3)))
    tm = t[::MOCAP_EVERY]
    mocap = [p.compose(gtsam.Pose3.Expmap(rng.normal(size=6) * 1e-3)) for p in trajectory(tm + lag)]
    workspace.config({"name": "r", "parameters": {"clock": {"type": "scalar", "value": 0.0, "sigma": 0.5}}},
                     "robot.yaml")
    return {"robots": {"r": {"description": "robot.yaml", "states": {"stream": "odom"}}},
            "sources": [workspace.poses("odom", t, odom), workspace.poses("mocap", tm, mocap)],
            "factors": [{"type": "pose.relative", "robot": "r", "stream": "odom",
                         "sigma": {"rotation": 1e-3, "translation": 1e-3}},
                        {"type": "pose.absolute", "robot": "r", "stream": "mocap",
                         "sigma": {"rotation": 1e-3, "translation": 1e-3}, "time_offset": {"parameter": "clock"}}],
            "initializers": [{"type": "pose.interpolate", "robot": "r", "stream": "mocap"}],
            "solver": solver}


@pytest.mark.parametrize("solver", [{"type": "batch"}, {"type": "isam2", "warmup": 1.0},
                                    {"type": "fixed_lag", "lag": 1.0, "warmup": 1.0}],
                         ids=["batch", "isam2", "fixed_lag"])
def test_offset_recovered_within_its_sigma_in_batch_isam2_and_fixed_lag(workspace, solver):
    """Incremental solvers get a warm-up: the first pose is anchored by the shifted motion capture only."""
    result = estimate(load_config(workspace.config(offset_config(workspace, 0.03, solver))))
    clock = result.parameters["r"]["clock"]
    error, sigma = clock.values[0] - 0.03, clock.sigma[0][0]
    assert sigma < 1e-3
    assert abs(error) < 3 * sigma, (error, sigma)


def test_offset_that_moves_samples_into_the_next_state_interval_is_recovered_without_notes(workspace):
    """Built at offset 0 (each mocap stamp on a state), the truth 0.07 s puts every sample in the next
    interval but one (states 0.05 s apart): the window of states around the build-time pair covers it."""
    result = estimate(load_config(workspace.config(offset_config(workspace, 0.07, {"type": "batch"}))))
    clock = result.parameters["r"]["clock"]
    assert abs(clock.values[0] - 0.07) < 3 * clock.sigma[0][0]
    assert not [n for n in result.notes if "past the states" in n]
    assert "r/clock" in {f"{p.robot}/{p.name}" for ps in result.parameters.values() for p in ps.values()}


def test_a_drifting_offset_and_a_clock_rate_error_are_estimated_within_their_sigmas(workspace):
    cfg = offset_config(workspace, 0.03, {"type": "batch"})
    workspace.config({"name": "r", "parameters": {
        "clock": {"type": "scalar", "value": 0.0, "sigma": 0.5, "time_varying": True}}}, "robot.yaml")
    cfg["factors"].append({"type": "parameter.random_walk", "robot": "r", "parameter": "clock", "sigma": 0.001})
    clock = estimate(load_config(workspace.config(cfg))).parameters["r"]["clock"]
    assert len(clock.values) == RATE * DURATION
    assert np.all(np.abs(np.asarray(clock.values) - 0.03) < 3 * clock.sigma[:, 0])
    cfg = offset_config(workspace, 0.03, {"type": "batch"})
    cfg["factors"][1]["time_offset"]["rate"] = "drift"
    workspace.config({"name": "r", "parameters": {"clock": {"type": "scalar", "value": 0.0, "sigma": 0.5},
                                                  "drift": {"type": "scalar", "value": 0.0, "sigma": 0.01}}},
                     "robot.yaml")
    params = estimate(load_config(workspace.config(cfg))).parameters["r"]
    for name, truth in (("clock", 0.03), ("drift", 0.0)):
        assert abs(params[name].values[0] - truth) < 3 * params[name].sigma[0][0], name


def test_a_linearly_drifting_offset_is_followed_by_a_random_walk_at_start_and_end(workspace):
    """The motion-capture clock's offset grows linearly from 20 to 40 ms over the 6 s (not a random walk: the
    walk's 0.01 s/sqrt(s) is the estimator's allowance, not the generator's); the time-varying offset is
    read at each sample's nearest state and recovered within 3 sigma at the first and the last state, far
    from the constant it would be without the walk."""
    t = np.arange(int(DURATION * RATE)) / RATE
    lag = 0.02 + 0.02 * t[::MOCAP_EVERY] / DURATION
    cfg = offset_config(workspace, lag, {"type": "batch"})
    workspace.config({"name": "r", "parameters": {
        "clock": {"type": "scalar", "value": 0.0, "sigma": 0.5, "time_varying": True}}}, "robot.yaml")
    cfg["factors"].append({"type": "parameter.random_walk", "robot": "r", "parameter": "clock", "sigma": 0.01})
    clock = estimate(load_config(workspace.config(cfg))).parameters["r"]["clock"]
    values, sigma = np.asarray(clock.values), clock.sigma[:, 0]
    for k, truth in ((0, 0.02), (-1, 0.02 + 0.02 * t[-1] / DURATION)):
        assert abs(values[k] - truth) < 3 * sigma[k], (k, values[k], truth, sigma[k])
    assert values[-1] - values[0] > 0.015


def test_the_offset_brings_the_fit_to_the_noise_which_it_is_far_from_without(workspace):
    cfg = offset_config(workspace, 0.03, {"type": "batch"})
    fitted = estimate(load_config(workspace.config(cfg))).solution.chi2_per_dof
    del cfg["factors"][1]["time_offset"]
    cfg["factors"][1]["tolerance"] = 0.001
    ignored = estimate(load_config(workspace.config(cfg)), keep_rejected=True).solution.chi2_per_dof
    assert 0.5 < fitted < 1.5 and ignored > 4 * fitted, (fitted, ignored)


# ---------------------------------------------------------------- the first guess

def test_cross_correlation_finds_the_shift_between_a_pose_speed_and_a_rate_signal():
    t = np.arange(0, 20, 0.02)
    poses = np.column_stack([np.sin(0.7 * t) * np.sin(0.23 * t), np.zeros((len(t), 5)), np.ones(len(t))])
    reference = Stream("mocap", t[::10], ("x", "y", "z", "qx", "qy", "qz", "qw"), poses[::10])
    lag = -0.043  # the stream's sample stamped t shows the motion at t + lag
    lengths = Stream("lengths", t, ("l0",), (3.0 + np.sin(0.7 * (t + lag)) * np.sin(0.23 * (t + lag)))[:, None])
    guess = correlate(motion_signal(lengths), motion_signal(reference), 0.5)
    assert guess.usable and abs(guess.delta - lag) < 0.01


def test_a_robot_at_rest_gives_no_guess():
    rng = np.random.default_rng(7)
    t = np.arange(0, 10, 0.02)
    still = Stream("a", t, ("l0", "l1"), rng.normal(0, 1e-3, (len(t), 2)))
    other = Stream("b", t, ("l0",), rng.normal(0, 1e-3, (len(t), 1)))
    assert not correlate(motion_signal(still), motion_signal(other), 0.5).usable


# ---------------------------------------------------------------- bad input

def write_bad(workspace, edit) -> str:
    cfg = offset_config(workspace, 0.03, {"type": "batch"})
    edit(cfg)
    return str(workspace.config(cfg))


@pytest.mark.parametrize("edit, needles", [
    (lambda c: c["factors"][1]["time_offset"].update(parameter="lag"),
     ["factors[1].time_offset.parameter", "no parameter 'lag'", "clock"]),
    (lambda c: c["factors"][1]["time_offset"].update(rate="clock_rate"),
     ["factors[1].time_offset.rate", "no parameter 'clock_rate'"]),
    (lambda c: c["factors"][1].update(time_offset="clock"),
     ["factors[1].time_offset", "expected a mapping"]),
    (lambda c: c["factors"][0].update(time_offset={"parameter": "clock"}),
     ["factors[0].time_offset", "pose.relative does not pair its samples with states by stamp"]),
    (lambda c: c["factors"][1]["time_offset"].update(robot="q"),
     ["factors[1].time_offset.robot", "unknown robot 'q'"]),
    (lambda c: (c["robots"]["r"]["states"].update(type="pose2"), c["factors"][1]["time_offset"].update(velocities=True)),
     ["factors[1].time_offset.velocities", "only pose3 states"]),
    (lambda c: c.setdefault("initializers", []).append(
        {"type": "time.offset_guess", "robot": "r", "parameter": "clock", "stream": "mocap", "reference": "odom",
         "signal": "turn_rate", "columns": ["x"]}),
     ["initializers[1].columns", "turn_rate signal uses the pose columns"]),
])
def test_misconfigured_time_offset_is_one_located_line(workspace, capsys, edit, needles):
    path = write_bad(workspace, edit)
    assert main(["validate", path]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "config.yaml" in err[0] and "Traceback" not in err[0]
    for needle in needles:
        assert needle in err[0], (needle, err[0])


def test_a_time_offset_parameter_that_is_not_a_scalar_is_refused(workspace, capsys):
    path = write_bad(workspace, lambda c: None)
    workspace.config({"name": "r", "parameters": {"clock": {"type": "point3", "value": [0, 0, 0], "sigma": 1.0}}},
                     "robot.yaml")
    assert main(["validate", path]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "factors[1].time_offset.parameter" in err[0] and "is one scalar" in err[0], err
