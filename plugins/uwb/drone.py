"""`uwb.drone`: a UWB-tagged vehicle flying in 3-D among anchors at several heights, with an IMU
between the ranging epochs.

The path is a 3-D Lissajous curve in a 10 x 8 m room (1 to 2 m high), the yaw follows the
horizontal velocity, roll and pitch sway by a few degrees. The IMU (`imu_rate` Hz) measures the
specific force R^T (a - g) and the body rate (from the attitude on a fine grid) with white noise
(`accel_density`, `gyro_density`, per sqrt(Hz)) and constant biases (`accel_bias`, `gyro_bias`
standard deviations). Ranging at `rate` Hz to 6 anchors with a constant bias per anchor
(N(0, bias_sigma)) and `range_sigma` noise.

Streams: `ranges` (t, r0..r5), `imu` (t, ax, ay, az, gx, gy, gz). Truth: the trajectory, the
anchors and the IMU bias.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from fusionkit.api import pose_stream, sample_times, Simulator, SourceOutput, Stream

from .simulator import ANCHORS

VEHICLE = "drone"
GRAVITY = 9.81
POSITIVE = {"type": "number", "exclusiveMinimum": 0}
NONNEG = {"type": "number", "minimum": 0}
ANCHOR_POINTS = [[0.0, 0.0, 0.3], [10.0, 0.0, 2.7], [10.0, 8.0, 0.3], [0.0, 8.0, 2.7], [5.0, 0.0, 2.9],
                 [5.0, 8.0, 0.2]]
LAP = 30.0  # s


def flight(t: np.ndarray, phase: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (N, 3), world accelerations (N, 3) and attitudes (N, 3, 3) at the times t."""
    w = 2 * np.pi / LAP
    c, h = np.array([5.0, 4.0, 1.5]), np.array([3.5, 2.8, 0.5])
    f = np.array([w, 2 * w, 3 * w])
    ph = np.array([phase, 1.7 * phase, 0.4])
    pos = c + h * np.sin(f * t[:, None] + ph)
    vel = h * f * np.cos(f * t[:, None] + ph)
    acc = -h * f ** 2 * np.sin(f * t[:, None] + ph)
    yaw = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    roll, pitch = np.radians(3.0) * np.sin(1.3 * w * t), np.radians(2.0) * np.sin(0.9 * w * t + 0.5)
    R = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    return pos, acc, R


def body_rates(t: np.ndarray, phase: float = 0.0, h: float = 1e-4) -> np.ndarray:
    """Body angular velocity (N, 3) by central differences of the attitude (error O(h^2))."""
    _, _, Rm = flight(t - h, phase)
    _, _, Rp = flight(t + h, phase)
    return Rotation.from_matrix(np.einsum("nji,njk->nik", Rm, Rp)).as_rotvec() / (2 * h)


