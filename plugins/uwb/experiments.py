"""The results of spec uwb.md, shared by tests and benchmarks/bench_uwb.py: bias models side by
side, robust kernels under NLOS outliers, anchor self-calibration against the number of epochs,
two robots in one graph, and the per-epoch multilateration baseline."""

from __future__ import annotations

import numpy as np

from fusionkit.data.association import nearest
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config

from .factors import lever_arm
from .initializers import multilaterate

SCENARIO = "uwb.sim"
MODELS = ("none", "constant", "time_varying")


def position_rmse(result, robot: str = "a") -> float:
    """RMSE (m) of the estimated positions against the truth at the state times."""
    truth, est = result.truth.trajectories[robot], result.trajectories[robot]
    m = nearest(truth.t, est.t, 1e-6)
    err = est.pose_array()[m.row, :2] - truth.pose_array()[m.state, :2]
    return float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))


def bias_rmse(result, robot: str = "a") -> float:
    """RMSE (m) of the estimated range biases against the true ones over all anchors and states
    (a model without bias counts as estimating 0)."""
    true = result.streams[f"bias_{robot}"]
    params = result.parameters.get(robot, {})
    k = nearest(true.t, result.problem.states[robot].t, 1e-6)
    n = true.values.shape[1]
    values = np.zeros((len(k.row), n))
    if "uwb_bias" in params:  # constant: one value per anchor
        values[:] = np.asarray(params["uwb_bias"].values, float)[None, :]
    for i in range(n):  # time-varying: a series per anchor
        series = params.get(f"uwb_bias[{i}]")
        if series is not None:
            values[:, i] = np.asarray(series.values, float)[k.row]
    return float(np.sqrt(np.mean((values - true.values[k.state]) ** 2)))


def run(params: dict, seed: int, robust: dict | None = None, edit=None):
    def change(config):
        config["output"] = {"plots": False}
        config["solver"]["max_cost_ratio"] = 1e6  # a wrong bias model is compared, not refused
        if robust:
            for f in config["factors"]:
                if f["type"] == "uwb.range":
                    f["robust"] = robust
        if edit:
            edit(config)
    with simulated_config(SCENARIO, params, seed, change) as config:
        return estimate(config)


def bias_models(seeds, params: dict | None = None) -> dict:
    """Per bias model: mean position RMSE and bias RMSE (m) over the seeds, same data."""
    out = {}
    for model in MODELS:
        runs = [run({**(params or {}), "bias_model": model}, s) for s in seeds]
        out[model] = {"position_m": float(np.mean([position_rmse(r) for r in runs])),
                      "bias_m": float(np.mean([bias_rmse(r) for r in runs]))}
    return out


def per_epoch_multilateration(result, robot: str = "a", window: float = 0.0) -> float:
    """Position RMSE (m) of plain multilateration at each epoch from that epoch's ranges alone
    (no bias, no motion model): the baseline."""
    ranges = result.streams[f"ranges_{robot}"]
    n = ranges.values.shape[1]
    t = np.repeat(ranges.t, n)
    idx = np.tile(np.arange(n), len(ranges.t))
    anchors = np.asarray(result.truth.calibration["anchors"]["anchor"]["values"], float)
    pos, _ = multilaterate(ranges.t, t, idx, ranges.values.ravel(), anchors, window=max(window, 1e-9))
    truth = result.truth.trajectories[robot]
    m = nearest(truth.t, ranges.t, 1e-6)
    b = lever_arm(result.config.robots[robot].description, "tag")
    tag_truth = np.array([np.asarray(p.transformFrom(b))[:2] for p in (truth.poses()[k] for k in m.state)])
    return float(np.sqrt(np.mean(np.sum((pos[m.row] - tag_truth) ** 2, axis=1))))
