"""Localization in a known arena from the e-puck's IR readings and commanded speeds (epuck.sim, 20 s):
batch and fixed-lag within millimetres where dead reckoning drifts by centimetres, with sigmas that
cover the errors; per-sensor gains and offsets (the simulator's sensors differ from the model)
recovered within 3 sigma. The configs give the estimator the simulator's own noise levels: a
self-consistency check (benchmarks/bench_epuck.py also runs misstated noise)."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.epuck.factors import motion_increments
from fusionkit_plugins.epuck.model import alphas


def run(params: dict, seed: int, solver: dict | None = None):
    def change(config):
        config["output"] = {"plots": False}
        config["solver"].update(solver or {})
    with simulated_config("epuck.sim", {"duration": 20.0, **params}, seed, change) as config:
        return estimate(config)


def dead_reckoning_error(result) -> float:
    """RMS position error (m) of the commanded speeds integrated from the origin prior's pose."""
    stream, truth = result.streams["commands"], result.truth.trajectories["puck"]
    start = result.config.factors[0]["pose"]
    alpha = alphas(result.config.robots["puck"].description.extra)
    poses = [gtsam.Pose2(*start)]
    for delta, _ in motion_increments(truth.t, stream, stream.column("v"), stream.column("omega"), alpha):
        poses.append(poses[-1].compose(delta))
    est = np.array([[p.x(), p.y()] for p in poses])
    return float(np.sqrt(np.mean(np.sum((est - truth.pose_array()[:, :2]) ** 2, axis=1))))


def test_batch_localization_is_within_millimetres_where_dead_reckoning_drifts_and_sigmas_cover_it():
    result = run({}, 1)
    ev = result.evaluation["trajectories"]["puck"]
    assert ev["ate_rmse_m"] < 0.0015                                     # measured: 0.39 mm
    assert ev["ate_rmse_m"] < 0.1 * dead_reckoning_error(result)         # dead reckoning: 15.5 mm
    assert min(ev["consistency_percent"][a]["3sigma"] for a in "xy") > 95.0   # measured: 100 % (the Cauchy kernel weighs clean states by ~0.7)


def test_fixed_lag_steps_with_the_ir_readings_and_stays_within_millimetres():
    result = run({}, 1, {"type": "fixed_lag", "lag": 1.0})
    assert len(result.solution.step_latency) == 201
    assert result.evaluation["trajectories"]["puck"]["ate_rmse_m"] < 0.002   # measured: 0.9 mm


def test_sensor_gains_and_offsets_that_differ_from_the_model_are_recovered_within_three_sigma():
    result = run({"gain_error": 0.03, "offset_error": 10.0}, 2)
    found = result.evaluation["parameters"]["puck"]
    for name in ("ir_gain", "ir_offset"):
        assert np.abs(np.ravel(found[name]["z_per_axis"])).max() < 3.0, (name, found[name])  # measured: 1.9
    assert result.evaluation["trajectories"]["puck"]["ate_rmse_m"] < 0.002
