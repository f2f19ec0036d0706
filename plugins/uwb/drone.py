"""`uwb.drone`: a UWB-tagged vehicle flying in 3-D among anchors at several heights, with an IMU
between the ranging epochs.

The path is a 3-D Lissajous curve in a 10 x 8 m room (1 to 2 m high), the yaw follows the
horizontal velocity, roll and pitch sway by a few degrees. The IMU (`imu_rate` Hz) measures the
specific force R^T (a - g) and the body rate (from the attitude on a fine grid) over the interval that
its stamp starts (at the interval's midpoint: fusionkit's preintegration holds each sample until the
next, and an instantaneous sample would lag that by half an interval) with white noise
(`accel_density`, `gyro_density`, per sqrt(Hz)) and constant biases (`accel_bias`, `gyro_bias`
standard deviations). Ranging at `rate` Hz to 6 anchors with a constant bias per anchor
(N(0, bias_sigma)) and `range_sigma` noise.

Motion capture (`mocap_rate` > 0 Hz): the body pose with `mocap_sigma` noise (body frame), stream `mocap`;
the config then adds it as `pose.absolute`.

Motion capture on a clock of its own, `time_offset: {mocap: s}` (or `{mocap: {offset: s, rate: s/s}}`):
the pose stamped t shows the vehicle at t + offset (+ rate (t - t0)) on the IMU's clock, which is the
states' (fusionkit's sign convention, docs/models/unified_graph.md#time-offsets; motion capture that lags
the IMU by 20 ms is `mocap: -0.02`). The config then estimates `mocap_time_offset` (and
`mocap_clock_rate`), from a first guess by `time.offset_guess` (the mocap's turn rate against the gyro's).

Streams: `ranges` (t, r0..r5), `imu` (t, ax, ay, az, gx, gy, gz), `mocap` (poses; with `mocap_rate`). Truth:
the trajectory, the anchors, the IMU bias and the clocks.
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import (CLOCK_SCHEMA, GRAVITY, NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS, POSE_NOISE_SCHEMA,
                           POSITIVE_SCHEMA as POSITIVE, Simulator, SourceOutput, Stream, clock_times, pose_stream,
                           sample_times)

from .simulators import ANCHORS

VEHICLE = "drone"
ANCHOR_POINTS = [[0.0, 0.0, 0.3], [10.0, 0.0, 2.7], [10.0, 8.0, 0.3], [0.0, 8.0, 2.7], [5.0, 0.0, 2.9],
                 [5.0, 8.0, 0.2]]
LAP = 30.0  # s
IMU_COLUMNS = ("ax", "ay", "az", "gx", "gy", "gz")
CLOCKED = {"mocap": "mocap"}  # stream -> its clock parameters' prefix
OFFSET_PARAMETER = {"type": "scalar", "value": 0.0, "sigma": 1.0, "unit": "s"}
CLOCK_RATE_PARAMETER = {"type": "scalar", "value": 0.0, "sigma": 0.01, "unit": "s/s"}


def _clock_parameters(clocks: dict) -> dict[str, float]:
    """The true clock of each stream with a time offset: {<prefix>_time_offset: s, <prefix>_clock_rate: s/s}."""
    out = {}
    for stream, clock in clocks.items():
        offset, rate = (clock["offset"], clock.get("rate")) if isinstance(clock, dict) else (clock, None)
        out[f"{CLOCKED[stream]}_time_offset"] = float(offset)
        if rate is not None:
            out[f"{CLOCKED[stream]}_clock_rate"] = float(rate)
    return out


def _mocap(p: dict, clock, rng: np.random.Generator) -> Stream:
    """Motion capture at `mocap_rate`: the body pose at each stamp's true time, noisy in the body frame."""
    from scipy.spatial.transform import Rotation
    t = sample_times(p["duration"], p["mocap_rate"])
    pos, _, R = flight(clock_times(clock, t))
    sigma = np.array([p["mocap_sigma"]["rotation"]] * 3 + [p["mocap_sigma"]["translation"]] * 3)
    xi = rng.standard_normal((len(t), 6)) * sigma
    noise = Rotation.from_rotvec(xi[:, :3])
    rot = Rotation.from_matrix(R) * noise
    position = pos + np.einsum("nij,nj->ni", R, xi[:, 3:])
    return pose_stream("mocap", t, np.column_stack([position, rot.as_quat()]), "simulated:mocap")


