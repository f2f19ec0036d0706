"""Variable types: how each kind of unknown is stored in gtsam.Values, given a prior, and reported.

Tangent-space conventions are GTSAM's: Pose3 = [rotation (rad), translation (m)] in the body
frame, Pose2 = [x, y, theta], imu bias = [accelerometer (m/s^2), gyroscope (rad/s)].
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable

import gtsam
import numpy as np


@dataclass(frozen=True)
class VarType:
    """One kind of variable. `from_list`/`to_list` convert to/from plain YAML values."""

    name: str
    dim: int
    read: Callable[[gtsam.Values, int], Any]
    prior: Callable[[int, Any, Any], gtsam.NonlinearFactor]
    between: Callable[[int, int, Any, Any], gtsam.NonlinearFactor]
    from_list: Callable[[Any], Any]
    to_list: Callable[[Any], Any]
    zero: Callable[[], Any]

    def local(self, a: Any, b: Any) -> np.ndarray:
        """Tangent vector from a to b (b = a.retract(v)); used for errors against truth."""
        va, vb = gtsam.Values(), gtsam.Values()
        va.insert(0, a)
        vb.insert(0, b)
        return np.asarray(va.localCoordinates(vb).at(0), dtype=float)


def _pose3_from(v: Any) -> gtsam.Pose3:
    """[x, y, z, qx, qy, qz, qw] or {translation: [..], rotation_rpy|quaternion_xyzw: [..]}."""
    if isinstance(v, gtsam.Pose3):
        return v
    if isinstance(v, dict):
        t = np.asarray(v.get("translation", [0, 0, 0]), float)
        if "quaternion_xyzw" in v:
            qx, qy, qz, qw = v["quaternion_xyzw"]
            r = gtsam.Rot3.Quaternion(qw, qx, qy, qz)
        else:
            r = gtsam.Rot3.RzRyRx(*np.asarray(v.get("rotation_rpy", [0, 0, 0]), float))
        return gtsam.Pose3(r, t)
    a = np.asarray(v, float)
    if a.shape == (7,):
        return gtsam.Pose3(gtsam.Rot3.Quaternion(a[6], a[3], a[4], a[5]), a[:3])
    if a.shape == (4, 4):
        return gtsam.Pose3(a)
    raise ValueError("expected [x, y, z, qx, qy, qz, qw], a 4x4 matrix or {translation, rotation_rpy}")


def pose3_to_list(p: gtsam.Pose3) -> list[float]:
    q = p.rotation().toQuaternion()
    return [*map(float, p.translation()), float(q.x()), float(q.y()), float(q.z()), float(q.w())]


def _pose2_from(v: Any) -> gtsam.Pose2:
    if isinstance(v, gtsam.Pose2):
        return v
    a = np.asarray(v, float)
    if a.shape != (3,):
        raise ValueError("expected [x, y, theta]")
    return gtsam.Pose2(*a)


def _rot3_from(v: Any) -> gtsam.Rot3:
    if isinstance(v, gtsam.Rot3):
        return v
    a = np.asarray(v, float)
    if a.shape == (3,):
        return gtsam.Rot3.RzRyRx(*a)
    if a.shape == (4,):
        return gtsam.Rot3.Quaternion(a[3], a[0], a[1], a[2])
    raise ValueError("expected roll-pitch-yaw [r, p, y] or quaternion [qx, qy, qz, qw]")


def _vector_from(dim: int) -> Callable[[Any], np.ndarray]:
    def convert(v: Any) -> np.ndarray:
        a = np.atleast_1d(np.asarray(v, float))
        if a.shape != (dim,):
            raise ValueError(f"expected a list of {dim} numbers")
        return a
    return convert


def _scalar_from(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
        raise ValueError("expected a number")
    return float(v)


def _bias_from(v: Any) -> gtsam.imuBias.ConstantBias:
    if isinstance(v, gtsam.imuBias.ConstantBias):
        return v
    a = np.asarray(v, float)
    if a.shape != (6,):
        raise ValueError("expected [ax, ay, az, gx, gy, gz]")
    return gtsam.imuBias.ConstantBias(a[:3], a[3:])


POSE3 = VarType(
    "pose3", 6, lambda v, k: v.atPose3(k), gtsam.PriorFactorPose3, gtsam.BetweenFactorPose3,
    _pose3_from, pose3_to_list, gtsam.Pose3)
POSE2 = VarType(
    "pose2", 3, lambda v, k: v.atPose2(k), gtsam.PriorFactorPose2, gtsam.BetweenFactorPose2,
    _pose2_from, lambda p: [float(p.x()), float(p.y()), float(p.theta())], gtsam.Pose2)
POINT3 = VarType(
    "point3", 3, lambda v, k: v.atPoint3(k), gtsam.PriorFactorPoint3, gtsam.BetweenFactorPoint3,
    _vector_from(3), lambda p: [float(x) for x in p], lambda: np.zeros(3))
POINT2 = VarType(
    "point2", 2, lambda v, k: v.atPoint2(k), gtsam.PriorFactorPoint2, gtsam.BetweenFactorPoint2,
    _vector_from(2), lambda p: [float(x) for x in p], lambda: np.zeros(2))
ROT3 = VarType(
    "rot3", 3, lambda v, k: v.atRot3(k), gtsam.PriorFactorRot3, gtsam.BetweenFactorRot3,
    _rot3_from, lambda r: [float(x) for x in r.xyz()], gtsam.Rot3)
SCALAR = VarType(
    "scalar", 1, lambda v, k: v.atDouble(k), gtsam.PriorFactorDouble, gtsam.BetweenFactorDouble,
    _scalar_from, float, lambda: 0.0)
IMU_BIAS = VarType(
    "imu_bias", 6, lambda v, k: v.atConstantBias(k), gtsam.PriorFactorConstantBias,
    gtsam.BetweenFactorConstantBias, _bias_from, lambda b: [float(x) for x in b.vector()],
    gtsam.imuBias.ConstantBias)


def vector_type(dim: int) -> VarType:
    """An n-vector: joint angles, kinematic-parameter vectors, velocities (dim 3)."""
    return VarType(
        f"vector{dim}", dim, lambda v, k: v.atVector(k), gtsam.PriorFactorVector,
        gtsam.BetweenFactorVector, _vector_from(dim), lambda p: [float(x) for x in p],
        lambda: np.zeros(dim))


VELOCITY3 = replace(vector_type(3), name="velocity3")  # a 3-vector that reports itself as velocity3

_NAMED = {t.name: t for t in (POSE3, POSE2, POINT3, POINT2, ROT3, SCALAR, VELOCITY3, IMU_BIAS)}


def vartype_named(name: str) -> VarType:
    """'pose3', 'scalar', 'vector7', ... -> VarType; ValueError listing accepted names."""
    if name in _NAMED:
        return _NAMED[name]
    if name.startswith("vector") and name[6:].isdigit() and int(name[6:]) > 0:
        return vector_type(int(name[6:]))
    raise ValueError(f"unknown variable type {name!r}; accepted: {', '.join(sorted(_NAMED))}, vectorN")


VARTYPE_NAMES = sorted(_NAMED) + ["vectorN"]


# names of the components of a value as listed (to_list) and of its tangent axes (sigmas), per type
COMPONENTS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "pose3": (("x", "y", "z", "qx", "qy", "qz", "qw"), ("rx", "ry", "rz", "tx", "ty", "tz")),
    "pose2": (("x", "y", "theta"), ("tx", "ty", "rz")),
    "rot3": (("roll", "pitch", "yaw"), ("rx", "ry", "rz")),
    "point3": (("x", "y", "z"), ("x", "y", "z")),
    "point2": (("x", "y"), ("x", "y")),
    "velocity3": (("vx", "vy", "vz"), ("vx", "vy", "vz")),
    "imu_bias": (("ax", "ay", "az", "gx", "gy", "gz"), ("ax", "ay", "az", "gx", "gy", "gz")),
}


def component_names(vartype: VarType) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(value components, tangent axes) of a type: COMPONENTS, `value` for a scalar, c0..c{n-1} for a vector."""
    if vartype.name in COMPONENTS:
        return COMPONENTS[vartype.name]
    if vartype.dim == 1:
        return ("value",), ("value",)
    names = tuple(f"c{i}" for i in range(vartype.dim))
    return names, names
