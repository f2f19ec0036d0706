"""`camera.demo`: a hand-held camera filmed by motion capture while it looks at a calibration target.

Streams (times in s):
- `mocap`  -- the camera's pose at each frame, with noise (a pose stream);
- `pixels` -- per frame, the pixel (u, v) of each target point inside the image, with noise, and the point's
              world position (x, y, z; m): columns u, v, x, y, z, one row per point (rows of a frame share its
              stamp).
The target is a grid of points on the plane z = 0 (world), the camera sweeps an arc 0.7-1.3 m in front of it,
always aimed at its centre, tilted up to ~40 degrees so that focal length and distance separate.
Truth: the `rig` trajectory and its intrinsics `K`.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import POSE_COLUMNS, POSE_NOISE_SCHEMA, POSITIVE_SCHEMA, Simulator, SourceOutput, Stream, pose_stream

from .factors import COLUMNS

IMAGE = (640, 480)  # width, height (px)


def target_points(rows: int, columns: int, spacing: float) -> np.ndarray:
    """(rows * columns, 3) grid points on z = 0, centred on the origin (m)."""
    x, y = np.meshgrid((np.arange(columns) - (columns - 1) / 2) * spacing, (np.arange(rows) - (rows - 1) / 2) * spacing)
    return np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])


def camera_path(t: np.ndarray, duration: float) -> list[gtsam.Pose3]:
    """Poses (camera frame: x right, y down, z forward) on an arc in front of the target, aimed at its centre."""
    s = 2 * np.pi * t / duration
    centres = np.column_stack([0.5 * np.sin(s), 0.35 * np.sin(2 * s), -(1.0 + 0.3 * np.cos(3 * s))])
    poses = []
    for c, roll in zip(centres, 0.3 * np.sin(1.5 * s)):
        z = -c / np.linalg.norm(c)
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        rotation = gtsam.Rot3(np.column_stack([x, np.cross(z, x), z])).compose(gtsam.Rot3.Rz(roll))
        poses.append(gtsam.Pose3(rotation, c))
    return poses


def project(pose: gtsam.Pose3, k: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pixels (n, 2), in front of the camera and inside the image (n,) bool)."""
    p = np.array([pose.transformTo(x) for x in points])
    xn, yn = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    pixels = np.column_stack([k[0] * xn + k[2] * yn + k[3], k[1] * yn + k[4]])
    inside = (p[:, 2] > 0) & (pixels[:, 0] >= 0) & (pixels[:, 0] < IMAGE[0]) & (pixels[:, 1] >= 0) & \
        (pixels[:, 1] < IMAGE[1])
    return pixels, inside


class CameraDemo(Simulator):
    name = "camera.demo"
    summary = "hand-held camera in motion capture looking at a grid target: mocap poses and pixels, true intrinsics"
    schema = {"type": "object",
              "properties": {"duration": POSITIVE_SCHEMA, "rate": POSITIVE_SCHEMA,
                             "intrinsics": {"type": "array", "items": {"type": "number"}, "minItems": 5,
                                            "maxItems": 5},
                             "pixel_sigma": {"type": "number", "minimum": 0}, "mocap_sigma": POSE_NOISE_SCHEMA,
                             "target": {"type": "object",
                                        "properties": {"rows": {"type": "integer", "minimum": 2},
                                                       "columns": {"type": "integer", "minimum": 2},
                                                       "spacing": POSITIVE_SCHEMA},
                                        "additionalProperties": False}},
              "additionalProperties": False}
    defaults = {"duration": 20.0, "rate": 5.0, "intrinsics": [525.0, 518.0, 0.0, 316.0, 243.0], "pixel_sigma": 0.5,
                "mocap_sigma": {"rotation": 0.002, "translation": 0.001},
                "target": {"rows": 5, "columns": 7, "spacing": 0.1}}

    def stream_columns(self, params: dict) -> dict[str, tuple[str, ...]]:
        return {"mocap": POSE_COLUMNS, "pixels": COLUMNS}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        t = np.arange(int(round(params["duration"] * params["rate"]))) / params["rate"]
        truth = camera_path(t, params["duration"])
        k = np.asarray(params["intrinsics"], dtype=float)
        points = target_points(**{"rows": 5, "columns": 7, "spacing": 0.1, **params["target"]})
        sigma = params["mocap_sigma"]
        steps = rng.standard_normal((len(t), 6)) * np.r_[[sigma["rotation"]] * 3, [sigma["translation"]] * 3]
        mocap = [p.compose(gtsam.Pose3.Expmap(d)) for p, d in zip(truth, steps)]
        stamps, rows = [], []
        for time, pose in zip(t, truth):
            pixels, inside = project(pose, k, points)
            pixels = pixels[inside] + params["pixel_sigma"] * rng.standard_normal((int(inside.sum()), 2))
            stamps += [time] * len(pixels)
            rows.append(np.column_stack([pixels, points[inside]]))
        return SourceOutput(
            streams={"mocap": pose_stream("mocap", t, mocap, "simulated:mocap"),
                     "pixels": Stream("pixels", np.asarray(stamps), COLUMNS, np.vstack(rows), "simulated:pixels")},
            truth_trajectories={"rig": pose_stream("rig", t, truth, "simulated:truth")},
            truth_calibration={"rig": {"K": {"type": "cal3_s2", "value": [float(x) for x in k]}}})

    def robots(self, params: dict) -> dict[str, dict]:
        """The description `fusionkit simulate` writes to robots/rig.yaml (as in robots/)."""
        return {"rig": {"name": "camera_rig", "model": "generic", "frames": ["world", "camera"],
                        "sensors": {"camera": {"type": "camera", "frame": "camera"}},
                        "parameters": {"K": {"type": "cal3_s2", "value": [500.0, 500.0, 0.0, 320.0, 240.0],
                                             "sigma": [100.0, 100.0, 10.0, 50.0, 50.0], "unit": "px"}}}}

    def config(self, params: dict) -> dict:
        """A runnable config for the written dataset (`fusionkit simulate` adds sources/truth)."""
        sigma = {k: max(v, 1e-4) for k, v in params["mocap_sigma"].items()}
        return {"robots": {"rig": {"description": "robots/rig.yaml", "states": {"stream": "mocap"}}},
                "factors": [{"type": "pose.absolute", "robot": "rig", "stream": "mocap", "sigma": sigma},
                            {"type": "camera.pixel", "robot": "rig", "stream": "pixels", "intrinsics": "K",
                             "sigma": max(params["pixel_sigma"], 1e-3)}],
                "initializers": [{"type": "pose.interpolate", "robot": "rig", "stream": "mocap"}],
                "solver": {"type": "batch", "method": "lm"}}


SIMULATORS = [CameraDemo]
