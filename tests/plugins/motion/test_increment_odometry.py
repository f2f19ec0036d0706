"""`odometry.increments`: dead reckoning logged as (distance, heading change) per sample, composed as arcs
between states, with a heading-rate bias parameter. A minute of a 10 Hz log whose heading drifts at -5.4
mrad/s (the real log's figure), with motion capture at 1 Hz: the bias is recovered within 3 sigma and the
fit reaches the noise, which it is far from without the bias. Data simulated with the noise the config
states (a self-consistency check)."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate
from fusionkit_plugins.motion.factors import composed_arcs, increment_segments

BIAS = -0.0054  # rad/s: logged heading change = true + BIAS dt
SIGMA = {"translation": 0.002, "rotation": 0.001}  # per sqrt(s)


def test_increments_are_split_at_state_times_in_proportion_and_compose_as_arcs():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    d, theta, dt = increment_segments(t, np.array([9.0, 0.1, 0.2, 0.3]), np.array([9.0, 0.0, 0.1, 0.0]), 0.05, 0.25)
    np.testing.assert_allclose(d, [0.05, 0.2, 0.15])       # half of row 1, row 2, half of row 3
    np.testing.assert_allclose(theta, [0.0, 0.1, 0.0])
    np.testing.assert_allclose(dt, [0.05, 0.1, 0.05])
    delta, _ = composed_arcs(np.array([1.0]), np.array([np.pi / 2]), 0.0, np.array([1.0]))
    r = 2 / np.pi  # a quarter circle of length 1
    np.testing.assert_allclose([delta.x(), delta.y(), delta.theta()], [r, r, np.pi / 2], atol=1e-12)


def logged_run(workspace, seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    t = np.arange(601) / 10.0
    dt = 0.1
    v, omega = 0.3, 0.4 * np.sin(0.15 * t[1:])
    d = np.concatenate([[0.0], v * dt + rng.normal(0, SIGMA["translation"] * np.sqrt(dt), 600)])
    true_turn = np.concatenate([[0.0], omega * dt])
    logged = true_turn + np.concatenate([[0.0], BIAS * dt + rng.normal(0, SIGMA["rotation"] * np.sqrt(dt), 600)])
    poses = [gtsam.Pose2()]
    for k in range(1, len(t)):
        poses.append(poses[-1].compose(gtsam.Pose2.Expmap(np.array([v * dt, 0.0, true_turn[k]]))))
    mocap = [gtsam.Pose3(gtsam.Rot3.Yaw(p.theta() + rng.normal(0, 0.005)),
                         np.array([p.x(), p.y(), 0.0]) + np.r_[rng.normal(0, 0.005, 2), 0.0]) for p in poses[::10]]
    workspace.config({"name": "logger", "parameters": {
        "heading_rate_bias": {"type": "scalar", "value": 0.0, "sigma": 0.1, "unit": "rad/s"}}}, "robot.yaml")
    return {"robots": {"r": {"description": "robot.yaml", "states": {"stream": "odom", "type": "pose2"}}},
            "sources": [workspace.columns("odom", t, distance=d, turn=logged), workspace.poses("mocap", t[::10], mocap)],
            "factors": [{"type": "odometry.increments", "robot": "r", "stream": "odom", "bias": "heading_rate_bias",
                         "sigma": SIGMA},
                        {"type": "pose.absolute", "robot": "r", "stream": "mocap",
                         "sigma": {"rotation": 0.005, "translation": 0.005}}],
            "initializers": [{"type": "pose.interpolate", "robot": "r", "stream": "mocap"}],
            "solver": {"type": "batch", "method": "lm"}}


def test_a_drifting_heading_is_estimated_as_a_bias_within_3_sigma_and_the_fit_reaches_the_noise(workspace):
    config = logged_run(workspace)
    result = estimate(load_config(workspace.config(config)))
    bias = result.parameters["r"]["heading_rate_bias"]
    assert abs(bias.values[0] - BIAS) < 3 * bias.sigma[0][0] and bias.sigma[0][0] < 5e-4, (bias.values, bias.sigma)
    del config["factors"][0]["bias"]
    ignored = estimate(load_config(workspace.config(config)), keep_rejected=True)
    assert 0.5 < result.solution.chi2_per_dof < 1.5 and ignored.solution.chi2_per_dof > 5 * result.solution.chi2_per_dof


@pytest.mark.parametrize("key, where, needle", [("distance", "factors[0].stream", "lacks column(s) dist"),
                                                ("bias", "factors[0].bias", "has no parameter")])
def test_misnamed_columns_and_bias_are_one_located_line(workspace, capsys, key, where, needle):
    from fusionkit.cli.main import main
    config = logged_run(workspace)
    config["factors"][0][key] = "dist" if key == "distance" else "gyro_bias"
    assert main(["validate", str(workspace.config(config))]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and where in err[0] and needle in err[0], err


def test_only_the_part_of_a_state_interval_the_log_covers_is_used():
    t = np.array([1.0, 1.1, 1.2])
    d, theta, dt = increment_segments(t, np.array([0.0, 0.1, 0.1]), np.zeros(3), 0.9, 1.15)
    np.testing.assert_allclose(dt, [0.1, 0.05]) and np.testing.assert_allclose(d, [0.1, 0.05])
    assert all(len(x) == 0 for x in increment_segments(t, np.zeros(3), np.zeros(3), 0.5, 0.9))