class UwbDroneSimulator(Simulator):
    name = "uwb.drone"
    summary = "a UWB-tagged vehicle flying in 3-D among 6 anchors at several heights, with an IMU: ranges, IMU, truth"
    schema = {"type": "object",
              "properties": {"duration": POSITIVE, "rate": POSITIVE, "imu_rate": POSITIVE, "range_sigma": NONNEG,
                             "bias_sigma": NONNEG, "accel_density": NONNEG, "gyro_density": NONNEG,
                             "accel_bias": NONNEG, "gyro_bias": NONNEG},
              "additionalProperties": False}
    defaults = {"duration": 60.0, "rate": 10.0, "imu_rate": 200.0, "range_sigma": 0.05, "bias_sigma": 0.1,
                "accel_density": 0.02, "gyro_density": 0.002, "accel_bias": 0.05, "gyro_bias": 0.005}

    def stream_columns(self, params: dict):
        return {"ranges": tuple(f"r{i}" for i in range(len(ANCHOR_POINTS))), "imu": ("ax", "ay", "az", "gx", "gy", "gz")}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        p = {**self.defaults, **params}
        anchors = np.asarray(ANCHOR_POINTS)
        t = sample_times(p["duration"], p["rate"])
        pos, _, R = flight(t)
        bias = rng.normal(0.0, p["bias_sigma"], len(anchors))
        z = (np.linalg.norm(pos[:, None, :] - anchors[None], axis=2) + bias
             + rng.normal(0.0, p["range_sigma"], (len(t), len(anchors))))
        ti = sample_times(p["duration"], p["imu_rate"])
        _, acc, Ri = flight(ti)
        accel_bias = rng.normal(0.0, p["accel_bias"], 3)
        gyro_bias = rng.normal(0.0, p["gyro_bias"], 3)
        specific = np.einsum("nji,nj->ni", Ri, acc + [0.0, 0.0, GRAVITY])
        root = np.sqrt(p["imu_rate"])  # white noise density -> per-sample sigma
        imu = np.column_stack([specific + accel_bias + rng.normal(0.0, p["accel_density"] * root, specific.shape),
                               body_rates(ti) + gyro_bias + rng.normal(0.0, p["gyro_density"] * root, (len(ti), 3))])
        streams = {"ranges": Stream("ranges", t, tuple(f"r{i}" for i in range(len(anchors))), z, "simulated:ranges"),
                   "imu": Stream("imu", ti, ("ax", "ay", "az", "gx", "gy", "gz"), imu, "simulated:imu")}
        quat = Rotation.from_matrix(R).as_quat()
        calibration = {ANCHORS: {"anchor": {"type": "point3", "values": anchors.tolist()}},
                       VEHICLE: {"imu_bias": {"type": "imu_bias", "value": [float(x) for x in (*accel_bias, *gyro_bias)]},
                                 "uwb_bias": {"type": "scalar", "values": bias.tolist()}}}
        return SourceOutput(streams, {VEHICLE: pose_stream(VEHICLE, t, np.column_stack([pos, quat]), "simulated:truth")},
                            calibration)

    def robots(self, params: dict) -> dict[str, dict]:
        n = len(ANCHOR_POINTS)
        return {ANCHORS: {"name": ANCHORS, "summary": "6 UWB anchors at several heights in a 10 x 8 m room",
                          "parameters": {"anchor": {"type": "point3", "values": ANCHOR_POINTS, "sigma": 0.001}}},
                VEHICLE: {"name": VEHICLE, "summary": "UWB tag and IMU at the body origin",
                          "sensors": {"tag": {"type": "uwb_tag", "frame": "body"}, "imu": {"type": "imu", "frame": "body"}},
                          "parameters": {"uwb_bias": {"type": "scalar", "values": [0.0] * n, "sigma": 1.0},
                                         "imu_bias": {"type": "imu_bias", "value": [0.0] * 6,
                                                      "sigma": [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]}}}}

    def config(self, params: dict) -> dict:
        """UWB ranges with a constant bias per anchor, the IMU between epochs; multilateration
        (heading along the travel) and velocities from it; batch Levenberg-Marquardt."""
        p = {**self.defaults, **params}
        return {"robots": {ANCHORS: {"description": f"robots/{ANCHORS}.yaml"},
                           VEHICLE: {"description": f"robots/{VEHICLE}.yaml", "states": {"stream": "ranges"}}},
                "factors": [{"type": "uwb.range", "robot": VEHICLE, "stream": "ranges", "anchors": ANCHORS,
                             "tag": "tag", "bias": "uwb_bias", "sigma": max(p["range_sigma"], 1e-3)},
                            {"type": "imu.preintegrated", "robot": VEHICLE, "stream": "imu", "bias": "imu_bias",
                             "sigma": {"accelerometer": max(p["accel_density"], 1e-4),
                                       "gyroscope": max(p["gyro_density"], 1e-5)}}],
                "initializers": [{"type": "uwb.multilateration", "robot": VEHICLE, "anchors": ANCHORS,
                                  "stream": "ranges", "tag": "tag", "heading": "travel"},
                                 {"type": "imu.velocity", "robot": VEHICLE}],
                "solver": {"type": "batch", "method": "lm"}}
