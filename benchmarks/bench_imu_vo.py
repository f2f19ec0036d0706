"""IMU + monocular VO with a camera dropout (the unified graph's reference localization example,
docs/tutorials/imu_vo_bag.md): position error before, during and after the dropout, for the graph
(batch and fixed-lag) against visual odometry alone and the IMU alone.

`pose.imu_vo` scenario at its defaults (60 s, camera 20 Hz, IMU 40 Hz, VO scale 2.5, camera out from
25 to 33 s), seeds 0..9 (--quick: 0..2). Fixed-lag: a 3-s window, the first 5 s solved as one batch
(warmup: the scale is not observable from the first steps alone; without it 2 of 10 seeds diverged),
new states carried forward from the estimate (solver.new_states: carried). The estimator's noise settings are the simulator's (a
self-consistency check); `--misspecified` runs the graph with the IMU's noise densities 3x too small (an
IMU trusted 9x too much against the VO). Errors are positions against the truth, no alignment for the graph
(its origin prior fixes the frame); the baselines are given what they cannot estimate themselves:
- VO alone: the VO positions times the true scale (it has none of its own); during the dropout it holds
  its last pose, and its new chain after the dropout (it lost track) starts from there.
- IMU alone, from t = 0: dead reckoning from the true initial pose and velocity, zero bias.
- IMU across the dropout: the same from the true state at the dropout's start (a bridge with perfect
  knowledge of where the camera was lost).

    python benchmarks/bench_imu_vo.py [--quick] [--misspecified]
"""

from __future__ import annotations

import argparse

import gtsam
import numpy as np

from fusionkit.errors import SolverError
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.imu.preintegrated import IMU_COLUMNS, integrate_held, preintegration_params
from fusionkit_plugins.imu.simulators import ImuVoSimulator, body_path
from _timing import table

SCENARIO = "pose.imu_vo"
P = ImuVoSimulator.defaults
START, END = P["dropout_start"], P["dropout_start"] + P["dropout_duration"]
WINDOWS = {"before (5-25 s)": (5.0, START), "during (25-33 s)": (START, END), "after (33-38 s)": (END, END + 5.0),
           "rest (38-60 s)": (END + 5.0, np.inf)}


def _velocity(t: np.ndarray, h: float = 1e-5) -> np.ndarray:
    return (body_path(t + h)[0] - body_path(t - h)[0]) / (2 * h)


def imu_alone(t: np.ndarray, imu, t0: float) -> np.ndarray:
    """Positions at the times t >= t0 dead-reckoned from the true state at t0 (zero bias); NaN before t0."""
    zero = gtsam.imuBias.ConstantBias()
    pos, _, R = body_path(np.array([t0]))
    nav = gtsam.NavState(gtsam.Pose3(gtsam.Rot3(R[0]), pos[0]), _velocity(np.array([t0]))[0])
    samples = np.column_stack([imu.column(c) for c in IMU_COLUMNS])
    pim = gtsam.PreintegratedImuMeasurements(preintegration_params(1e-3, 1e-4, 9.81), zero)
    out = np.full((len(t), 3), np.nan)
    last = t0
    for k in np.flatnonzero(t >= t0):
        integrate_held(pim, imu.t, samples, last, float(t[k]))
        out[k] = pim.predict(nav, zero).position()
        last = float(t[k])
    return out


def vo_alone(t: np.ndarray, vo, scale: float) -> np.ndarray:
    """VO positions times the true scale, the last pose held while there is no frame; a chain that starts
    again after a gap (at the identity) continues from the pose held (VO starts at the truth's first pose)."""
    poses = vo.poses()
    joined = [poses[0]]
    for k in range(1, len(poses)):
        restart = vo.t[k] - vo.t[k - 1] > 1.5 * np.median(np.diff(vo.t))
        joined.append(joined[-1] if restart else joined[-1].compose(poses[k - 1].between(poses[k])))
    idx = np.clip(np.searchsorted(vo.t, t, side="right") - 1, 0, len(vo.t) - 1)
    return scale * np.array([joined[i].translation() for i in idx])


def window_errors(t: np.ndarray, err: np.ndarray) -> list[float]:
    return [float(np.sqrt(np.mean(err[(t >= a) & (t < b)] ** 2))) if np.isfinite(err[(t >= a) & (t < b)]).all()
            else float("nan") for a, b in WINDOWS.values()]


def one_seed(seed: int, misspecified: bool) -> dict[str, list[float]]:
    def edit(config: dict) -> None:
        if misspecified:
            for f in config["factors"]:
                if f["type"] == "imu.preintegrated":
                    f["sigma"] = {k: v / 3 for k, v in f["sigma"].items()}

    out = {}
    for solver in ("batch", "fixed_lag"):
        def edit_solver(config: dict, solver=solver) -> None:
            edit(config)
            if solver == "fixed_lag":
                config["solver"] = {"type": "fixed_lag", "lag": 3.0, "warmup": 5.0, "new_states": "carried"}
        name = f"graph, {solver.replace('_', '-')}"
        try:
            with simulated_config(SCENARIO, {}, seed, edit_solver) as config:
                result = estimate(config)
        except SolverError:  # counted in the table
            out[name] = [float("nan")] * len(WINDOWS)
            continue
        est, ref = result.trajectories["cam"], result.truth.trajectories["cam"]
        err = np.linalg.norm(est.pose_array()[:, :3] - ref.pose_array()[:len(est), :3], axis=1)
        out[name] = window_errors(est.t, err)
    streams = ImuVoSimulator().simulate(dict(P), np.random.default_rng(seed))
    ref = streams.truth_trajectories["cam"]
    t = ref.t
    truth = ref.pose_array()[:, :3]
    vo = vo_alone(t, streams.streams["vo"], P["scale"])
    out["VO alone (true scale)"] = window_errors(t, np.linalg.norm(vo - truth, axis=1))
    imu = streams.streams["imu"]
    out["IMU alone from t = 0"] = window_errors(t, np.linalg.norm(imu_alone(t, imu, 0.0) - truth, axis=1))
    out["IMU across the dropout"] = window_errors(t, np.linalg.norm(imu_alone(t, imu, START) - truth, axis=1))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--misspecified", action="store_true")
    args = ap.parse_args()
    seeds = range(3 if args.quick else 10)
    runs = [one_seed(s, args.misspecified) for s in seeds]
    label = "mis-specified noise (IMU densities 3x too small)" if args.misspecified \
        else "the simulator's noise (self-consistency)"
    print(f"position error RMS [m] by window, median over {len(runs)} seeds; estimator given {label}")
    rows = []
    for method in runs[0]:
        failed = sum(np.isnan(r[method][-1]) for r in runs)
        rows.append([method + (f" ({failed} of {len(runs)} diverged)" if failed else "")]
                    + [f"{np.nanmedian([r[method][i] for r in runs]):.3f}" for i in range(len(WINDOWS))])
    print(table(["method"] + list(WINDOWS), rows))


if __name__ == "__main__":
    main()
