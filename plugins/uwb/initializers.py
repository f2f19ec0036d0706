"""`uwb.multilateration`: first poses and unknown anchors from the ranges alone.

1. Positions: at each state, the ranges of the surrounding `window` (s; default 0: the state's own
   epoch; round-robin ranging needs a window spanning one round) to the anchors whose positions are
   known (their current values: the description's nominal ones) give the tag
   position by Gauss-Newton least squares (vectorized over states), minus the lever arm. The
   heading comes from the direction of travel (`heading: travel`, the planar default) or stays
   (`keep`, the 3-D default). This is also the per-epoch multilateration baseline of
   experiments.py.
2. Unknown anchors (`unknown:` indices): from those positions and their ranges, the closed-form
   range-origin fit shared with the cable plugins (fusionkit.geometry.fit_range_origin): anchor
   position and its constant bias, which initializes the robot's bias parameter when given.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit import Initializer, Spec
from fusionkit.data.association import nearest
from fusionkit.geometry import fit_range_origin
from fusionkit.graph.variables import POINT2, POSE2

from .factors import _range_rows, lever_arm

NAME = {"type": "string"}
GN_ITERATIONS = 10
ROBUST_SCALE = 0.3  # m: ranges this far off count half (Cauchy weights: NLOS outliers hardly pull)
HEADING_BASELINE = 1.0  # s: planar headings from positions this far apart (not from noisy neighbours)


def multilaterate(t_states: np.ndarray, t_ranges: np.ndarray, anchor_index: np.ndarray, ranges: np.ndarray,
                  anchors: np.ndarray, window: float, height: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Robust least-squares tag positions (S, d) at the state times from the ranges within
    +-window/2 s, d = anchors' dimension (with `height`, a planar tag at that height among 3-D
    anchors: d = 2): Gauss-Newton, with Cauchy weights (scale ROBUST_SCALE) after the first half of
    the iterations. Returns (positions, usable) where usable marks states with ranges to at least
    d + 1 distinct anchors."""
    dim = anchors.shape[1] if height is None else 2
    S = len(t_states)
    lo = np.searchsorted(t_ranges, t_states - window / 2, side="left")
    hi = np.searchsorted(t_ranges, t_states + window / 2, side="right")
    width = int(max(1, (hi - lo).max()))
    idx = lo[:, None] + np.arange(width)[None]
    valid = idx < hi[:, None]
    idx = np.minimum(idx, len(t_ranges) - 1)
    a = anchors[anchor_index[idx]]               # (S, W, da)
    z = ranges[idx]
    distinct = np.array([len(set(anchor_index[i][v])) for i, v in zip(idx, valid)])
    usable = distinct >= dim + 1
    x = np.tile(anchors.mean(axis=0)[:dim], (S, 1)) + 0.1  # off the anchors' centroid
    for _ in range(GN_ITERATIONS):
        p = x if height is None else np.concatenate([x, np.full((S, 1), height)], axis=1)
        d = p[:, None, :] - a                    # (S, W, da)
        r = np.linalg.norm(d, axis=2)
        e = (r - z) * valid
        weight = valid / (1.0 + (e / ROBUST_SCALE) ** 2) if _ >= GN_ITERATIONS // 2 else valid.astype(float)
        J = (d / np.maximum(r, 1e-9)[..., None])[..., :dim] * np.sqrt(weight)[..., None]
        e = e * np.sqrt(weight)
        JtJ = np.einsum("swi,swj->sij", J, J) + 1e-9 * np.eye(dim)
        x = x - np.linalg.solve(JtJ, np.einsum("swi,sw->si", J, e)[..., None])[..., 0]
    return x, usable


