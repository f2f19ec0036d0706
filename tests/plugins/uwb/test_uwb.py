"""UWB results of docs/models/uwb.md on the simulator and on the Labyrinth recordings: the three bias
models side by side, the robust kernel under NLOS outliers, anchor self-calibration against the
number of epochs, two robots in one graph, the per-epoch multilateration baseline, the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from research.external_data import external_data, missing_reason
from research.uwb_experiments import bias_models, labyrinth, per_epoch_multilateration, position_rmse, run

LABYRINTH = external_data("uwb_labyrinth")
needs_labyrinth = pytest.mark.skipif(not LABYRINTH.is_dir(),
                                     reason=missing_reason("uwb_labyrinth", "Labyrinth recordings"))


@pytest.fixture(scope="module")
def models():
    return bias_models(range(2))


@pytest.mark.slow
def test_drifting_bias_time_varying_model_beats_constant_and_none_within_10_cm(models):
    """Self-consistency (estimator noise = simulator noise). Measured (2 seeds, 60 s at 10 Hz, bias
    0.15 m drifting 0.03 m/sqrt(s)): position 0.25 /
    0.14 / 0.077 m and bias 0.21 / 0.12 / 0.056 m for none / constant / time-varying."""
    none, const, varying = models["none"], models["constant"], models["time_varying"]
    assert varying["position_m"] < const["position_m"] < none["position_m"]
    assert varying["bias_m"] < const["bias_m"] < none["bias_m"]
    assert varying["position_m"] < 0.1 and varying["bias_m"] < 0.08


@pytest.mark.slow
@pytest.mark.parametrize("noise", [{"uwb.range": 0.5}, {"uwb.range": 2.0},
                                   {"parameter.random_walk": 0.5, "odometry.diff_drive": 2.0}],
                         ids=["range_x0.5", "range_x2", "drift_x0.5_odometry_x2"])
def test_bias_model_ranking_holds_by_0_8x_with_noise_misstated_x0_5_or_x2(noise):
    """The test above is a self-consistency check (the estimator uses the simulator's noise
    levels); the ranking must not depend on that. Measured (seed 0) position none / constant /
    time-varying: range sigma x0.5 0.223 / 0.130 / 0.081 m, x2 0.227 / 0.126 / 0.074 m, drift x0.5
    with odometry x2 0.229 / 0.130 / 0.092 m: each model at most 0.71 times the next worse one."""
    m = bias_models(range(1), noise=noise)
    assert m["time_varying"]["position_m"] < 0.8 * m["constant"]["position_m"]
    assert m["constant"]["position_m"] < 0.8 * m["none"]["position_m"]


@pytest.mark.slow
def test_cauchy_kernel_keeps_the_error_within_1_5x_clean_under_10_percent_nlos():
    """NLOS bursts on 10 % of the ranges: least squares 0.34 m, Cauchy 0.087 m (clean: 0.078 m)."""
    clean = position_rmse(run({"bias_model": "time_varying"}, 0))
    params = {"bias_model": "time_varying", "outlier_fraction": 0.1}
    plain = position_rmse(run(params, 0))
    robust = position_rmse(run(params, 0, robust={"kernel": "cauchy", "k": 2.0}))
    assert robust < 1.5 * clean and plain > 2 * robust


def test_unknown_anchor_error_shrinks_with_epochs_to_under_10_cm_after_40_s():
    """Anchor 3 starts 1 m off: 0.76 m after 5 s, 0.2 m after 20 s, under 0.1 m after a 40 s lap."""
    errors = []
    for duration in (5.0, 20.0, 40.0):
        r = run({"bias_model": "constant", "unknown_anchors": [3], "duration": duration, "bias_drift": 0.0}, 0)
        errors.append(r.evaluation["parameters"]["anchors"]["anchor"]["abs_error"][3])
    assert errors[0] > errors[1] > errors[2] and errors[2] < 0.1


@pytest.mark.slow
def test_tag_to_tag_ranges_improve_robot_a_and_robot_b_tracks_within_10_cm():
    """Measured: robot a 0.054 m with tag-to-tag ranges, 0.078 m without."""
    both = run({"robots": 2}, 0)
    alone = run({"robots": 2}, 0, edit=lambda c: c.update(
        factors=[f for f in c["factors"] if f["type"] != "uwb.tag_range"]))
    assert position_rmse(both, "a") < position_rmse(alone, "a")
    assert position_rmse(both, "b") < 0.1


def test_graph_halves_the_error_of_per_epoch_multilateration():
    r = run({"bias_model": "time_varying"}, 0)
    assert position_rmse(r) < 0.5 * per_epoch_multilateration(r)


@pytest.mark.slow
def test_simulate_and_run_from_the_command_line_track_within_15_cm(tmp_path):
    cli = Path(sys.executable).parent / "fusionkit"
    subprocess.run([str(cli), "simulate", "uwb.sim", "--out", str(tmp_path / "sim"), "--set", "duration=20"],
                   check=True, capture_output=True)
    proc = subprocess.run([str(cli), "run", str(tmp_path / "sim/config.yaml"), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    report = json.loads((tmp_path / "out/report.json").read_text())
    assert report["evaluation"]["trajectories"]["a"]["ate_rmse_m"] < 0.15


@pytest.mark.slow
@needs_labyrinth
def test_labyrinth_constant_bias_tracks_within_13_cm_beating_no_bias_and_multilateration():
    """Per-epoch multilateration 0.197 m; the graph without bias 0.169 m, with a constant bias per
    anchor 0.104 m (biases 0.075-0.127 m: the data's README says +0.09 to +0.16 m)."""
    r = labyrinth(LABYRINTH)
    assert r["constant"] < 0.13 and r["constant"] < 0.7 * r["multilateration"]
    assert r["none"] > r["constant"]
    assert all(0.03 < b < 0.2 for b in r["constant_bias_m"])


def test_2_percent_range_scale_is_estimated_within_3_sigma_and_halves_the_error():
    """Ranges 2 % long: alpha = 0.0216 +- 0.0017 measured; positions 1.3 cm with it, 5.9 cm without."""
    params = {"bias_model": "constant", "scale_error": 0.02, "bias_drift": 0.0}
    r = run(params, 0)
    est = r.parameters["a"]["uwb_scale"]
    assert abs(est.values[0] - 0.02) < 3 * est.sigma[0, 0] + 1e-3
    without = run(params, 0, edit=lambda c: [f.pop("scale", None) for f in c["factors"]])
    assert position_rmse(r) < 0.5 * position_rmse(without)


@pytest.mark.slow
def test_constant_velocity_prior_without_odometry_beats_multilateration_by_0_6x():
    """Without wheel odometry a constant-velocity prior carries the motion between epochs (0.11 m
    measured, against 0.24 m per-epoch multilateration)."""
    def no_wheels(config):
        config["factors"] = [f if f["type"] != "odometry.diff_drive" else
                             {"type": "motion.constant_velocity", "robot": "a",
                              "sigma": {"translation": 0.3, "rotation": 0.5}} for f in config["factors"]]
    r = run({"bias_model": "time_varying"}, 0, edit=no_wheels)
    assert position_rmse(r) < 0.6 * per_epoch_multilateration(r)


def test_drone_with_imu_tracks_within_5_cm_and_halves_multilateration_error():
    """uwb.drone: 6 anchors at several heights, ranges at 10 Hz, an IMU at 200 Hz with unknown
    biases. Measured (seed 0): 2.1 cm, per-anchor biases within 4 mm, per-epoch multilateration
    several times worse."""
    from fusionkit.pipeline import estimate
    from fusionkit.simulate import simulated_config

    with simulated_config("uwb.drone", {"duration": 30.0}, 0, lambda c: c.update(output={"plots": False})) as config:
        r = estimate(config)
    ev = r.evaluation
    assert ev["trajectories"]["drone"]["ate_rmse_m"] < 0.05
    assert max(ev["parameters"]["drone"]["uwb_bias"]["abs_error"]) < 0.02
    gyro = np.abs(np.asarray(ev["parameters"]["drone"]["imu_bias"]["z_per_axis"])).max()
    assert gyro < 4
    baseline = per_epoch_multilateration(r, "drone", stream="ranges")
    assert ev["trajectories"]["drone"]["ate_rmse_m"] < 0.5 * baseline
