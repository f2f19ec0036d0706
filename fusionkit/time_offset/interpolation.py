"""The state at a sample's time, and the shifted factor that evaluates a factor there.

A sample stamped t (s, its sensor's clock) was taken at tau = t + delta + rho (t - t_ref) on the states'
clock (delta: the time offset, s; rho: an optional clock-rate error, s/s; t_ref: the robot's first state).
The state at tau lies on a cubic Hermite (Catmull-Rom) curve, in the tangent space at x_k, through the
states x_{k-1}, x_k, x_{k+1}, x_{k+2} around the pair x_k, x_{k+1} that brackets tau:

    x(s) = x_k Exp(xi(s)),  s = (tau - t_k) / (t_{k+1} - t_k),  xi_i = Log(x_k^-1 x_i)
    xi(s) = h01(s) xi_{k+1} + h10(s) m_k + h11(s) m_{k+1}
    m_k = (xi_{k+1} - xi_{k-1}) (t_{k+1} - t_k) / (t_{k+1} - t_{k-1}),
    m_{k+1} = xi_{k+2} (t_{k+1} - t_k) / (t_{k+2} - t_k)

(h.. the cubic Hermite basis; a missing neighbour at the window's or the trajectory's end makes that
tangent the chord xi_{k+1}; with neither, x(s) = x_k Exp(s Log(x_k^-1 x_{k+1})), the geodesic). Pose3,
pose2 and rot3 states use the group's Exp/Log; vectors and scalars the same formulas with x_k + xi.
Pose3 states whose robot also has per-state world-frame velocities (a velocity3 variable per state, as
imu.preintegrated declares them) use them: the rotation follows the same curve through the window's
rotations, the position the cubic Hermite through p_k, p_{k+1} with the tangents (t_{k+1} - t_k) v_k and
(t_{k+1} - t_k) v_{k+1} of the pair around the sample at build time (`_pose_velocity_curve`; two velocities
per sample: four would tie each sample to eight state variables, and the marginals of such a graph cost
many times the solve).
The curve passes through the states and its velocity is continuous across them (to second order on a
group): a piecewise-geodesic curve has a kink at every state, and with sample stamps commensurate with
the state times all samples cross a kink at the same offset, which pulls the offset's estimate toward it.

`shifted_factor` wraps any noise-model factor built on a placeholder key for the state at the sample's
time: it evaluates the factor with that state on the curve and carries its Jacobian by the chain rule to
the window's states, delta and rho (exact), under the factor's own noise model and robust kernel. The
window holds up to four states around the build-time pair and one more on each side; the factor picks the
pair that brackets tau at the current delta, so the offset may move a sample across a state boundary;
beyond the window's ends it extrapolates.
"""

from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass
from functools import partial
from typing import Callable

import gtsam
import numpy as np

from ..graph.variables import ROT3, VarType


@dataclass(frozen=True)
class _Lie:
    """Group operations with right-perturbation Jacobians, for one GTSAM Lie type."""

    cls: type
    read: Callable[[gtsam.Values, int], object]  # the type's read from a Values

    def log_between(self, a, b):
        """(xi = Log(a^-1 b), dxi/da, dxi/db)."""
        d = a.between(b)
        xi = self.cls.Logmap(d)
        inv = self.cls.LogmapDerivative(xi)
        return xi, -inv @ d.inverse().AdjointMap(), inv

    def exp_from(self, a, xi):
        """(y = a Exp(xi), dy/da, dy/dxi)."""
        E = self.cls.Expmap(xi)
        return a.compose(E), E.inverse().AdjointMap(), self.cls.ExpmapDerivative(xi)

    def error(self, y, m):
        """(e = Log(y^-1 m), de/dy, de/dm)."""
        r = y.between(m)
        e = self.cls.Logmap(r)
        inv = self.cls.LogmapDerivative(e)
        return e, -inv @ r.inverse().AdjointMap(), inv


@dataclass(frozen=True)
class _Linear:
    """Vectors, points, scalars and any type without a lie_group: the same operations on its array form."""

    read: Callable[[gtsam.Values, int], object]
    dim: int
    to_array: Callable[[object], np.ndarray]  # a Values entry -> its array form (VarType.to_array)
    entry: Callable[[np.ndarray], object]     # an array (dim,) -> the Values entry of the type

    def log_between(self, a, b):
        eye = np.eye(self.dim)
        return np.atleast_1d(self.to_array(b)) - np.atleast_1d(self.to_array(a)), -eye, eye

    def exp_from(self, a, xi):
        eye = np.eye(self.dim)
        return np.atleast_1d(self.to_array(a)) + xi, eye, eye

    def error(self, y, m):
        eye = np.eye(self.dim)
        return np.atleast_1d(self.to_array(m)) - y, -eye, eye


