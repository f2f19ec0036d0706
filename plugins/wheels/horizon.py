"""`wheels.long_horizon`: the driven wheels dead-reckoned over long windows, scored where a reference places the
robot (docs/models/wheels.md#long-horizon-calibration).

Checkpoints are states `spacing` m of travel apart (every state without it). Every checkpoint X_a anchors a window
through the later checkpoints X_c1..X_cn of its recording (up to `horizon` s; `anchors: recording_start`: only the
recording's first state anchors one): every horizon at once. A window's factor integrates the wheel samples
exactly at the current intrinsics theta = (r_L, r_R, A) (preintegration.dead_reckon) and compares, at every
checkpoint state, where dead reckoning from X_a puts the robot with where the state is:

    e_c = R_a^T (p_c - p_a) - q_c(theta)             (m; q_c: the dead-reckoned position in X_a's frame)
    e_c' = wrap(th_c - th_a - psi_c(theta))          (rad; with `heading_sigma`)

every checkpoint with the same sigma: the squared position errors of dead reckoning at checkpoints along the
path, the objective of Sousa et al.'s OptiOdom (2022), inside the graph, from states the reference holds.
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import FactorExample, FactorType, Spec, gaussian

from .factors import NAME, SIGMA, check_drive_entry, drive_stream_intervals, require_wheels
from .kinematics import driven_twist, increments, wheel_column
from .model import AXLE, RADIUS_LEFT, RADIUS_RIGHT, drive_of
from .preintegration import dead_reckon

INTRINSICS = (RADIUS_LEFT, RADIUS_RIGHT, AXLE)


def _rotation(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def long_horizon_residual(anchor, checkpoints: np.ndarray, theta, left: np.ndarray, right: np.ndarray,
                          at: np.ndarray, with_heading: bool, jacobians: bool = False):
    """Unwhitened residual (n * 2 or n * 3,) of one window: anchor (x, y, th), checkpoints (n, 3) poses, theta
    (r_L, r_R, A), the window's wheel angle increments left/right (S,), rad, and `at` (n,) the sample count
    after which each checkpoint falls. With `jacobians`: d/d anchor (rows, 3), d/d each checkpoint (rows, 3)
    and d/d each intrinsic (rows, 1), in Pose2's local coordinates (body-frame translation, then rotation)."""
    r = dead_reckon(left, right, theta)
    rot_a_t = _rotation(-anchor[2])
    v = (checkpoints[:, :2] - np.asarray(anchor[:2])) @ rot_a_t.T       # R_a^T (p_c - p_a), (n, 2)
    pos = v - r.position[at]
    rows = [pos]
    if with_heading:
        dh = checkpoints[:, 2] - anchor[2] - r.heading[at]
        rows.append(np.arctan2(np.sin(dh), np.cos(dh))[:, None])
    e = np.concatenate(rows, axis=1).ravel()
    if not jacobians:
        return e, None
    n, dim = len(at), 2 + with_heading
    d_anchor = np.zeros((n, dim, 3))
    d_anchor[:, :2, :2] = -np.eye(2)
    d_anchor[:, 0, 2], d_anchor[:, 1, 2] = v[:, 1], -v[:, 0]
    d_check = np.zeros((n, n, dim, 3))
    d_check[np.arange(n), np.arange(n), :2, :2] = _rotation(checkpoints[:, 2] - anchor[2])
    d_theta = np.zeros((n, dim, 3))
    d_theta[:, :2] = -r.d_position[at]
    if with_heading:
        d_anchor[:, 2, 2] = -1.0
        d_check[np.arange(n), np.arange(n), 2, 2] = 1.0
        d_theta[:, 2] = -r.d_heading[at]
    d_check = d_check.transpose(1, 0, 2, 3).reshape(n, n * dim, 3)
    d_theta = d_theta.reshape(n * dim, 3)
    return e, [d_anchor.reshape(n * dim, 3), *d_check, *(d_theta[:, i:i + 1] for i in range(3))]


def _xyt(p: gtsam.Pose2) -> tuple[float, float, float]:
    return p.x(), p.y(), p.theta()


def _window_error(n: int, left, right, at, with_heading: bool, this, values, H):
    keys = this.keys()
    anchor = _xyt(values.atPose2(keys[0]))
    checkpoints = np.array([_xyt(values.atPose2(k)) for k in keys[1:1 + n]])
    theta = [values.atDouble(k) for k in keys[1 + n:]]
    e, J = long_horizon_residual(anchor, checkpoints, theta, left, right, at, with_heading, H is not None)
    if H is not None:
        for i, block in enumerate(J):
            H[i] = block
    return e


def long_horizon_factor(keys: list[int], left, right, at, with_heading: bool, noise) -> gtsam.CustomFactor:
    """Keys: the anchor pose, the n checkpoint poses, r_L, r_R, A."""
    at = np.asarray(at, int)
    return gtsam.CustomFactor(noise, keys, partial(_window_error, len(at), np.asarray(left, float),
                                                   np.asarray(right, float), at, with_heading))


def checkpoints(travel: np.ndarray, spacing: float | None) -> np.ndarray:
    """Indices into `travel` (each usable state's distance travelled, m, non-decreasing) of the states kept: the
    first, then each state `spacing` m or more past the last kept one (every state without `spacing`), and the
    last."""
    if spacing is None:
        return np.arange(len(travel))
    kept = [0]
    for i, d in enumerate(travel.tolist()):
        if d - travel[kept[-1]] >= spacing:
            kept.append(i)
    if kept[-1] != len(travel) - 1:
        kept.append(len(travel) - 1)
    return np.array(kept)


