"""What a robot model draws of itself (`RobotModel.geometry`): points and line segments in the world frame
(m), with a label and a colour. Plain data, written to the output folder's scene.json."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Points:
    """Points (N, 3), drawn as markers (e.g. pulleys, anchors, joints)."""

    label: str
    xyz: np.ndarray
    color: str = "#1f77b4"
    size: float = 6.0

    def to_json(self) -> dict:
        return {"kind": "points", "label": self.label, "color": self.color, "size": self.size,
                "xyz": np.asarray(self.xyz, float).reshape(-1, 3).tolist()}


@dataclass(frozen=True)
class Lines:
    """Line segments (N, 2, 3) (e.g. cables from pulley to attachment, arm links)."""

    label: str
    segments: np.ndarray
    color: str = "#444444"
    width: float = 1.5

    def to_json(self) -> dict:
        return {"kind": "lines", "label": self.label, "color": self.color, "width": self.width,
                "segments": np.asarray(self.segments, float).reshape(-1, 2, 3).tolist()}


def polyline(points: np.ndarray) -> np.ndarray:
    """Consecutive points (N, 3) as N - 1 segments (N - 1, 2, 3)."""
    p = np.asarray(points, float)
    return np.stack([p[:-1], p[1:]], axis=1)