def operations(vartype: VarType):
    """The interpolation's operations for a state type (VarType.lie_group: on the group; else in the vector
    space); ValueError for a type declared not interpolable (imu_bias)."""
    if not vartype.interpolable:
        raise ValueError(f"{vartype.name} states cannot be interpolated in time")
    if vartype.lie_group is not None:
        return _Lie(vartype.lie_group, vartype.read)
    scalar = isinstance(vartype.zero(), float)  # the Values holds a float, not a 1-vector
    return _Linear(vartype.read, vartype.dim, vartype.to_array,
                   (lambda y: vartype.from_list(float(y[0]))) if scalar else vartype.from_list)


def interpolable(vartype: VarType) -> bool:
    try:
        operations(vartype)
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class Timing:
    """Where one sample lies in time: its stamp, the clock-rate reference and the window of state times."""

    stamp: float
    t_ref: float
    window_t: np.ndarray  # (w,) times of the window's states, increasing, w >= 2

    def __post_init__(self) -> None:
        object.__setattr__(self, "_t", tuple(float(x) for x in self.window_t))  # plain floats: fast to bisect

    def tau(self, delta: float, rho: float = 0.0) -> float:
        """The sample's time on the states' clock."""
        return self.stamp + delta + rho * (self.stamp - self.t_ref)

    def pair(self, tau: float) -> tuple[int, float, float]:
        """(j, s, interval): the window pair j, j+1 used at tau, the fraction s, t_{j+1} - t_j."""
        w = self._t
        j = min(max(bisect_right(w, tau) - 1, 0), len(w) - 2)
        interval = w[j + 1] - w[j]
        return j, (tau - w[j]) / interval, interval

    def coefficients(self, j: int, s: float) -> dict[int, tuple[float, float]]:
        """{window index i: (c_i(s), dc_i/ds)} with xi(s) = sum c_i xi_i (xi_j = 0: not listed)."""
        w = self._t
        h = w[j + 1] - w[j]
        h10, h01, h11 = s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
        d10, d01, d11 = 3 * s ** 2 - 4 * s + 1, -6 * s ** 2 + 6 * s, 3 * s ** 2 - 2 * s
        out = {j + 1: [h01, d01]}
        if j > 0:  # m_j = (xi_{j+1} - xi_{j-1}) h / (t_{j+1} - t_{j-1})
            g = h / (w[j + 1] - w[j - 1])
            out[j + 1] = [out[j + 1][0] + g * h10, out[j + 1][1] + g * d10]
            out[j - 1] = [-g * h10, -g * d10]
        else:  # m_j = xi_{j+1}
            out[j + 1] = [out[j + 1][0] + h10, out[j + 1][1] + d10]
        if j + 2 < len(w):  # m_{j+1} = xi_{j+2} h / (t_{j+2} - t_j)
            g = h / (w[j + 2] - w[j])
            out[j + 2] = [g * h11, g * d11]
        else:  # m_{j+1} = xi_{j+1}
            out[j + 1] = [out[j + 1][0] + h11, out[j + 1][1] + d11]
        return {i: (c, dc) for i, (c, dc) in out.items()}


def _curve(ops, timing: Timing, states: list, tau: float):
    """(x(tau), j, dx/dx_j, {i: dx/dx_i}, dx/ds, interval, {}) of the curve through the window's states (the
    last: Jacobians with respect to velocities, which this curve does not use)."""
    j, s, interval = timing.pair(tau)
    anchor = states[j]
    omega = d_ds = dxi_da = 0.0
    dxi_di = {}
    for i, (c, dc) in timing.coefficients(j, s).items():
        xi, d_anchor, d_state = ops.log_between(anchor, states[i])
        omega = omega + c * xi
        d_ds = d_ds + dc * xi
        dxi_da = dxi_da + c * d_anchor
        dxi_di[i] = c * d_state
    y, dy_da, dy_domega = ops.exp_from(anchor, np.asarray(omega, float))
    return (y, j, dy_da + dy_domega @ dxi_da, {i: dy_domega @ d for i, d in dxi_di.items()},
            dy_domega @ np.asarray(d_ds, float), interval, {})


