"""The UWB results (docs/models/uwb.md), shared by tests and benchmarks/bench_uwb.py: bias models side by
side (with the estimator's noise levels equal to the simulator's -- a self-consistency check -- or
misstated), robust kernels under NLOS outliers, anchor self-calibration against the number of
epochs, two robots in one graph, and the per-epoch multilateration baseline."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import yaml

from fusionkit import load_config
from fusionkit.api import nearest
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.uwb.factors import lever_arm
from fusionkit_plugins.uwb.initializers import multilaterate
from fusionkit_plugins.uwb.labyrinth import read_labyrinth

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


def misstate_noise(config: dict, factors: dict[str, float]) -> None:
    """Multiply the sigma of every factor entry of type T by factors[T] (e.g. {"uwb.range": 2.0}):
    the estimator's noise levels misstated against the simulator's. Scaling every entry alike
    leaves the least-squares estimate unchanged but for the priors (anchors, bias start)."""
    for entry in config["factors"]:
        factor, sigma = factors.get(entry["type"], 1.0), entry.get("sigma")
        if isinstance(sigma, dict):
            entry["sigma"] = {k: v * factor for k, v in sigma.items()}
        elif sigma is not None:
            entry["sigma"] = sigma * factor


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


def bias_models(seeds, params: dict | None = None, noise: dict[str, float] | None = None) -> dict:
    """Per bias model: mean position RMSE and bias RMSE (m) over the seeds, same data. The
    estimator's noise levels are the simulator's (a self-consistency check), or misstated by
    `noise` (factor type -> multiplier of its sigma, see misstate_noise)."""
    out = {}
    for model in MODELS:
        runs = [run({**(params or {}), "bias_model": model}, s, edit=lambda c: misstate_noise(c, noise or {}))
                for s in seeds]
        out[model] = {"position_m": float(np.mean([position_rmse(r) for r in runs])),
                      "bias_m": float(np.mean([bias_rmse(r) for r in runs]))}
    return out


def per_epoch_multilateration(result, robot: str = "a", window: float = 0.0, stream: str | None = None) -> float:
    """Position RMSE (m) of the tag by plain multilateration at each epoch from that epoch's ranges
    alone (no bias, no motion model): the baseline. `stream`: the wide range stream (default
    ranges_<robot>, the uwb.sim naming); anchors 2-D or 3-D."""
    ranges = result.streams[stream or f"ranges_{robot}"]
    n = ranges.values.shape[1]
    t = np.repeat(ranges.t, n)
    idx = np.tile(np.arange(n), len(ranges.t))
    anchors = np.asarray(result.truth.calibration["anchors"]["anchor"]["values"], float)
    pos, _ = multilaterate(ranges.t, t, idx, ranges.values.ravel(), anchors, window=max(window, 1e-9))
    truth = result.truth.trajectories[robot]
    m = nearest(truth.t, ranges.t, 1e-6)
    b = lever_arm(result.config.robots[robot].description, "tag")
    dim = anchors.shape[1]
    tag_truth = np.array([np.asarray(p.transformFrom(b))[:dim] for p in (truth.poses()[k] for k in m.state)])
    return float(np.sqrt(np.mean(np.sum((pos[m.row] - tag_truth) ** 2, axis=1))))


# ------------------------------------------------------------------ the Labyrinth recordings

LABYRINTH_WHEEL_DISTANCE = 0.0785  # m, from the dataset
LABYRINTH_WINDOW = 0.6  # s: the four anchors are ranged round-robin every 0.128 s
# the small robot's wheel odometry is poor: 0.2 m and 1 rad per sqrt(s) make chi-square per degree
# of freedom about 1 (0.01 m / 0.1 rad: 15; tighter odometry then costs accuracy: 0.19 m vs 0.10 m)
LABYRINTH_ODOMETRY = {"translation": 0.2, "rotation": 1.0}


def labyrinth_config(folder: Path, bias_model: str) -> dict:
    """A config for the Labyrinth recordings: anchors known (from the data, 1 mm), the tag at the
    robot's origin, ranges with the given bias model, wheel odometry, multilateration start."""
    _, anchors, _, _ = read_labyrinth(folder)
    ids = sorted(anchors)
    robot_desc = {"name": "labyrinth_robot", "parameters": {}}
    factors = [{"type": "uwb.range", "robot": "robot", "stream": "ranges", "anchors": "anchors",
                "anchor_column": "anchor", "range_column": "range", "ids": ids, "sigma": 0.1}]
    if bias_model != "none":
        robot_desc["parameters"]["uwb_bias"] = {"type": "scalar", "values": [0.0] * len(ids), "sigma": 1.0,
                                                "time_varying": bias_model == "time_varying"}
        factors[0]["bias"] = "uwb_bias"
    if bias_model == "time_varying":
        factors.append({"type": "parameter.random_walk", "robot": "robot", "parameter": "uwb_bias", "sigma": 0.01})
    factors.append({"type": "odometry.diff_drive", "robot": "robot", "stream": "wheels",
                    "wheel_distance": LABYRINTH_WHEEL_DISTANCE, "sigma": LABYRINTH_ODOMETRY})
    return {"name": f"labyrinth_{bias_model}",
            "robots": {"anchors": {"description": {"name": "labyrinth_anchors", "parameters": {"anchor": {
                "type": "point2", "values": [list(anchors[i]) for i in ids], "sigma": 0.001}}}},
                       "robot": {"description": robot_desc, "states": {"stream": "ranges", "type": "pose2"}}},
            "sources": [{"type": "uwb.labyrinth", "path": str(folder)}],
            "factors": factors,
            "initializers": [{"type": "uwb.multilateration", "robot": "robot", "anchors": "anchors",
                              "stream": "ranges", "anchor_column": "anchor", "range_column": "range", "ids": ids,
                              "window": LABYRINTH_WINDOW}],
            "solver": {"type": "batch", "method": "lm", "max_cost_ratio": 1e6}, "output": {"plots": False}}


