"""The shared benchmark problem: a 3-D pose chain with odometry between consecutive states, a
prior on the first pose, and absolute poses every `ABS_EVERY` states.

`write_dataset` writes TUM files + a fusionkit config into a folder; `load_arrays` reads the same
files with numpy for the hand-written baselines, and `handwritten_graph` builds in a plain python
loop exactly the graph and initial values fusionkit builds from that config (same factors, same
order, same dead-reckoning initial values, same noise models). The baselines use gtsam and numpy
only; fusionkit writes the files.
"""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np

from fusionkit.data.files import write_tum
from fusionkit.data.stream import pose_array_from, pose_stream

RATE = 10.0          # states per second
ABS_EVERY = 100      # an absolute pose every 100 states
ORIGIN_SIGMA = {"rotation": 0.001, "translation": 0.001}
ODOM_SIGMA = {"rotation": 0.002, "translation": 0.01}
ABS_SIGMA = {"rotation": 0.01, "translation": 0.05}

CONFIG = """\
name: bench_chain_{n}
robots:
  r:
    description: {{name: bench_robot, model: generic, frames: [world, body]}}
    states: {{stream: odom}}
sources:
  - {{type: tum, name: odom, path: odom.tum}}
  - {{type: tum, name: abs, path: abs.tum}}
factors:
  - {{type: pose.origin, robot: r, sigma: {origin}}}
  - {{type: pose.relative, robot: r, stream: odom, sigma: {odom}}}
  - {{type: pose.absolute, robot: r, stream: abs, sigma: {abs}}}
initializers:
  - {{type: pose.dead_reckoning, robot: r, stream: odom, anchor: abs}}
solver: {{type: {solver}, method: lm, marginals: false}}
output: {{plots: false}}
"""


def _sig(s: dict) -> str:
    return f"{{rotation: {s['rotation']}, translation: {s['translation']}}}"


def _sigmas6(s: dict) -> np.ndarray:
    return np.array([s["rotation"]] * 3 + [s["translation"]] * 3)


def _perturb(poses: list[gtsam.Pose3], sigma: dict, rng) -> list[gtsam.Pose3]:
    xi = rng.standard_normal((len(poses), 6)) * _sigmas6(sigma)
    return [p.compose(gtsam.Pose3.Expmap(x)) for p, x in zip(poses, xi)]


def write_dataset(folder: Path, n: int, solver: str = "batch", seed: int = 0) -> Path:
    """Truth: 0.1 m forward per state on a 20 m circle with gentle roll/pitch/heave, starting at the
    identity. Odometry = noisy truth increments integrated from the identity; absolute = noisy truth."""
    rng = np.random.default_rng(seed)
    k = np.arange(n - 1)
    xi = np.zeros((n - 1, 6))
    xi[:, 0] = 0.002 * np.sin(0.01 * k)   # roll rate
    xi[:, 1] = 0.002 * np.cos(0.013 * k)  # pitch rate
    xi[:, 2] = 0.1 / 20.0                 # yaw rate: 20 m circle
    xi[:, 3] = 0.1
    xi[:, 5] = 0.01 * np.sin(0.02 * k)    # heave
    inc = [gtsam.Pose3.Expmap(x) for x in xi]
    truth = [gtsam.Pose3()]
    for d in inc:
        truth.append(truth[-1].compose(d))
    odom = [gtsam.Pose3()]
    for d in _perturb(inc, ODOM_SIGMA, rng):
        odom.append(odom[-1].compose(d))
    rows = np.arange(0, n, ABS_EVERY)
    absolute = _perturb([truth[i] for i in rows], ABS_SIGMA, rng)
    t = np.arange(n) / RATE
    folder.mkdir(parents=True, exist_ok=True)
    write_tum(folder / "odom.tum", pose_stream("odom", t, pose_array_from(odom)))
    write_tum(folder / "abs.tum", pose_stream("abs", t[rows], pose_array_from(absolute)))
    config = folder / f"chain_{n}_{solver}.yaml"
    config.write_text(CONFIG.format(n=n, solver=solver, origin=_sig(ORIGIN_SIGMA), odom=_sig(ODOM_SIGMA),
                                    abs=_sig(ABS_SIGMA)))
    return config


def load_arrays(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(N, 8) and (M, 8) arrays t x y z qx qy qz qw of the odometry and absolute TUM files."""
    return np.loadtxt(folder / "odom.tum"), np.loadtxt(folder / "abs.tum")


def _poses(a: np.ndarray) -> list[gtsam.Pose3]:
    return [gtsam.Pose3(gtsam.Rot3.Quaternion(r[7], r[4], r[5], r[6]), r[1:4]) for r in a]


def handwritten_graph(odom: np.ndarray, absolute: np.ndarray) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
    """The graph of the config above, written directly against GTSAM (keys 0..N-1)."""
    origin_noise = gtsam.noiseModel.Diagonal.Sigmas(_sigmas6(ORIGIN_SIGMA))
    odom_noise = gtsam.noiseModel.Diagonal.Sigmas(_sigmas6(ODOM_SIGMA))
    abs_noise = gtsam.noiseModel.Diagonal.Sigmas(_sigmas6(ABS_SIGMA))
    graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
    graph.add(gtsam.PriorFactorPose3(0, gtsam.Pose3(), origin_noise))
    meas = _poses(odom)
    abs_poses = _poses(absolute)
    x = abs_poses[0]  # dead reckoning anchored at the first absolute pose
    initial.insert(0, x)
    for k in range(len(meas) - 1):
        d = meas[k].between(meas[k + 1])
        graph.add(gtsam.BetweenFactorPose3(k, k + 1, d, odom_noise))
        x = x.compose(d)
        initial.insert(k + 1, x)
    idx = np.searchsorted(odom[:, 0], absolute[:, 0])
    for k, p in zip(idx, abs_poses):
        graph.add(gtsam.PriorFactorPose3(int(k), p, abs_noise))
    return graph, initial


# fusionkit's batch LM defaults, written out (bench_batch warns if fusionkit's change): tolerances
# of fusionkit/solve/batch.py, lambda schedule of fusionkit.solve.levenberg.DampingSettings, which
# damps lambda * diag(J^T J) like GTSAM's diagonalDamping (same min/max diagonal 1e-6 / 1e32)
LM_DEFAULTS = {"lambda_initial": 1e-5, "lambda_factor": 10.0, "lambda_upper": 1e5, "lambda_lower": 0.0,
               "min_diagonal": 1e-6, "max_diagonal": 1e32, "scaled": True}


def lm_params() -> gtsam.LevenbergMarquardtParams:
    """GTSAM's LM with the settings fusionkit's batch LM uses by default (LM_DEFAULTS)."""
    d = LM_DEFAULTS
    p = gtsam.LevenbergMarquardtParams()
    p.setRelativeErrorTol(1e-6)
    p.setAbsoluteErrorTol(1e-9)
    p.setMaxIterations(100)
    p.setlambdaInitial(d["lambda_initial"])
    p.setlambdaFactor(d["lambda_factor"])
    p.setlambdaUpperBound(d["lambda_upper"])
    p.setlambdaLowerBound(d["lambda_lower"])
    p.setDiagonalDamping(True)
    return p


def isam2_params() -> gtsam.ISAM2Params:
    """The same settings fusionkit's iSAM2 solver uses by default."""
    p = gtsam.ISAM2Params()
    p.setRelinearizeThreshold(0.01)
    p.relinearizeSkip = 1
    return p
