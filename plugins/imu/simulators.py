"""`pose.imu_vo`: the unified graph's reference localization example (docs/models/unified_graph.md):
an IMU at twice the camera rate and monocular visual odometry with an unknown scale, the camera
dropping out for a stretch.

The body flies a 3-D Lissajous path (about 6 x 5 x 1 m, one lap in `LAP` s), heading along the
horizontal velocity, rolling and pitching by a few degrees. The world frame is the body frame at t = 0
(level, z up, so gravity is -z): the first true pose is the identity, which the config's `pose.origin`
prior states (the position and heading of a VO+IMU system are unobservable, roll and pitch are not).

- IMU (`imu_rate` Hz): specific force R^T (a - g) and body rate over the interval each stamp starts
  (sampled at its midpoint, as fusionkit's preintegration holds a sample until the next), white noise
  (`accel_density`, `gyro_density` per sqrt(Hz)) and constant biases (standard deviations `accel_bias`,
  `gyro_bias`).
- Visual odometry (`camera_rate` Hz): the camera-rate increments with their translation divided by
  `scale` and noise `vo_sigma` (in the VO's own units), chained from the identity, so it drifts. During
  the dropout [`dropout_start`, `dropout_start` + `dropout_duration`) s there are no frames; after it the
  VO has lost track and starts again from the identity (a new frame; the same scale, as if the map's
  scale were kept). No VO factor spans the gap (`max_gap`).

Streams: `imu` (t, ax, ay, az, gx, gy, gz), `vo` (poses). Truth: the trajectory, the IMU bias, the scale.
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import (GRAVITY, NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS, POSE_NOISE_SCHEMA,
                           POSITIVE_SCHEMA as POSITIVE, Simulator, SourceOutput, Stream, odometry, pose_stream,
                           poses_from_array, sample_times)

ROBOT = "cam"
LAP = 24.0  # s
IMU_COLUMNS = ("ax", "ay", "az", "gx", "gy", "gz")


def _room_path(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, world accelerations and attitudes (N, 3, 3) in the room frame (z up)."""
    from scipy.spatial.transform import Rotation
    w = 2 * np.pi / LAP
    h, f, ph = np.array([3.0, 2.5, 0.5]), np.array([w, 2 * w, 3 * w]), np.array([0.3, 1.1, 0.0])
    pos = h * np.sin(f * t[:, None] + ph)
    vel = h * f * np.cos(f * t[:, None] + ph)
    acc = -h * f ** 2 * np.sin(f * t[:, None] + ph)
    yaw = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    roll, pitch = np.radians(4.0) * np.sin(1.3 * w * t), np.radians(3.0) * np.sin(0.9 * w * t)  # level at t = 0
    R = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    return pos, acc, R


