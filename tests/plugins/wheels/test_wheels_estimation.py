"""The wheel factors estimate what wheels.sim made: through a stuck episode the graph (per-wheel encoder
factors, over-runs down-weighted, gyro, no sideways motion) ends well inside plain odometry's error;
with the camera's ground-truth poses a short clean run calibrates the radii, axle length, passive radius
and gyro to within 3 sigma; the fixed-lag smoother tracks a drifting radius with preintegrated odometry.
Each data set is simulated with the noise levels the config assumes (a self-consistency check); the
mis-specified case: the same stuck run estimated with the encoder sigma 3x too small still beats odometry."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.wheels import rules
from fusionkit_plugins.wheels.kinematics import wheel_angles
from fusionkit_plugins.wheels.model import drive_of

STUCK = {"duration": 20.0, "faults": {"stuck": {"count": 1, "duration": 2.0}}}


def odometry_end(result) -> np.ndarray:
    """Plain odometry (driven wheels, nominal intrinsics) of the run's wheel stream: its end position."""
    wheels, drive = result.streams["wheels"], drive_of(result.config.robots["robot"].description)
    dt = np.diff(wheels.t)
    speed = {w: drive.nominal[f"wheel_radius_{w}"] * np.diff(wheel_angles(wheels.column(w), drive.ticks[w])) / dt
             for w in ("left", "right")}
    return rules.odometry(rules.WheelSteps(dt, speed["left"], speed["right"], drive.nominal["axle_length"]))[-1, :2]


def end_errors(result) -> tuple[float, float]:
    truth_end = result.truth.trajectories["robot"].pose_array()[-1, :2]
    graph_end = result.trajectories["robot"].pose_array()[-1, :2]
    return float(np.linalg.norm(graph_end - truth_end)), float(np.linalg.norm(odometry_end(result) - truth_end))


@pytest.mark.parametrize("sigma_factor", [1.0, 1 / 3])
def test_through_a_stuck_episode_the_graph_ends_within_half_of_plain_odometrys_error(sigma_factor):
    """20 s figure eight, stuck for 2 s (the driven wheels spin 0.3 m). Measured (seed 0): graph 0.021 m,
    odometry 0.31 m; over seeds 0..4 the graph's error was 0.05..0.47 of odometry's."""
    def edit(config):
        for f in config["factors"]:
            if f["type"] == "wheels.encoder":
                f["sigma"] *= sigma_factor
    with simulated_config("wheels.sim", STUCK, seed=0, edit=edit) as config:
        graph, odometry = end_errors(estimate(config, keep_rejected=True))
    assert odometry > 0.2 and graph < 0.5 * odometry


def test_camera_poses_calibrate_radii_axle_passive_wheel_and_gyro_within_3_sigma():
    def edit(config):
        config["factors"].append({"type": "pose.absolute", "robot": "robot", "stream": "camera",
                                  "sigma": {"rotation": 0.02, "translation": 0.0028}})
    with simulated_config("wheels.sim", {"duration": 20.0, "path": "slalom"}, seed=1, edit=edit) as config:
        result = estimate(config)
    errors = result.evaluation["parameters"]["robot"]
    for name in ("wheel_radius_left", "wheel_radius_right", "axle_length", "passive_radius", "gyro_scale",
                 "gyro_bias"):
        assert abs(errors[name]["z_per_axis"][0][0]) < 3, (name, errors[name])
    prior = {"wheel_radius_left": 0.0004, "axle_length": 0.003}
    for name, sigma in prior.items():  # the camera, not the prior, determines them
        assert result.parameters["robot"][name].sigma[0][0] < sigma / 5


def test_fixed_lag_tracks_a_drifting_radius_with_preintegrated_odometry_within_3_sigma():
    """60 s random path, left radius -1 mm (2.5 %) linearly; states at 2 Hz, camera at 2 Hz, lag 5 s."""
    params = {"duration": 60.0, "path": "random", "drift": {"wheel": "left", "change": -0.001}}

    def edit(config):
        config["robots"]["robot"]["states"]["every"] = 10
        config["factors"] = [
            {"type": "pose.origin", "robot": "robot", "sigma": {"rotation": 0.02, "translation": 0.005}},
            {"type": "wheels.preintegrated", "robot": "robot", "stream": "wheels", "sigma": 2e-4, "lateral_sigma": 1e-3},
            {"type": "parameter.random_walk", "robot": "robot", "parameter": "wheel_radius_left", "sigma": 1.3e-4},
            {"type": "pose.absolute", "robot": "robot", "stream": "camera",
             "sigma": {"rotation": 0.02, "translation": 0.0028}}]
        config["initializers"] = [{"type": "pose.interpolate", "robot": "robot", "stream": "camera"}]
        config["solver"] = {"type": "fixed_lag", "lag": 5.0}
    with simulated_config("wheels.sim", params, seed=5, edit=edit) as config:
        result = estimate(config)
    radius = result.parameters["robot"]["wheel_radius_left"]
    truth = result.streams["radius_truth"]
    true_left = np.interp(radius.series_t, truth.t, truth.column("left"))
    z = (np.array(radius.values) - true_left) / radius.sigma[:, 0]
    assert true_left[0] - true_left[-1] == pytest.approx(0.001, rel=0.01)
    assert abs(z[-1]) < 3 and np.mean(np.abs(z[len(z) // 2:]) < 3) > 0.95


@pytest.mark.slow
def test_two_updates_per_step_keep_a_per_step_fixed_lag_within_1_mm_over_30_s():
    """Per-wheel encoder factors at 20 Hz with the camera, fixed-lag 2 s after a 5 s batch warm-up, 30 s
    figure eight (the speed benchmark's quick case): with one Gauss-Newton step per update the smoother
    loses the track after about 25 s (ATE 32 mm: `bench_wheels_speed.py --quick` with updates_per_step 1,
    not rerun here to keep the suite short); a second update per step keeps it at the batch's 0.6 mm."""
    def edit(config):
        config["factors"].append({"type": "pose.absolute", "robot": "robot", "stream": "camera",
                                  "sigma": {"rotation": 0.02, "translation": 0.0028}})
        config["solver"] = {"type": "fixed_lag", "warmup": 5.0, "lag": 2.0, "relinearize_threshold": 1e-4,
                            "updates_per_step": 2}
    with simulated_config("wheels.sim", {"duration": 30.0, "path": "figure_eight"}, seed=0, edit=edit) as config:
        ate = estimate(config, keep_rejected=True).evaluation["trajectories"]["robot"]["ate_rmse_m"]
    assert ate < 0.001, ate