def windows(state_t: np.ndarray, ks: np.ndarray, parts: list[tuple[float, float]], horizon: float | None,
            travel=None, spacing: float | None = None, every_anchor: bool = True) -> list[list[int]]:
    """Lists of state indices [anchor, checkpoint, ..]: within each recording part (t0, t1), the states of `ks`
    (sorted) kept by `checkpoints` (travel(times): the distance travelled between consecutive times, m); every
    kept state but the part's last (`every_anchor`; else the part's first only) anchors a window through the later
    ones, up to the first `horizon` s or more after it (absent: to the part's end)."""
    out = []
    for t0, t1 in parts:
        inside = ks[(state_t[ks] >= t0) & (state_t[ks] <= t1)]
        if spacing is not None and len(inside) > 1:
            inside = inside[checkpoints(np.concatenate([[0.0], np.cumsum(travel(state_t[inside]))]), spacing)]
        t = state_t[inside]
        ends = (np.full(len(inside), len(inside) - 1) if horizon is None else
                np.minimum(np.searchsorted(t, t + horizon), len(inside) - 1))
        out += [inside[i:end + 1].tolist() for i, end in enumerate(ends[:-1 if every_anchor else 1].tolist())]
    return out


class LongHorizon(FactorType):
    name = "wheels.long_horizon"
    summary = ("driven-wheel dead reckoning over long windows from an anchor state, its position error at every "
               "later state (OptiOdom's objective in the graph: wheel calibration for long paths; diff_drive)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": SIGMA, "heading_sigma": SIGMA,
                             "horizon": SIGMA, "spacing": SIGMA,
                             "anchors": {"enum": ["every_checkpoint", "recording_start"],
                                         "default": "every_checkpoint"}},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        require_wheels(spec, scope, drive_of(check_drive_entry(spec, scope)), ("left", "right"))

    def build(self, ctx, spec: Spec) -> None:
        """sigma: m, of the position dead reckoning reaches at each checkpoint; heading_sigma: rad, of its
        heading (absent: position only); horizon: s, the longest window (absent: each recording whole); spacing: m of
        travel (at the description's intrinsics) between checkpoints (absent: every state); anchors: every_checkpoint
        (windows from each checkpoint: every horizon at once) or recording_start (from each recording's start
        only: OptiOdom's objective as published)."""
        robot, drive, stream, states, ks = drive_stream_intervals(ctx, spec)
        if len(ks) == 0:
            return
        usable = np.union1d(ks - 1, ks)
        parts = [(a, b) for _, a, b in stream.parts] or [(float(stream.t[0]), float(stream.t[-1]))]
        with_heading = "heading_sigma" in spec.data
        sigmas = [spec["sigma"]] * 2 + ([spec["heading_sigma"]] if with_heading else [])
        left_angles, right_angles = (wheel_column(stream, drive, w) for w in ("left", "right"))

        def travel(times):
            return np.abs(driven_twist(stream, drive, times)[0])

        spans = windows(states.t, usable, parts, spec.get("horizon"), travel, spec.get("spacing"),
                        spec["anchors"] == "every_checkpoint")
        if len(spans) > 1:
            ctx.note(f"{spec.label}: {len(spans)} windows share their wheel samples; the intrinsics' sigmas "
                             "treat their checkpoints as independent (a weighting, not a noise model): judge the "
                             "calibration held out (fusionkit crossval, or dead reckoning on another run)")
        for window in spans:
            t = states.t[window]
            bounds = np.union1d(t, stream.t[(stream.t > t[0]) & (stream.t < t[-1])])
            at = np.searchsorted(bounds, t[1:])
            keys = ctx.state_keys(robot, window) + [ctx.parameter(robot, n, k=window[0]) for n in INTRINSICS]
            ctx.add(long_horizon_factor(keys, increments(stream.t, left_angles, bounds),
                                        increments(stream.t, right_angles, bounds), at, with_heading,
                                        ctx.noise(sigmas * len(at), spec)),
                    spec, float(t[-1]))

    @classmethod
    def example(cls, rng):
        """Forty samples of random wheel increments, four checkpoints where dead reckoning from the anchor puts them."""
        theta = np.array([rng.uniform(0.03, 0.06), rng.uniform(0.03, 0.06), rng.uniform(0.2, 0.4)])
        left, right = rng.uniform(-0.5, 2.0, 40), rng.uniform(-0.5, 2.0, 40)
        at = np.array([5, 17, 30, 40])
        anchor = gtsam.Pose2(*rng.normal(scale=[1.0, 1.0, 2.0]))
        r = dead_reckon(left, right, theta)
        values = gtsam.Values()
        values.insert(0, anchor)
        for i, j in enumerate(at):
            values.insert(1 + i, anchor.compose(gtsam.Pose2(*r.position[j], r.heading[j])))
        for i, v in enumerate(theta.tolist()):
            values.insert(5 + i, v)
        with_heading = bool(rng.uniform() < 0.5)
        factor = long_horizon_factor(list(range(8)), left, right, at, with_heading,
                                     gaussian([0.01] * (len(at) * (2 + with_heading))))
        return FactorExample(factor, values, perturbation=0.01)


FACTOR_TYPES = [LongHorizon]