def body_path(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (N, 3), world accelerations (N, 3) and attitudes (N, 3, 3) in the world frame: the room
    frame moved so that the body at t = 0 is the identity (a rotation about z: gravity stays -z)."""
    p0, _, R0 = _room_path(np.zeros(1))
    pos, acc, R = _room_path(t)
    W = R0[0].T
    return (pos - p0) @ W.T, acc @ W.T, np.einsum("ij,njk->nik", W, R)


def body_rates(t: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """Body angular velocity (N, 3) by central differences of the attitude (error O(h^2))."""
    from scipy.spatial.transform import Rotation
    Rm, Rp = body_path(t - h)[2], body_path(t + h)[2]
    return Rotation.from_matrix(np.einsum("nji,njk->nik", Rm, Rp)).as_rotvec() / (2 * h)


def imu_samples(t: np.ndarray, rate: float, p: dict, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(K, 6) IMU samples stamped t and the true biases [accelerometer (3), gyroscope (3)]."""
    mid = t + 0.5 / rate  # the sample stamped t is the motion over [t, t + 1/rate] (its midpoint)
    _, acc, R = body_path(mid)
    bias = np.concatenate([rng.normal(0.0, p["accel_bias"], 3), rng.normal(0.0, p["gyro_bias"], 3)])
    specific = np.einsum("nji,nj->ni", R, acc + [0.0, 0.0, GRAVITY])
    root = np.sqrt(rate)  # white-noise density -> per-sample sigma
    noise = np.column_stack([rng.normal(0.0, p["accel_density"] * root, specific.shape),
                             rng.normal(0.0, p["gyro_density"] * root, specific.shape)])
    return np.column_stack([specific, body_rates(mid)]) + bias + noise, bias


class ImuVoSimulator(Simulator):
    name = "pose.imu_vo"
    summary = ("IMU at twice the camera rate + monocular VO with unknown scale; the camera drops out for a "
               "stretch: imu, vo, truth")
    schema = {"type": "object",
              "properties": {"duration": POSITIVE, "camera_rate": POSITIVE, "imu_rate": POSITIVE, "scale": POSITIVE,
                             "vo_sigma": POSE_NOISE_SCHEMA, "accel_density": NONNEG, "gyro_density": NONNEG,
                             "accel_bias": NONNEG, "gyro_bias": NONNEG, "dropout_start": NONNEG,
                             "dropout_duration": NONNEG},
              "additionalProperties": False}
    defaults = {"duration": 60.0, "camera_rate": 20.0, "imu_rate": 40.0, "scale": 2.5,
                "vo_sigma": {"rotation": 0.002, "translation": 0.002}, "accel_density": 0.02, "gyro_density": 0.002,
                "accel_bias": 0.05, "gyro_bias": 0.005, "dropout_start": 25.0, "dropout_duration": 8.0}

    @classmethod
    def resolve(cls, params: dict, doc, path: tuple = ()) -> dict:
        full = super().resolve(params, doc, path)
        if full["dropout_start"] + full["dropout_duration"] >= full["duration"] and full["dropout_duration"] > 0:
            raise doc.error(path + ("dropout_start",), "the dropout must end before the recording does: expected "
                            f"dropout_start + dropout_duration < duration ({full['duration']} s)")
        return full

    def stream_columns(self, params: dict):
        return {"imu": IMU_COLUMNS, "vo": POSE_COLUMNS}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        from scipy.spatial.transform import Rotation
        p = {**self.defaults, **params}
        t = sample_times(p["duration"], p["camera_rate"])
        pos, _, R = body_path(t)
        truth = np.column_stack([pos, Rotation.from_matrix(R).as_quat()])
        start, end = p["dropout_start"], p["dropout_start"] + p["dropout_duration"]
        seen = (t < start) | (t >= end)
        vo = []  # one chain before the dropout, a new one after it
        for part in ((t < start, t >= end) if end > start else (seen,)):
            if part.any():
                vo += odometry(poses_from_array(truth[part]), p["vo_sigma"], rng, p["scale"])
        ti = sample_times(p["duration"], p["imu_rate"])
        imu, bias = imu_samples(ti, p["imu_rate"], p, rng)
        streams = {"imu": Stream("imu", ti, IMU_COLUMNS, imu, "simulated:imu"),
                   "vo": pose_stream("vo", t[seen], vo, "simulated:vo")}
        calibration = {ROBOT: {"imu_bias": {"type": "imu_bias", "value": bias.tolist()},
                               "vo_scale": {"type": "scalar", "value": float(p["scale"])}}}
        return SourceOutput(streams, {ROBOT: pose_stream(ROBOT, t, truth, "simulated:truth")}, calibration)

    def robots(self, params: dict) -> dict[str, dict]:
        return {ROBOT: {
            "name": "imu_camera", "summary": "a camera with an IMU at its optical centre (the body frame)",
            "frames": ["world", "body"],
            "sensors": {"camera": {"type": "camera", "frame": "body"}, "imu": {"type": "imu", "frame": "body"}},
            "parameters": {"vo_scale": {"type": "scalar", "value": 1.0, "sigma": 10.0},
                           "imu_bias": {"type": "imu_bias", "value": [0.0] * 6,
                                        "sigma": [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]}}}}

    def config(self, params: dict) -> dict:
        """States at the camera rate over the IMU's span (they go on through the dropout); the origin prior,
        the scaled VO (no pair across a gap) and the preintegrated IMU; the VO's scale from the IMU, poses
        from the VO at that scale and across the dropout from the IMU, velocities from them; batch
        Levenberg-Marquardt with Levenberg's damping (lambda I: Marquardt's crawls across the dropout)."""
        p = {**self.defaults, **params}
        vo_sigma = {k: max(v, 1e-4) for k, v in p["vo_sigma"].items()}
        return {
            "robots": {ROBOT: {"description": f"robots/{ROBOT}.yaml",
                               "states": {"rate": p["camera_rate"], "stream": "imu"}}},
            "factors": [
                {"type": "pose.origin", "robot": ROBOT, "sigma": {"rotation": 1e-3, "translation": 1e-3}},
                {"type": "pose.scaled_relative", "robot": ROBOT, "stream": "vo", "scale": "vo_scale",
                 "sigma": vo_sigma, "max_gap": 1.5 / p["camera_rate"]},
                {"type": "imu.preintegrated", "robot": ROBOT, "stream": "imu", "bias": "imu_bias",
                 "sigma": {"accelerometer": max(p["accel_density"], 1e-4),
                           "gyroscope": max(p["gyro_density"], 1e-5)}}],
            "initializers": [
                {"type": "imu.odometry_scale", "robot": ROBOT, "stream": "vo", "imu": "imu", "scale": "vo_scale",
                 "max_gap": 1.5 / p["camera_rate"]},
                {"type": "pose.dead_reckoning", "robot": ROBOT, "stream": "vo", "scale": "vo_scale"},
                {"type": "imu.bridge_gaps", "robot": ROBOT, "stream": "vo", "imu": "imu",
                 "max_gap": 1.5 / p["camera_rate"]},
                {"type": "imu.velocity", "robot": ROBOT}],
            "solver": {"type": "batch", "method": "lm", "damping": "levenberg"}}