def _pose_velocity_curve(timing: Timing, poses: list, velocities: list, pair: int, tau: float):
    """(x(tau), j, dx/dx_j, {i: dx/dx_i}, dx/ds, interval, {0, 1: dx/dv}) for Pose3 states with world-frame
    velocities (m/s) `velocities` of the window's states `pair`, `pair` + 1: the rotation on the curve through
    the window's rotations (pair j, fraction s, interval h), the position on the cubic Hermite
    p(u) = h00 p_a + h01 p_b + g (h10 v_a + h11 v_b) through the states a = pair, b = pair + 1
    (g = t_b - t_a, u = (tau - t_a) / g, outside [0, 1] when tau left that pair). Jacobians in Pose3's
    right tangent (rotation, translation): a pose's rotation moves only the rotation, its translation
    (R_i dt_i in the world) only the position, seen in the curve point's frame as R^T; dx/ds = h dx/dtau."""
    R, j, dR_da, dR_di, dR_ds, h, _ = _curve(operations(ROT3), timing, [x.rotation() for x in poses], tau)
    a, b = pair, pair + 1
    g = timing.window_t[b] - timing.window_t[a]
    u = (tau - timing.window_t[a]) / g
    h00, h10, h01, h11 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u, -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2
    d00, d10, d01, d11 = 6 * u ** 2 - 6 * u, 3 * u ** 2 - 4 * u + 1, -6 * u ** 2 + 6 * u, 3 * u ** 2 - 2 * u
    pa, pb = poses[a].translation(), poses[b].translation()
    va, vb = np.asarray(velocities[0], float), np.asarray(velocities[1], float)
    p = h00 * pa + h01 * pb + g * (h10 * va + h11 * vb)
    dp_dtau = (d00 * pa + d01 * pb) / g + d10 * va + d11 * vb
    Rt = R.matrix().T
    zero = np.zeros((3, 6))
    dx_di = {i: np.vstack([np.hstack([d, np.zeros((3, 3))]), zero]) for i, d in dR_di.items()}
    dx_dj = np.vstack([np.hstack([dR_da, np.zeros((3, 3))]), zero])
    for i, c in ((a, h00), (b, h01)):
        translation = np.vstack([zero, np.hstack([np.zeros((3, 3)), c * Rt @ poses[i].rotation().matrix()])])
        if i == j:
            dx_dj = dx_dj + translation
        else:
            dx_di[i] = dx_di.get(i, 0.0) + translation
    dx_dv = {0: np.vstack([np.zeros((3, 3)), g * h10 * Rt]), 1: np.vstack([np.zeros((3, 3)), g * h11 * Rt])}
    return gtsam.Pose3(R, p), j, dx_dj, dx_di, np.r_[dR_ds, h * Rt @ dp_dtau], h, dx_dv


def interpolate(vartype: VarType, window_t: np.ndarray, states: list, tau: float, velocities: list | None = None,
                pair: int = 0):
    """The state at time tau on the curve through `states` at `window_t` (as the factor evaluates it; Pose3
    states with the world-frame `velocities` (m/s) of states `pair`, `pair` + 1 on the position's Hermite
    curve between those two)."""
    ops = operations(vartype)
    timing = Timing(tau, 0.0, np.asarray(window_t, float))
    if velocities is not None:
        return _pose_velocity_curve(timing, states, velocities, pair, tau)[0]
    y = _curve(ops, timing, states, tau)[0]
    return _value(ops, y)


def _value(ops, y):
    """The curve's point as the Values entry of its type (a float for scalars)."""
    return ops.entry(y) if isinstance(ops, _Linear) else y


@dataclass
class Shift:
    """How a factor's measurement-time key is evaluated: the curve through the states `window` (times in
    `timing`; Pose3 states: with `velocities`, the keys of the world-frame velocities of the window's states
    `pair`, `pair` + 1, the pair around the sample at build time) at tau(delta, rho), delta and rho the
    variables `offset` and `rate` (None: no clock-rate error). One Shift serves every factor of a sample:
    the curve of the latest values is kept (`_last`)."""

    key: int
    vartype: VarType
    timing: Timing
    window: tuple[int, ...]
    offset: int
    rate: int | None = None
    velocities: tuple[int, int] | None = None
    pair: int = 0
    _last: tuple | None = None  # (window states and velocities, delta, rho, curve)

    def curve(self, ops, values: gtsam.Values):
        """(x(tau), j, dx/dx_j, {i: dx/dx_i}, dx/ds, interval, {i: dx/dv_i}) at the values' states,
        velocities, delta and rho."""
        states = [ops.read(values, k) for k in self.window]
        speeds = [values.atVector(k) for k in self.velocities] if self.velocities else []
        delta = values.atDouble(self.offset)
        rho = 0.0 if self.rate is None else values.atDouble(self.rate)
        last = self._last
        if last is not None and last[1] == delta and last[2] == rho and all(
                _same(a, b) for a, b in zip(last[0], states + speeds)):
            return last[3]
        tau = self.timing.tau(delta, rho)
        out = (_pose_velocity_curve(self.timing, states, speeds, self.pair, tau) if self.velocities
               else _curve(ops, self.timing, states, tau))
        self._last = (states + speeds, delta, rho, out)
        return out