def labyrinth(folder: Path) -> dict:
    """Position RMSE (m) on the recordings: per-epoch multilateration (the baseline), and the graph
    without bias, with a constant and with a time-varying bias per anchor; the constant biases found."""
    out = {}
    for model in MODELS:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "config.yaml"
            path.write_text(yaml.safe_dump(labyrinth_config(Path(folder), model)))
            result = estimate(load_config(path))
        out[model] = position_rmse(result, "robot")
        if model == "constant":
            out["constant_bias_m"] = [float(v) for v in result.parameters["robot"]["uwb_bias"].values]
    ranges, anchors, _, truth = read_labyrinth(Path(folder))
    ids = sorted(anchors)
    points = np.array([anchors[i] for i in ids])
    index = np.array([ids.index(i) for i in ranges[:, 1]])
    pos, usable = multilaterate(truth[:, 0], ranges[:, 0], index, ranges[:, 2], points, LABYRINTH_WINDOW)
    err = pos[usable] - truth[usable, 1:]
    out["multilateration"] = float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))
    return out


# The sparse far regime (issue: a vehicle at walking speed ranging to a few far beacons one at a time): uwb.sim's
# field site, one range per epoch at 2 Hz to four beacons 10-70 m from the path, and a right wheel reading 3 % long.
FIELD = {"site": "field", "round_robin": True, "rate": 2.0, "duration": 240.0, "wheel_scale_error": 0.03,
         "bias_model": "constant"}
FIELD_STARTS = ("defaults", "good start", "per-epoch multilateration")


def field_starts(folder: Path, seed: int, params: dict = FIELD) -> dict:
    """The field regime (seed) written to `folder`, solved from three starts: the shipped config's defaults
    (uwb.multilateration, which starts on the odometry aligned to the ranges when ranging cannot place the tag epoch
    by epoch), a good start (the true path) and per-epoch multilateration alone (the alignment switched off).
    Returns {start: RunResult} (rejected runs kept)."""
    from fusionkit.simulate import write_dataset
    from fusionkit.sweep import override_text
    from fusionkit_plugins.uwb import initializers
    write_dataset(SCENARIO, folder, [f"{k}={override_text(v)}" for k, v in params.items()], seed=seed)
    config = yaml.safe_load((folder / "config.yaml").read_text())

    def solve(name: str, edit=None):
        data = yaml.safe_load(yaml.safe_dump(config))
        if edit:
            edit(data)
        (folder / f"{name}.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
        return estimate(load_config(folder / f"{name}.yaml"), keep_rejected=True)

    def from_truth(data):
        data["sources"].append({"type": "tum", "name": "start", "path": "truth/a.tum"})
        data["initializers"] = [{"type": "pose.interpolate", "robot": "a", "stream": "start"}]
    out = {"defaults": solve("defaults"), "good start": solve("good_start", from_truth)}
    aligned = initializers.Multilateration._try_odometry
    initializers.Multilateration._try_odometry = lambda *args, **kwargs: None
    try:
        out["per-epoch multilateration"] = solve("multilateration")
    finally:
        initializers.Multilateration._try_odometry = aligned
    return out