def flight(t: np.ndarray, phase: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (N, 3), world accelerations (N, 3) and attitudes (N, 3, 3) at the times t."""
    from scipy.spatial.transform import Rotation
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
    from scipy.spatial.transform import Rotation
    _, _, Rm = flight(t - h, phase)
    _, _, Rp = flight(t + h, phase)
    return Rotation.from_matrix(np.einsum("nji,njk->nik", Rm, Rp)).as_rotvec() / (2 * h)


class UwbDroneSimulator(Simulator):
    name = "uwb.drone"
    summary = "a UWB-tagged vehicle flying in 3-D among 6 anchors at several heights, with an IMU: ranges, IMU, truth"
    schema = {"type": "object",
              "properties": {"duration": POSITIVE, "rate": POSITIVE, "imu_rate": POSITIVE, "range_sigma": NONNEG,
                             "bias_sigma": NONNEG, "accel_density": NONNEG, "gyro_density": NONNEG,
                             "accel_bias": NONNEG, "gyro_bias": NONNEG, "mocap_rate": NONNEG,
                             "mocap_sigma": POSE_NOISE_SCHEMA,
                             "time_offset": {"type": "object",
                                             "properties": {s: CLOCK_SCHEMA for s in CLOCKED},
                                             "additionalProperties": False}},
              "additionalProperties": False}
    defaults = {"duration": 60.0, "rate": 10.0, "imu_rate": 200.0, "range_sigma": 0.05, "bias_sigma": 0.1,
                "accel_density": 0.02, "gyro_density": 0.002, "accel_bias": 0.05, "gyro_bias": 0.005,
                "mocap_rate": 0.0, "mocap_sigma": {"rotation": 0.002, "translation": 0.001}, "time_offset": {}}

    @classmethod
    def resolve(cls, params: dict, doc, path: tuple = ()) -> dict:
        full = super().resolve(params, doc, path)
        if full["time_offset"].get("mocap") is not None and not full["mocap_rate"]:
            raise doc.error(path + ("time_offset", "mocap"), "a mocap clock needs motion capture: expected "
                            "mocap_rate > 0 (Hz)")
        return full

    def stream_columns(self, params: dict):
        out = {"ranges": tuple(f"r{i}" for i in range(len(ANCHOR_POINTS))), "imu": IMU_COLUMNS}
        if params.get("mocap_rate"):
            out["mocap"] = POSE_COLUMNS
        return out

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        from scipy.spatial.transform import Rotation
        p = {**self.defaults, **params}
        anchors = np.asarray(ANCHOR_POINTS)
        clocks = p["time_offset"]
        t = sample_times(p["duration"], p["rate"])
        pos, _, R = flight(t)
        bias = rng.normal(0.0, p["bias_sigma"], len(anchors))
        z = (np.linalg.norm(pos[:, None, :] - anchors[None], axis=2) + bias
             + rng.normal(0.0, p["range_sigma"], (len(t), len(anchors))))
        ti = sample_times(p["duration"], p["imu_rate"])
        mid = ti + 0.5 / p["imu_rate"]  # the sample stamped t is the motion over [t, t + 1/rate] (its midpoint)
        _, acc, Ri = flight(mid)
        accel_bias = rng.normal(0.0, p["accel_bias"], 3)
        gyro_bias = rng.normal(0.0, p["gyro_bias"], 3)
        specific = np.einsum("nji,nj->ni", Ri, acc + [0.0, 0.0, GRAVITY])
        root = np.sqrt(p["imu_rate"])  # white noise density -> per-sample sigma
        imu = np.column_stack([specific + accel_bias + rng.normal(0.0, p["accel_density"] * root, specific.shape),
                               body_rates(mid) + gyro_bias + rng.normal(0.0, p["gyro_density"] * root, (len(ti), 3))])
        streams = {"ranges": Stream("ranges", t, tuple(f"r{i}" for i in range(len(anchors))), z, "simulated:ranges"),
                   "imu": Stream("imu", ti, ("ax", "ay", "az", "gx", "gy", "gz"), imu, "simulated:imu")}
        if p["mocap_rate"]:
            streams["mocap"] = _mocap(p, clocks.get("mocap", 0.0), rng)
        quat = Rotation.from_matrix(R).as_quat()
        calibration = {ANCHORS: {"anchor": {"type": "point3", "values": anchors.tolist()}},
                       VEHICLE: {"imu_bias": {"type": "imu_bias", "value": [float(x) for x in (*accel_bias, *gyro_bias)]},
                                 "uwb_bias": {"type": "scalar", "values": bias.tolist()},
                                 **{name: {"type": "scalar", "value": value}
                                    for name, value in _clock_parameters(clocks).items()}}}
        return SourceOutput(streams, {VEHICLE: pose_stream(VEHICLE, t, np.column_stack([pos, quat]), "simulated:truth")},
                            calibration)

    def robots(self, params: dict) -> dict[str, dict]:
        n = len(ANCHOR_POINTS)
        clocks = {**self.defaults, **params}["time_offset"]
        clock_parameters = {name: CLOCK_RATE_PARAMETER if name.endswith("_clock_rate") else OFFSET_PARAMETER
                            for name in _clock_parameters(clocks)}
        return {ANCHORS: {"name": ANCHORS, "summary": "6 UWB anchors at several heights in a 10 x 8 m room",
                          "parameters": {"anchor": {"type": "point3", "values": ANCHOR_POINTS, "sigma": 0.001}}},
                VEHICLE: {"name": VEHICLE, "summary": "UWB tag and IMU at the body origin",
                          "sensors": {"tag": {"type": "uwb_tag", "frame": "body"}, "imu": {"type": "imu", "frame": "body"}},
                          "parameters": {"uwb_bias": {"type": "scalar", "values": [0.0] * n, "sigma": 1.0},
                                         "imu_bias": {"type": "imu_bias", "value": [0.0] * 6,
                                                      "sigma": [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]},
                                         **clock_parameters}}}

    def config(self, params: dict) -> dict:
        """UWB ranges with a constant bias per anchor, the IMU between epochs, motion capture if any;
        poses from multilateration (heading along the travel) or from the motion capture, velocities from them; the mocap's time offset (and
        clock rate) estimated, first guessed against the gyro; batch Levenberg-Marquardt."""
        p = {**self.defaults, **params}
        clocks = _clock_parameters(p["time_offset"])

        def clock(stream: str) -> dict:
            prefix = CLOCKED[stream]
            if f"{prefix}_time_offset" not in clocks:
                return {}
            rate = f"{prefix}_clock_rate"
            return {"time_offset": {"parameter": f"{prefix}_time_offset", **({"rate": rate} if rate in clocks else {})}}
        factors = [{"type": "uwb.range", "robot": VEHICLE, "stream": "ranges", "anchors": ANCHORS,
                    "tag": "tag", "bias": "uwb_bias", "sigma": max(p["range_sigma"], 1e-3)},
                   {"type": "imu.preintegrated", "robot": VEHICLE, "stream": "imu", "bias": "imu_bias",
                    "sigma": {"accelerometer": max(p["accel_density"], 1e-4),
                              "gyroscope": max(p["gyro_density"], 1e-5)}}]
        initializers = [{"type": "uwb.multilateration", "robot": VEHICLE, "anchors": ANCHORS,
                         "stream": "ranges", "tag": "tag", "heading": "travel"},
                        {"type": "imu.velocity", "robot": VEHICLE}]
        if p["mocap_rate"]:
            sigma = {k: max(v, 1e-4) for k, v in p["mocap_sigma"].items()}
            factors.append({"type": "pose.absolute", "robot": VEHICLE, "stream": "mocap", "sigma": sigma,
                            **clock("mocap")})
            initializers[0] = {"type": "pose.interpolate", "robot": VEHICLE, "stream": "mocap"}
            if clock("mocap"):
                initializers.append({"type": "time.offset_guess", "robot": VEHICLE, "parameter": "mocap_time_offset",
                                     "stream": "mocap", "signal": "turn_rate", "reference": "imu",
                                     "reference_signal": "magnitude", "reference_columns": ["gx", "gy", "gz"]})
        return {"robots": {ANCHORS: {"description": f"robots/{ANCHORS}.yaml"},
                           VEHICLE: {"description": f"robots/{VEHICLE}.yaml", "states": {"stream": "ranges"}}},
                "factors": factors, "initializers": initializers, "solver": {"type": "batch", "method": "lm"}}
