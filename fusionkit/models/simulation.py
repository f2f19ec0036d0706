"""Building blocks for simulators: smooth trajectories, pose noise, integrated odometry.
Vectorized where the math allows; noise is drawn once per stream from the caller's generator."""

from __future__ import annotations

import gtsam
import numpy as np

from ..graph.noise import pose_sigma_schema

POSE_NOISE_SCHEMA = pose_sigma_schema(allow_zero=True)  # a simulated pose noise level; 0 = noiseless
# a simulated stream's clock: an offset (s), or {offset: s, rate: s/s} (docs/models/unified_graph.md#time-offsets)
CLOCK_SCHEMA = {"oneOf": [{"type": "number"},
                          {"type": "object", "properties": {"offset": {"type": "number"}, "rate": {"type": "number"}},
                           "required": ["offset"], "additionalProperties": False}]}


def smooth_trajectory(t: np.ndarray, amplitude: np.ndarray, frequency: np.ndarray,
                      phase: np.ndarray, offset: np.ndarray, tilt: float = 0.1) -> np.ndarray:
    """(N, 7) poses: sinusoidal position per axis (m, Hz), heading along the velocity, small
    roll/pitch oscillation of `tilt` rad."""
    from scipy.spatial.transform import Rotation
    w = 2 * np.pi * frequency
    pos = offset + amplitude * np.sin(w * t[:, None] + phase)
    vel = amplitude * w * np.cos(w * t[:, None] + phase)
    yaw = np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))
    roll = tilt * np.sin(0.7 * t)
    pitch = tilt * np.cos(0.5 * t)
    quat = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_quat()
    return np.column_stack([pos, quat])


def noisy(poses: list[gtsam.Pose3], sigma: dict, rng: np.random.Generator) -> list[gtsam.Pose3]:
    """Each pose times Exp(xi), xi ~ N(0, diag(rot^2 x3, trans^2 x3)) in the body frame."""
    s = np.array([sigma["rotation"]] * 3 + [sigma["translation"]] * 3)
    xi = rng.standard_normal((len(poses), 6)) * s
    return [p.compose(gtsam.Pose3.Expmap(x)) for p, x in zip(poses, xi)]


def odometry(poses: list[gtsam.Pose3], sigma: dict, rng: np.random.Generator,
             scale: float = 1.0) -> list[gtsam.Pose3]:
    """Integrated noisy increments starting at identity. Translations are divided by `scale`
    (thesis eq. 4.3) before the noise is applied, so sigma.translation is in the odometry's own units."""
    increments = [a.between(b) for a, b in zip(poses[:-1], poses[1:])]
    scaled = noisy([gtsam.Pose3(d.rotation(), d.translation() / scale) for d in increments], sigma, rng)
    out = [gtsam.Pose3()]
    for d in scaled:
        out.append(out[-1].compose(d))
    return out


def sample_times(duration: float, rate: float) -> np.ndarray:
    """Sample times (s) of a `duration`-second recording at `rate` Hz, starting at 0."""
    return np.arange(int(round(duration * rate))) / rate


def clock_times(clock: float | dict, t: np.ndarray) -> np.ndarray:
    """When the samples a stream's clock (CLOCK_SCHEMA) stamps `t` were taken on the true clock (s):
    t + offset + rate (t - t[0])."""
    if not isinstance(clock, dict):
        return t + float(clock)
    return t + float(clock["offset"]) + float(clock.get("rate", 0.0)) * (t - t[0])
