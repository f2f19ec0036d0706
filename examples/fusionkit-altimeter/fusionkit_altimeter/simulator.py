"""`altimeter.demo`: a synthetic drone flight with truth, for the demo config and for tests.

Streams (all times in s):
- `odom`  — VO-like odometry: noisy relative poses integrated from identity (a pose stream that
            drifts), one sample per state;
- `gnss`  — sparse absolute poses (GNSS + heading), every `absolute_every` states;
- `baro`  — altimeter readings (column `height`, m) at `baro_rate`, stamped `baro_offset` s after
            the odometry clock: true body height + `bias` + N(0, `baro_sigma`^2).
Truth: the `drone` trajectory and its `baro_bias`.
"""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from fusionkit.api import POSE_COLUMNS, Simulator, SourceOutput, Stream, pose_stream, poses_from_array

POSE_SIGMA = {"type": "object",
              "properties": {"rotation": {"type": "number", "minimum": 0},
                             "translation": {"type": "number", "minimum": 0}},
              "required": ["rotation", "translation"], "additionalProperties": False}
POSITIVE = {"type": "number", "exclusiveMinimum": 0}


def flight(t: np.ndarray) -> np.ndarray:
    """(N, 7) x y z qx qy qz qw: an ellipse (10 m x 6 m, 40 s per lap) while climbing and
    descending between 1.5 and 4.5 m, heading along the velocity, a little roll and pitch."""
    w = 2 * np.pi / 40.0
    pos = np.column_stack([5.0 * np.cos(w * t), 3.0 * np.sin(w * t),
                           3.0 + 1.5 * np.sin(2 * np.pi * t / 25.0)])
    yaw = np.unwrap(np.arctan2(3.0 * np.cos(w * t), -5.0 * np.sin(w * t)))
    roll, pitch = 0.08 * np.sin(0.9 * t), 0.05 * np.cos(0.6 * t)
    quat = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_quat()
    return np.column_stack([pos, quat])


def _perturb(poses: list[gtsam.Pose3], sigma: dict, rng: np.random.Generator) -> list[gtsam.Pose3]:
    """Each pose times Exp(xi), xi ~ N(0, diag(rot^2 x3, trans^2 x3)) (body frame)."""
    s = np.array([sigma["rotation"]] * 3 + [sigma["translation"]] * 3)
    return [p.compose(gtsam.Pose3.Expmap(x)) for p, x in zip(poses, rng.standard_normal((len(poses), 6)) * s)]


class AltimeterDemo(Simulator):
    name = "altimeter.demo"
    summary = "drone flight: VO-like odometry, sparse absolute poses and a biased barometric altimeter"
    schema = {"type": "object",
              "properties": {"duration": POSITIVE, "rate": POSITIVE, "bias": {"type": "number"},
                             "baro_rate": POSITIVE, "baro_sigma": {"type": "number", "minimum": 0},
                             "baro_offset": {"type": "number", "minimum": 0},
                             "odom_sigma": POSE_SIGMA, "absolute_sigma": POSE_SIGMA,
                             "absolute_every": {"type": "integer", "minimum": 1}},
              "additionalProperties": False}
    defaults = {"duration": 60.0, "rate": 20.0, "bias": 1.7, "baro_rate": 10.0, "baro_sigma": 0.1,
                "baro_offset": 0.002, "absolute_every": 40,
                "odom_sigma": {"rotation": 0.002, "translation": 0.01},
                "absolute_sigma": {"rotation": 0.02, "translation": 0.05}}

    def stream_columns(self, params: dict) -> dict[str, tuple[str, ...]]:
        return {"odom": POSE_COLUMNS, "gnss": POSE_COLUMNS, "baro": ("height",)}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        t = np.arange(int(round(params["duration"] * params["rate"]))) / params["rate"]
        truth_arr = flight(t)
        truth = poses_from_array(truth_arr)

        steps = _perturb([a.between(b) for a, b in zip(truth[:-1], truth[1:])], params["odom_sigma"], rng)
        odom = [gtsam.Pose3()]
        for d in steps:
            odom.append(odom[-1].compose(d))

        rows = np.arange(0, len(t), params["absolute_every"])
        gnss = _perturb([truth[i] for i in rows], params["absolute_sigma"], rng)

        t_baro = np.arange(0.0, t[-1], 1.0 / params["baro_rate"]) + params["baro_offset"]
        t_baro = t_baro[t_baro <= t[-1]]
        height = flight(t_baro)[:, 2] + params["bias"] + params["baro_sigma"] * rng.standard_normal(len(t_baro))

        return SourceOutput(
            streams={"odom": pose_stream("odom", t, odom, "simulated:odom"),
                     "gnss": pose_stream("gnss", t[rows], gnss, "simulated:gnss"),
                     "baro": Stream("baro", t_baro, ("height",), height[:, None], "simulated:baro")},
            truth_trajectories={"drone": pose_stream("drone", t, truth_arr, "simulated:truth")},
            truth_calibration={"drone": {"baro_bias": {"type": "scalar", "value": float(params["bias"])}}})

    def robots(self, params: dict) -> dict[str, dict]:
        """The description `fusionkit simulate` writes to robots/drone.yaml (as in robots/)."""
        return {"drone": {
            "name": "survey_drone", "model": "generic", "frames": ["world", "body"],
            "sensors": {"camera": {"type": "camera", "frame": "body"},
                        "gnss": {"type": "gnss_heading", "frame": "body"},
                        "baro": {"type": "barometer", "frame": "body"}},
            "parameters": {"baro_bias": {"type": "scalar", "value": 0.0, "sigma": 10.0, "unit": "m"}}}}

    def config(self, params: dict) -> dict:
        """A runnable config for the written dataset (`fusionkit simulate` adds sources/truth)."""
        floor = {k: max(v, 1e-4) for k, v in params["odom_sigma"].items()}
        absolute = {k: max(v, 1e-4) for k, v in params["absolute_sigma"].items()}
        return {
            "robots": {"drone": {"description": "robots/drone.yaml", "states": {"stream": "odom"}}},
            "factors": [
                {"type": "pose.relative", "robot": "drone", "stream": "odom", "sigma": floor},
                {"type": "pose.absolute", "robot": "drone", "stream": "gnss", "sigma": absolute},
                {"type": "altimeter.height", "robot": "drone", "stream": "baro", "bias": "baro_bias",
                 "sigma": max(params["baro_sigma"], 1e-3), "tolerance": 0.5 / params["rate"]}],
            "initializers": [{"type": "pose.dead_reckoning", "robot": "drone", "stream": "odom",
                              "anchor": "gnss"}],
            "solver": {"type": "batch", "method": "lm"}}


SIMULATORS = [AltimeterDemo]
