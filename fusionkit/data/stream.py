"""Streams: timestamped tables (seconds, SI units) that sources produce and factors consume."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..errors import DataError
from .quaternions import quaternions_xyzw

POSE_COLUMNS = ("x", "y", "z", "qx", "qy", "qz", "qw")
PLANAR_POSE_COLUMNS = ("x", "y", "theta")


@dataclass
class Stream:
    """N samples: times `t` (s, non-decreasing: round-robin logs stamp several readings alike) and `values`
    (N x len(columns)); not modified once read (its poses are converted once)."""

    name: str
    t: np.ndarray
    columns: tuple[str, ...]
    values: np.ndarray
    origin: str = ""
    notes: list[str] = field(default_factory=list, compare=False)  # what reading it corrected, for the report
    # several recordings laid end to end (a source given several files): each one's (origin, first t, last t)
    parts: tuple[tuple[str, float, float], ...] = field(default=(), compare=False)
    _poses: list | None = field(default=None, init=False, repr=False, compare=False)  # poses(), made once

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float).reshape(-1)
        self.values = np.asarray(self.values, dtype=float).reshape(len(self.t), len(self.columns))
        self.columns = tuple(self.columns)
        check_samples(self.t, self.values, self.origin or self.name)

    def __len__(self) -> int:
        return len(self.t)

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.columns.index(name)]

    def has(self, *names: str) -> bool:
        return all(n in self.columns for n in names)

    @property
    def is_pose(self) -> bool:
        return self.has(*POSE_COLUMNS)

    def pose_array(self) -> np.ndarray:
        """(N, 7) array x y z qx qy qz qw, quaternions normalized."""
        a = np.stack([self.column(c) for c in POSE_COLUMNS], axis=1)
        a[:, 3:] /= np.linalg.norm(a[:, 3:], axis=1, keepdims=True)
        return a

    def poses(self) -> list[gtsam.Pose3]:
        """The rows as Pose3 (a new list; converted on the first call only)."""
        if self._poses is None:
            self._poses = poses_from_array(self.pose_array())
        return list(self._poses)

    def repeated_stamps(self) -> tuple[int, float]:
        """(how many samples repeat the previous sample's stamp, the first such stamp in s; nan if none)."""
        same = np.diff(self.t) == 0
        return int(same.sum()), float(self.t[1:][same][0]) if same.any() else float("nan")

    def subset(self, rows: np.ndarray) -> "Stream":
        return Stream(self.name, self.t[rows], self.columns, self.values[rows], self.origin)


def poses_from_array(a: np.ndarray) -> list[gtsam.Pose3]:
    """(N, 7) x y z qx qy qz qw -> Pose3 list."""
    a, pose, quaternion = np.asarray(a, dtype=float).reshape(-1, 7), gtsam.Pose3, gtsam.Rot3.Quaternion
    qx, qy, qz, qw = a[:, 3:].T.tolist()  # columns as lists of floats: no Python object per row
    return [pose(quaternion(w, x, y, z), t) for w, x, y, z, t in zip(qw, qx, qy, qz, a[:, :3])]


def pose_array_from(poses: list[gtsam.Pose3]) -> np.ndarray:
    """Pose3 list -> (N, 7) x y z qx qy qz qw (the quaternion of p.rotation().toQuaternion())."""
    m = np.array([p.matrix() for p in poses], dtype=float).reshape(-1, 4, 4)
    return pose_array_of(m[:, :3, :3], m[:, :3, 3])


def pose_array_of(rotations: np.ndarray, translations: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices and (N, 3) translations -> (N, 7) x y z qx qy qz qw, as pose_array_from."""
    return np.column_stack([np.reshape(translations, (-1, 3)), quaternions_xyzw(rotations)])


def pose_stream(name: str, t: np.ndarray, poses: list[gtsam.Pose3] | np.ndarray, origin: str = "") -> Stream:
    arr = poses if isinstance(poses, np.ndarray) else pose_array_from(poses)
    return Stream(name, t, POSE_COLUMNS, arr, origin)


def check_samples(t: np.ndarray, values: np.ndarray, origin: str, first_line: int = 1,
                  lines: np.ndarray | None = None) -> None:
    """Reject NaN/inf and timestamps that go back in time, saying how many rows and the first line (equal
    stamps pass: the components that need strictly increasing ones refuse them, pipeline.check_stamps).

    Row i is reported as line `lines[i]` when given (files with comments or blank lines), else
    as `first_line + i`.
    """
    if len(t) == 0:
        raise DataError(f"{origin}: no samples (expected at least one data row)")
    line_of = (lambda i: int(lines[i])) if lines is not None else (lambda i: first_line + i)
    finite = np.isfinite(np.sum(t) + np.sum(values))  # False for any NaN or inf (or a sum that overflows)
    bad = np.zeros(len(t), dtype=bool) if finite else ~np.isfinite(t) | ~np.all(np.isfinite(values), axis=1)
    if bad.any():
        first = line_of(int(np.argmax(bad)))
        raise DataError(f"{origin}:{first}: {int(bad.sum())} row(s) contain NaN or "
                        f"infinite values (first at line {first}); expected finite numbers")
    back = np.diff(t) < 0
    if back.any():
        first = line_of(int(np.argmax(back)) + 1)
        raise DataError(f"{origin}:{first}: {int(back.sum())} row(s) have timestamps that go back "
                        f"in time (first at line {first}); expected non-decreasing t in seconds")