class Multilateration(Initializer):
    name = "uwb.multilateration"
    summary = ("first poses by per-epoch multilateration to the known anchors, unknown anchors (and their "
               "constant bias) by the closed-form range-origin fit shared with the cable plugins")
    robot_fields = ("robot", "anchors")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "anchors": NAME, "anchor_parameter": NAME, "stream": NAME, "tag": NAME,
                             "bias": NAME, "anchor_column": NAME, "range_column": NAME,
                             "ids": {"type": "array", "items": {"type": "number"}, "minItems": 1},
                             "columns": {"type": "array", "items": NAME, "minItems": 1},
                             "unknown": {"type": "array", "items": {"type": "integer", "minimum": 0}},
                             "window": {"type": "number", "minimum": 0},
                             "heading": {"enum": ["travel", "keep"]}},
              "required": ["robot", "anchors", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot")

    def initialize(self, ctx, spec: Spec) -> None:
        robot, anchors_robot = spec["robot"], spec["anchors"]
        param = spec.get("anchor_parameter", "anchor")
        n = ctx.robot(anchors_robot).parameters[param].count
        planar_anchors = ctx.robot(anchors_robot).parameters[param].vartype is POINT2
        keys = [ctx.parameter(anchors_robot, param, i) for i in range(n)]
        anchors = np.array([np.asarray(ctx.initial.atPoint2(k) if planar_anchors else ctx.initial.atPoint3(k))
                            for k in keys])
        unknown = sorted(set(spec.get("unknown", [])))
        if any(i >= n for i in unknown):
            raise spec.error("unknown", f"anchor index out of range: there are anchors 0..{n - 1}")
        states = ctx.state_set(robot, spec)
        planar = states.family.vartype is POSE2
        b = lever_arm(ctx.robot(robot), spec.get("tag"))
        stream = ctx.stream(spec["stream"])
        rows = _range_rows(stream, spec, n)
        t_r = np.array([stream.t[r] for r, _, _ in rows])
        ai = np.array([i for _, i, _ in rows])
        z = np.array([v for _, _, v in rows])
        known = ~np.isin(ai, unknown)
        height = float(b[2]) if (planar and not planar_anchors) else None
        pos, usable = multilaterate(states.t, t_r[known], ai[known], z[known], anchors, spec.get("window", 0.0),
                                    height)
        if not usable.any():
            raise spec.error("stream", "no state has ranges to enough known anchors within the window; widen "
                             "`window` or give more anchors known positions")
        # states without enough ranges take the nearest usable one
        fill = nearest(states.t[usable], states.t, np.inf)
        pos = pos[usable][fill.state[np.argsort(fill.row)]] if not usable.all() else pos
        self._set_poses(ctx, robot, states, pos, b, planar, spec.get("heading", "travel" if planar else "keep"))
        for i in unknown:
            m = ai == i
            points = self._tag_points(ctx, robot, states, t_r[m], b, planar, planar_anchors)
            try:
                a, c, rms = fit_range_origin(points, z[m])
            except ValueError as exc:
                raise spec.error("unknown", f"anchor {i}: {exc}") from None
            ctx.set_initial(keys[i], a if not planar_anchors else a[:2])
            if "bias" in spec.data:
                ctx.set_initial(ctx.parameter(robot, spec["bias"], i, 0), c)
            ctx.notes.append(f"{spec.label}: anchor {i} initialized at ({', '.join(f'{x:.3f}' for x in a)}), bias "
                             f"{c:+.3f} m, fit rms {rms:.3f} m over {int(m.sum())} ranges")

    @staticmethod
    def _set_poses(ctx, robot, states, pos, b, planar, heading_mode):
        """Positions from the tag's, headings along the travel (positions HEADING_BASELINE apart)
        or, with `keep` (3-D default), the current orientations."""
        h = max(1, int(np.searchsorted(states.t - states.t[0], HEADING_BASELINE / 2)))
        ahead, behind = np.minimum(np.arange(len(pos)) + h, len(pos) - 1), np.maximum(np.arange(len(pos)) - h, 0)
        step = pos[ahead] - pos[behind]
        heading = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
        for k, (p, th) in enumerate(zip(pos, heading)):
            if planar:
                c, s = np.cos(th), np.sin(th)
                origin = p[:2] - np.array([[c, -s], [s, c]]) @ b[:2]
                ctx.set_initial(ctx.pose_key(robot, k), gtsam.Pose2(origin[0], origin[1], th))
            else:
                R = gtsam.Rot3.Yaw(th) if heading_mode == "travel" else ctx.initial.atPose3(ctx.pose_key(robot, k)).rotation()
                ctx.set_initial(ctx.pose_key(robot, k), gtsam.Pose3(R, p - R.matrix() @ b))

    @staticmethod
    def _tag_points(ctx, robot, states, t, b, planar, planar_anchors):
        """Tag positions at the range times (nearest state's current initial pose)."""
        ks = nearest(states.t, t, np.inf)
        order = np.argsort(ks.row)
        out = []
        for k in ks.state[order]:
            if planar:
                x = ctx.initial.atPose2(ctx.pose_key(robot, int(k)))
                p = np.asarray(x.transformFrom(b[:2]))
                out.append(p if planar_anchors else np.append(p, b[2]))
            else:
                out.append(np.asarray(ctx.initial.atPose3(ctx.pose_key(robot, int(k))).transformFrom(b)))
        return np.array(out)


INITIALIZERS = [Multilateration]