def _same(a, b) -> bool:
    return bool(np.array_equal(a, b)) if isinstance(a, (np.ndarray, float)) else a.equals(b, 0.0)


@dataclass(frozen=True)
class _Plan:
    inner: gtsam.NonlinearFactor
    inner_keys: tuple[int, ...]
    dims: tuple[int, ...]  # tangent dimension of each inner key
    plain: tuple[tuple[int, int], ...]  # (position in inner keys, position in the shifted factor's keys)
    shifts: tuple[tuple[int, Shift, object], ...]  # (position in inner keys, shift, operations)
    column: dict  # key of the shifted factor -> its position
    key_dims: tuple[int, ...]


def _shifted_error(plan: _Plan, this, values: gtsam.Values, H):
    """The inner factor's error with each shifted key at its curve's point. The points are inserted into
    `values` for the inner factor to read, and erased before returning (GTSAM hands a Python factor the
    caller's Values; a copy of the inner factor's other variables would cost more than the factor)."""
    curves = [sh.curve(ops, values) for _, sh, ops in plan.shifts]
    try:
        for (_, sh, ops), curve in zip(plan.shifts, curves):
            values.insert(sh.key, _value(ops, curve[0]))
        if H is None:
            return plan.inner.unwhitenedError(values)
        m = plan.inner.dim()
        inner_H = gtsam.JacobianVector([np.zeros((m, d)) for d in plan.dims])
        e = plan.inner.unwhitenedError(values, inner_H)
    finally:
        for _, sh, _ in plan.shifts:
            if values.exists(sh.key):
                values.erase(sh.key)
    blocks = [np.zeros((m, d)) for d in plan.key_dims]
    for pos, col in plan.plain:
        blocks[col] += inner_H[pos]
    for (pos, sh, _), (_, j, da, di, dy_ds, interval, dv) in zip(plan.shifts, curves):
        B = np.asarray(inner_H[pos])
        blocks[plan.column[sh.window[j]]] += B @ da
        for i, d in di.items():
            blocks[plan.column[sh.window[i]]] += B @ d
        for i, d in dv.items():
            blocks[plan.column[sh.velocities[i]]] += B @ d
        dtau = (B @ dy_ds).reshape(m, 1) / interval
        blocks[plan.column[sh.offset]] += dtau
        if sh.rate is not None:
            blocks[plan.column[sh.rate]] += dtau * (sh.timing.stamp - sh.timing.t_ref)
    for i, block in enumerate(blocks):
        H[i] = block
    return e


def shifted_factor(inner: gtsam.NonlinearFactor, shifts: list[Shift],
                   vartype_of: Callable[[int], VarType]) -> gtsam.CustomFactor:
    """`inner` (any noise-model factor, its noise model and robust kernel kept) with each shift's key replaced
    by the curve through the shift's window at the sample's time: keys = inner's other keys, then each
    shift's window states, their velocities, offset and rate (each key once). `vartype_of(key)`: the type of a variable."""
    inner_keys = tuple(inner.keys())
    by_key = {sh.key: sh for sh in shifts}
    if set(by_key) - set(inner_keys):
        raise ValueError("a shift names a key the factor does not have")
    keys = list(dict.fromkeys([k for k in inner_keys if k not in by_key]
                              + [k for sh in shifts for k in (*sh.window, *(sh.velocities or ()), sh.offset, sh.rate)
                                 if k is not None]))
    column = {k: i for i, k in enumerate(keys)}
    plan = _Plan(inner, inner_keys,
                 tuple(by_key[k].vartype.dim if k in by_key else vartype_of(k).dim for k in inner_keys),
                 tuple((pos, column[k]) for pos, k in enumerate(inner_keys) if k not in by_key),
                 tuple((pos, by_key[k], operations(by_key[k].vartype)) for pos, k in enumerate(inner_keys)
                       if k in by_key),
                 column, tuple(vartype_of(k).dim for k in keys))
    return gtsam.CustomFactor(inner.noiseModel(), keys, partial(_shifted_error, plan))
