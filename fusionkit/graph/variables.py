"""Variable types: how each kind of unknown is stored in gtsam.Values, given a prior, read and written as
arrays, retracted, interpolated in time and reported.

Every type is registered like any plugin component (hook `register_variable_types`; the built-ins below
come from this module as a default plugin) and found by name with `fusionkit.plugins.variable_type`;
vectorN (N > 0) is one parametric family. Tangent-space conventions are GTSAM's: Pose3 = [rotation (rad),
translation (m)] in the body frame, Pose2 = [x, y, theta], imu bias = [accelerometer (m/s^2), gyroscope
(rad/s)].
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Any, Callable

import gtsam
import numpy as np

from .. import lie, se2
from ..hookspecs import hookimpl


def _as_float_array(value: Any) -> np.ndarray:
    return np.asarray(value, dtype=float)


def _add(x: np.ndarray, d: np.ndarray) -> np.ndarray:
    """x + d for N values at once; a scalar's array form is (N,) and its step (N, 1)."""
    return x + (d[..., 0] if x.ndim == 1 else d)


@dataclass(frozen=True)
class VarType:
    """One kind of variable.

    `read(values, key)` gets it from a gtsam.Values; `prior(key, value, noise)` and `between(k1, k2, delta,
    noise)` are its GTSAM factors (`between` None: it cannot follow a random walk); `from_list`/`to_list`
    convert to/from plain YAML values and `zero()` is the identity. The rest have defaults that fit a vector:
    - `components`, `axes`, `axis_units`: names of `to_list`'s entries, of the tangent axes (sigmas, covariances)
      and each axis's unit (empty: `value` for one dimension, c0..c{n-1} for more; the parameter's own unit);
      `sigma_note`: what the sigmas' axes mean, printed beside them in the summary;
    - `to_array(value)`: its array form in vectorized residuals (graph/vectorized.py), `retract_array(x, d)`
      GTSAM's retract on N array forms at once (x (N, ...), d (N, dim));
    - `lie_group`: the GTSAM class whose Expmap/Logmap (and their derivatives) interpolate states in time
      (time_offset/interpolation.py); None: interpolated in the vector space, unless `interpolable` is False;
    - `read_table(values)`: every value of this type in `values` at once, (keys sorted, array forms in that
      order), for a faster read of many (None: one `read` each);
    - `summary`: one line for `fusionkit plugins`."""

    name: str
    dim: int
    read: Callable[[gtsam.Values, int], Any]
    prior: Callable[[int, Any, Any], gtsam.NonlinearFactor]
    between: Callable[[int, int, Any, Any], gtsam.NonlinearFactor] | None
    from_list: Callable[[Any], Any]
    to_list: Callable[[Any], Any]
    zero: Callable[[], Any]
    components: tuple[str, ...] = ()
    axes: tuple[str, ...] = ()
    axis_units: tuple[str, ...] = ()
    sigma_note: str = ""
    to_array: Callable[[Any], np.ndarray] = _as_float_array
    retract_array: Callable[[np.ndarray, np.ndarray], np.ndarray] = _add
    lie_group: type | None = None
    interpolable: bool = True
    read_table: Callable[[gtsam.Values], tuple[np.ndarray, np.ndarray]] | None = None
    summary: str = ""

    def __post_init__(self) -> None:
        for field_name in ("components", "axes", "axis_units"):
            names = getattr(self, field_name)
            if names and len(names) != (len(self.to_list(self.zero())) if field_name == "components" else self.dim):
                raise ValueError(f"variable type {self.name}: {field_name} {names} do not match its size")

    def local(self, a: Any, b: Any) -> np.ndarray:
        """Tangent vector from a to b (b = a.retract(v)); used for errors against truth."""
        va, vb = gtsam.Values(), gtsam.Values()
        va.insert(0, a)
        vb.insert(0, b)
        return np.asarray(va.localCoordinates(vb).at(0), dtype=float)

    def names(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """(value components, tangent axes): as declared, `value` for one dimension, c0..c{n-1} for more."""
        if self.dim == 1:
            default = ("value",)
        else:
            default = tuple(f"c{i}" for i in range(self.dim))
        return self.components or default, self.axes or default

    def unit(self, axis: int, declared: str = "") -> str:
        """The unit of tangent axis `axis`: the type's own (poses, rotations, biases), else `declared`."""
        return self.axis_units[axis] if self.axis_units else declared


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


def _pose_table(extract: Callable, select: Callable) -> Callable[[gtsam.Values], tuple[np.ndarray, np.ndarray]]:
    """Every pose of one type in a Values at once (one C++ call): (keys sorted, rows in that order)."""
    def table(values: gtsam.Values) -> tuple[np.ndarray, np.ndarray]:
        return np.asarray(select(values).keys(), dtype=np.int64), extract(values)
    return table


def _pose3_table(values: gtsam.Values) -> tuple[np.ndarray, np.ndarray]:
    keys, rows = _pose_table(gtsam.utilities.extractPose3, gtsam.utilities.allPose3s)(values)
    out = np.zeros((len(keys), 4, 4))
    out[:, :3, :3] = rows[:, :9].reshape(-1, 3, 3)
    out[:, :3, 3] = rows[:, 9:]
    out[:, 3, 3] = 1.0
    return keys, out


def _rot3_retract(x: np.ndarray, d: np.ndarray) -> np.ndarray:
    return x @ lie.exp(np.concatenate([d, np.zeros_like(d)], axis=-1))[..., :3, :3]


_ROTATION_AXES = ("rx", "ry", "rz")
POSE3 = VarType(
    "pose3", 6, lambda v, k: v.atPose3(k), gtsam.PriorFactorPose3, gtsam.BetweenFactorPose3,
    _pose3_from, pose3_to_list, gtsam.Pose3,
    components=("x", "y", "z", "qx", "qy", "qz", "qw"), axes=_ROTATION_AXES + ("tx", "ty", "tz"),
    axis_units=("rad",) * 3 + ("m",) * 3, sigma_note="rad about, m along the body axes", to_array=lambda p: p.matrix(), retract_array=lambda x, d: x @ lie.exp(d),
    lie_group=gtsam.Pose3, read_table=_pose3_table,
    summary="3-D pose (SE(3)); listed [x, y, z, qx, qy, qz, qw]; array form 4x4; tangent [rotation, translation]")
POSE2 = VarType(
    "pose2", 3, lambda v, k: v.atPose2(k), gtsam.PriorFactorPose2, gtsam.BetweenFactorPose2,
    _pose2_from, lambda p: [float(p.x()), float(p.y()), float(p.theta())], gtsam.Pose2,
    components=("x", "y", "theta"), axes=("tx", "ty", "rz"), axis_units=("m", "m", "rad"),
    sigma_note="m along, rad about the body axes",    to_array=lambda p: np.array([p.x(), p.y(), p.theta()]), retract_array=lambda x, d: se2.compose(x, se2.exp(d)),
    lie_group=gtsam.Pose2, read_table=_pose_table(gtsam.utilities.extractPose2, gtsam.utilities.allPose2s),
    summary="planar pose (SE(2)) [x, y, theta]; tangent [x, y, theta] in the body frame")
POINT3 = VarType(
    "point3", 3, lambda v, k: v.atPoint3(k), gtsam.PriorFactorPoint3, gtsam.BetweenFactorPoint3,
    _vector_from(3), lambda p: [float(x) for x in p], lambda: np.zeros(3), components=("x", "y", "z"),
    axes=("x", "y", "z"), summary="3-D point [x, y, z]")
POINT2 = VarType(
    "point2", 2, lambda v, k: v.atPoint2(k), gtsam.PriorFactorPoint2, gtsam.BetweenFactorPoint2,
    _vector_from(2), lambda p: [float(x) for x in p], lambda: np.zeros(2), components=("x", "y"), axes=("x", "y"),
    summary="planar point [x, y]")
ROT3 = VarType(
    "rot3", 3, lambda v, k: v.atRot3(k), gtsam.PriorFactorRot3, gtsam.BetweenFactorRot3,
    _rot3_from, lambda r: [float(x) for x in r.xyz()], gtsam.Rot3, components=("roll", "pitch", "yaw"),
    axes=_ROTATION_AXES, axis_units=("rad",) * 3, sigma_note="rad about the body axes", to_array=lambda r: r.matrix(), retract_array=_rot3_retract,
    lie_group=gtsam.Rot3, summary="3-D rotation (SO(3)); listed roll-pitch-yaw, given as that or [qx, qy, qz, qw]")
SCALAR = VarType(
    "scalar", 1, lambda v, k: v.atDouble(k), gtsam.PriorFactorDouble, gtsam.BetweenFactorDouble,
    _scalar_from, float, lambda: 0.0, summary="one number")
_BIAS_AXES = ("ax", "ay", "az", "gx", "gy", "gz")
IMU_BIAS = VarType(
    "imu_bias", 6, lambda v, k: v.atConstantBias(k), gtsam.PriorFactorConstantBias,
    gtsam.BetweenFactorConstantBias, _bias_from, lambda b: [float(x) for x in b.vector()],
    gtsam.imuBias.ConstantBias, components=_BIAS_AXES, axes=_BIAS_AXES, axis_units=("m/s^2",) * 3 + ("rad/s",) * 3,
    to_array=lambda b: np.asarray(b.vector(), dtype=float), interpolable=False,
    summary="IMU bias [accelerometer (m/s^2), gyroscope (rad/s)]")


def vector_type(dim: int) -> VarType:
    """An n-vector: joint angles, kinematic-parameter vectors, velocities (dim 3)."""
    return VarType(
        f"vector{dim}", dim, lambda v, k: v.atVector(k), gtsam.PriorFactorVector,
        gtsam.BetweenFactorVector, _vector_from(dim), lambda p: [float(x) for x in p],
        lambda: np.zeros(dim), summary="n numbers (vectorN, N > 0)")


# a 3-vector that reports itself as velocity3
VELOCITY3 = replace(vector_type(3), name="velocity3", components=("vx", "vy", "vz"), axes=("vx", "vy", "vz"),
                    summary="velocity [vx, vy, vz]")
BUILTIN = (POSE3, POSE2, POINT3, POINT2, ROT3, SCALAR, VELOCITY3, IMU_BIAS)
VECTOR_NAME = re.compile(r"vector([0-9]+)")


def vector_named(name: str) -> VarType | None:
    """vectorN (N > 0) -> its type; None for any other name."""
    match = VECTOR_NAME.fullmatch(name)
    return vector_type(int(match.group(1))) if match and int(match.group(1)) > 0 else None


@hookimpl
def register_variable_types() -> list[VarType]:
    return list(BUILTIN)
