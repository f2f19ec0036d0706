"""`uwb.multilateration`: first poses and unknown anchors from the ranges alone.

1. Positions: at each state, the ranges of the surrounding `window` (s; `auto`, the default: the state's
   own epoch when epochs reach enough anchors, else the span of one round of round-robin ranging,
   round_window) to the anchors whose positions are
   known (their current values: the description's nominal ones) give the tag
   position by Gauss-Newton least squares (vectorized over states), minus the lever arm. The
   heading comes from the direction of travel (`heading: travel`, the planar default) or stays
   (`keep`, the 3-D default). This is also the per-epoch multilateration baseline of the
   repository's research/uwb_experiments.py.
2. Unknown anchors (`unknown:` indices): from those positions and their ranges, the closed-form
   range-origin fit shared with the cable plugins (fusionkit.geometry.fit_range_origin): anchor
   position and its constant bias, which initializes the robot's bias parameter when given.
3. No anchor known (`unknown` lists them all; planar robot, point2 anchors): the anchors are
   placed from the line-of-sight ranges alone (survey.place_anchors) and step 1 runs on them; of
   the placement and its mirror image, the one the robot's own factors fit better after a short
   solve is kept (wheel odometry knows which way the robot turns). Without anchor priors it is
   in the anchor frame (anchor 0 at the origin, anchor 1 on +x), held there by gauge priors; with
   priors it is moved rigidly onto the description's values, whose priors fix the frame. Biases
   keep their description values.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from fusionkit.api import Initializer, NAME_SCHEMA as NAME, POINT2, POSE2, Spec, fit_range_origin

from .alignment import PIECE_S, align_pieces, odometry_path
from .factors import ANCHOR_PARAMETER, RANGE_COLUMN, _range_rows, lever_arm
from .survey import anchor_frame, gauge_factors, line_of_sight, place_anchors, range_matrix, rigid_fit

GN_ITERATIONS = 10
ROBUST_SCALE = 0.3  # m: ranges this far off count half (Cauchy weights: NLOS outliers hardly pull)
HEADING_BASELINE = 1.0  # s: planar headings from positions this far apart (not from noisy neighbours)
GAUGE_SIGMA = 1e-6  # m, rad: the gauge priors of the anchor frame (any value leaves the solution's shape alone)
MIRROR_MARGIN = 1.0  # the mirror image is told apart when the solved errors (-log likelihood) differ by more
MIRROR_ITERATIONS = 100  # Levenberg-Marquardt iterations that judge a placement and its mirror image (or a start)
SMEAR = 0.25  # m: a tag that moves more within the multilateration window is not placed epoch by epoch


@dataclass
class _Ranges:
    """Every range of the stream: time (s), anchor index, range (m)."""

    t: np.ndarray
    anchor: np.ndarray
    z: np.ndarray

    def subset(self, mask: np.ndarray) -> "_Ranges":
        return _Ranges(self.t[mask], self.anchor[mask], self.z[mask])


def nearest_index(t_sorted: np.ndarray, t: np.ndarray) -> np.ndarray:
    """For each time in t, the index of the nearest time in t_sorted (many may share one)."""
    if len(t_sorted) == 1:
        return np.zeros(len(t), int)
    i = np.clip(np.searchsorted(t_sorted, t), 1, len(t_sorted) - 1)
    return np.where(np.abs(t - t_sorted[i - 1]) <= np.abs(t_sorted[i] - t), i - 1, i)


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


def smear(path: np.ndarray, t: np.ndarray, window: float) -> float:
    """How far (m) the robot typically travels within `window` s: its median speed along the dead-reckoned path."""
    speed = np.linalg.norm(np.diff(path[:, :2], axis=0), axis=1) / np.maximum(np.diff(t), 1e-9)
    return float(np.median(speed) * window) if len(speed) else 0.0


def round_window(t: np.ndarray, anchor: np.ndarray, need: int) -> float:
    """The window (s) a state needs to see `need` distinct anchors among ranges (t non-decreasing): 0 when
    the median epoch (stamp) reaches that many; else the median time over which `need` distinct anchors
    answer in turn (round-robin ranging), plus one step between epochs. 0 when they never do."""
    stamps, first = np.unique(t, return_index=True)
    ends = np.append(first[1:], len(t))
    if np.median([len(set(anchor[a:b].tolist())) for a, b in zip(first, ends)]) >= need:
        return 0.0
    spans = []
    for i in range(0, len(t), max(1, len(t) // 500)):
        seen, j = set(), i
        while j < len(t) and len(seen) < need:
            seen.add(int(anchor[j]))
            j += 1
        if len(seen) == need:
            spans.append(t[j - 1] - t[i])
    if not spans:
        return 0.0
    return float(np.median(spans) + (np.median(np.diff(stamps)) if len(stamps) > 1 else 0.0))


class Multilateration(Initializer):
    name = "uwb.multilateration"
    accepts_repeated_stamps = ("stream",)  # ranges are grouped by time window (round-robin logs stamp several alike)
    summary = ("first poses by per-epoch multilateration to the known anchors, unknown anchors (and their "
               "constant bias) by the closed-form range-origin fit shared with the cable plugins; with no anchor "
               "surveyed, anchors placed from the ranges alone, in the anchor frame")
    robot_fields = ("robot", "anchors")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "anchors": NAME, "anchor_parameter": ANCHOR_PARAMETER, "stream": NAME,
                             "tag": NAME, "bias": NAME, "anchor_column": NAME, "range_column": RANGE_COLUMN,
                             "ids": {"type": "array", "items": {"type": "number"}, "minItems": 1},
                             "columns": {"type": "array", "items": NAME, "minItems": 1},
                             "unknown": {"type": "array", "items": {"type": "integer", "minimum": 0}, "default": []},
                             "window": {"oneOf": [{"type": "number", "minimum": 0}, {"const": "auto"}],
                                        "default": "auto"},
                             "heading": {"enum": ["travel", "keep"]}},  # default: travel if planar, else keep
              "required": ["robot", "anchors", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot")
        param = spec["anchor_parameter"]
        anchors = scope.robots[spec["anchors"]].parameters.get(param)
        if anchors is None:
            raise spec.error("anchors", f"robot {spec['anchors']!r} has no parameter {param!r} (the anchor points)")
        unknown = set(spec["unknown"])
        if any(i >= anchors.count for i in unknown):
            raise spec.error("unknown", f"anchor index out of range: there are anchors 0..{anchors.count - 1}")
        if len(unknown) == anchors.count and (anchors.vartype is not POINT2
                                              or (scope.states.get(spec["robot"]) or {}).get("type") != "pose2"):
            raise spec.error("unknown", "every anchor is unknown: placing them from the ranges alone needs a "
                             "planar robot (states type pose2) and point2 anchors; otherwise leave enough surveyed "
                             "anchors out of `unknown` to multilaterate the robot from (3 in a plane, 4 in 3-D)")

    def initialize(self, ctx, spec: Spec) -> None:
        robot, anchors_robot = spec["robot"], spec["anchors"]
        param = spec["anchor_parameter"]
        n = ctx.robot(anchors_robot).parameters[param].count
        planar_anchors = ctx.robot(anchors_robot).parameters[param].vartype is POINT2
        keys = [ctx.parameter(anchors_robot, param, i) for i in range(n)]
        anchors = np.array([np.asarray(ctx.initial_value(k))
                            for k in keys])
        unknown = sorted(set(spec["unknown"]))
        stream = ctx.stream(spec["stream"])
        rows = _range_rows(stream, spec, n)
        ranges = _Ranges(np.array([stream.t[r] for r, _, _ in rows]), np.array([i for _, i, _ in rows], int),
                         np.array([v for _, _, v in rows]))
        if len(unknown) == n:
            self._self_survey(ctx, spec, keys, ranges, self._window(ctx, spec, ranges, n))
            return
        known = ~np.isin(ranges.anchor, unknown)
        self._place(ctx, spec, anchors, ranges.subset(known), planar_anchors, odometry=True)
        for i in unknown:
            a, c, rms, count = self._fit(ctx, spec, ranges, i, planar_anchors)
            ctx.set_initial(keys[i], a if not planar_anchors else a[:2])
            if "bias" in spec.data:
                ctx.set_initial(ctx.parameter(robot, spec["bias"], i, 0), c)
            ctx.note(f"{spec.label}: anchor {i} initialized at ({', '.join(f'{x:.3f}' for x in a)}), bias "
                             f"{c:+.3f} m, fit rms {rms:.3f} m over {count} ranges")

    def _place(self, ctx, spec: Spec, anchors: np.ndarray, ranges: "_Ranges", planar_anchors: bool,
               odometry: bool = False) -> None:
        """Every pose from the ranges to `anchors` (n, d) by per-state multilateration; with `odometry`, for a
        planar robot ranging round-robin whose odometry links every state and that moves more than SMEAR while the
        anchors answer in turn, also the dead-reckoned path aligned to the ranges (alignment.py), and of the two
        the start the robot's factors fit better once solved."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        planar = states.family.vartype is POSE2
        b = lever_arm(ctx.robot(robot), spec.get("tag"))
        height = float(b[2]) if (planar and not planar_anchors) else None
        need = (anchors.shape[1] if height is None else 2) + 1
        window = self._window(ctx, spec, ranges, need)
        pos, usable = multilaterate(states.t, ranges.t, ranges.anchor, ranges.z, anchors, window, height)
        path = odometry_path(ctx.factors(robots=(robot,)), [ctx.pose_key(robot, k) for k in range(len(states))]) \
            if odometry and planar and window > 0 else None
        if path is not None and smear(path, states.t, window) <= SMEAR:
            path = None  # the tag hardly moves while the anchors answer in turn: multilateration places it
        if not usable.any() and path is None:
            raise spec.error("stream", "no state has ranges to enough known anchors within the window; widen "
                             "`window` or give more anchors known positions")
        if usable.any():
            guesses = np.where(usable[:, None], pos[:, :2], np.nan)
            pos = pos[usable][nearest_index(states.t[usable], states.t)]  # states short of ranges: the nearest usable
            self._set_poses(ctx, robot, states, pos, b, planar, spec.get("heading", "travel" if planar else "keep"))
        else:
            guesses = None
        if path is not None:
            self._try_odometry(ctx, spec, states, path, b, anchors, ranges, height, guesses, usable.any())

    def _try_odometry(self, ctx, spec: Spec, states, path: np.ndarray, b: np.ndarray, anchors: np.ndarray,
                      ranges: "_Ranges", height: float | None, guesses, have_multilateration: bool) -> None:
        """The dead-reckoned path aligned to the ranges as the start, if the robot's factors fit it better than the
        multilaterated one once solved (or nothing else places the robot); a note says so."""
        robot = spec["robot"]
        local = self._robot_graph(ctx, robot, spec["anchors"])
        if have_multilateration:
            from_ranges = self._solved_error(local, ctx.initial_values())
        flat = anchors[ranges.anchor][:, :2]
        rise = 0.0 if height is None else anchors[ranges.anchor][:, 2] - height
        z = np.sqrt(np.maximum(ranges.z ** 2 - rise ** 2, 0.0))  # horizontal ranges (planar tag, 3-D anchors)
        placed = align_pieces(path, states.t, b[:2], nearest_index(states.t, ranges.t), flat, z, guesses)
        keys = [ctx.pose_key(robot, k) for k in range(len(states))]
        before = {k: ctx.initial_value(k) for k in keys} if have_multilateration else {}
        for k, (x, y, th) in zip(keys, placed):
            ctx.set_initial(k, gtsam.Pose2(x, y, th))
        from_odometry = self._solved_error(local, ctx.initial_values())
        if have_multilateration and from_ranges <= from_odometry:
            for k, pose in before.items():
                ctx.set_initial(k, pose)
            return
        better = f" (its solve fits {from_ranges / from_odometry:.3g}x better)" if have_multilateration else ""
        ctx.note(f"{spec.label}: the ranges alone cannot place the robot epoch by epoch: it starts on its "
                         f"odometry's dead-reckoned path aligned to the ranges (each {PIECE_S:g} s piece placed by a "
                         f"global search over rotation and translation){better}")

    @staticmethod
    def _solved_error(graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> float:
        """The error of `graph` after a short Levenberg-Marquardt solve from `values` (how good a start is)."""
        settings = gtsam.LevenbergMarquardtParams()
        settings.setMaxIterations(MIRROR_ITERATIONS)
        return graph.error(gtsam.LevenbergMarquardtOptimizer(graph, values, settings).optimize())

    def _fit(self, ctx, spec: Spec, ranges: "_Ranges", i: int, planar_anchors: bool):
        """Anchor i and its constant bias from its ranges at the current poses: (a, c, rms, count)."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        b = lever_arm(ctx.robot(robot), spec.get("tag"))
        m = ranges.anchor == i
        points = self._tag_points(ctx, robot, states, ranges.t[m], b, states.family.vartype is POSE2, planar_anchors)
        try:
            a, c, rms = fit_range_origin(points, ranges.z[m])
        except ValueError as exc:
            raise spec.error("unknown", f"anchor {i}: {exc}") from None
        return a, c, rms, int(m.sum())

    @staticmethod
    def _window(ctx, spec: Spec, ranges: "_Ranges", need: int) -> float:
        """The entry's `window` (s); `auto`: round_window, with a note when it is not the state's own epoch."""
        if spec["window"] != "auto":
            return float(spec["window"])
        window = round_window(ranges.t, ranges.anchor, need)
        if window > 0:
            note = (f"{spec.label}: an epoch of stream {spec['stream']!r} reaches fewer than {need} anchors "
                    f"(round-robin ranging): each state is placed from the ranges within +-{window / 2:.3f} s "
                    "(window: auto)")
            ctx.note(note)
        return window

    def _self_survey(self, ctx, spec: Spec, keys: list[int], ranges: "_Ranges", window: float) -> None:
        """No anchor known (planar): place the anchors from the ranges, keep the placement or its
        mirror image (whichever the robot's factors fit better once solved; when they do not tell,
        anchor 2 on the +y side), then fix the frame: gauge priors, or the description's priors."""
        robot, param = spec["robot"], spec["anchor_parameter"]
        described = ctx.robot(spec["anchors"]).parameters[param]
        states = ctx.state_set(robot, spec)
        ranges = ranges.subset(line_of_sight(ranges.t, ranges.anchor, ranges.z))
        table = range_matrix(states.t, ranges.t, ranges.anchor, ranges.z, len(keys), window)
        try:
            placed, _ = place_anchors(table[~np.isnan(table).any(axis=1)], 2)
        except ValueError as exc:
            raise spec.error("unknown", f"every anchor is unknown, so they are placed from the ranges of stream "
                             f"{spec['stream']!r} alone: {exc}") from None
        local = self._robot_graph(ctx, robot, spec["anchors"])
        gauge = gauge_factors(keys[0], keys[1], GAUGE_SIGMA, GAUGE_SIGMA) if described.sigma is None else []
        for factor in gauge:
            local.add(factor)
        nominal = np.array([np.asarray(v, float) for v in described.values]) if described.sigma is not None else None
        outcomes = [self._survey_candidate(ctx, spec, keys, ranges, placed * [1.0, m], nominal, local)
                    for m in (1.0, -1.0)]
        (e0, up0, _), (e1, _, _) = outcomes
        best = int(e1 < e0) if abs(e1 - e0) > MIRROR_MARGIN else int(not up0)
        if best == 0:  # the graph's values are the mirror image's, the last one tried
            self._survey_candidate(ctx, spec, keys, ranges, placed, nominal, local)
        placed = outcomes[best][2]
        for factor in gauge:
            ctx.add_constraint(factor, f"gauge:{spec['anchors']}/{param}")
        if nominal is None:
            frame = ("the anchor frame (anchor 0 at the origin, anchor 1 on the +x axis), not the world: compare "
                     "with truth after alignment (truth: align: se3)")
        else:
            frame = ("the frame of the description's anchor values (placement moved rigidly onto them; their "
                     "priors hold it)")
        ctx.note(f"{spec.label}: no anchor surveyed: {spec['anchors']}/{param} and robot {robot!r} are "
                         f"placed from the ranges alone, in {frame}")
        for i, a in enumerate(placed):
            ctx.note(f"{spec.label}: anchor {i} placed at ({a[0]:.3f}, {a[1]:.3f})")

    def _survey_candidate(self, ctx, spec: Spec, keys: list[int], ranges: "_Ranges", anchors: np.ndarray,
                          nominal: np.ndarray | None, local: gtsam.NonlinearFactorGraph):
        """Anchors (n, 2) from one placement, moved into the frame (the anchor frame, or onto
        `nominal`), and the poses multilaterated from them; returns (the error of the robot's
        factors `local` once solved from there, anchor 2 on the +y side, the anchors)."""
        frame = anchor_frame(anchors) if nominal is None else rigid_fit(anchors, nominal)
        anchors = np.array([np.asarray(frame.transformFrom(a)) for a in anchors])
        for key, a in zip(keys, anchors):
            ctx.set_initial(key, a)
        self._place(ctx, spec, anchors, ranges, True)
        up = bool(anchor_frame(anchors).transformFrom(anchors[2])[1] > 0)
        return self._solved_error(local, ctx.initial_values()), up, anchors

    @staticmethod
    def _robot_graph(ctx, robot: str, anchors_robot: str) -> gtsam.NonlinearFactorGraph:
        """The factors on the robot's and the anchors' variables alone (its ranges, odometry, priors)."""
        graph = gtsam.NonlinearFactorGraph()
        for factor in ctx.factors(robots=(robot, anchors_robot)):
            graph.add(factor)
        return graph

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
                R = gtsam.Rot3.Yaw(th) if heading_mode == "travel" else ctx.initial_value(ctx.pose_key(robot, k)).rotation()
                ctx.set_initial(ctx.pose_key(robot, k), gtsam.Pose3(R, p - R.matrix() @ b))

    @staticmethod
    def _tag_points(ctx, robot, states, t, b, planar, planar_anchors):
        """Tag positions at the range times (nearest state's current initial pose)."""
        out = []
        for k in nearest_index(states.t, t):
            if planar:
                x = ctx.initial_value(ctx.pose_key(robot, int(k)))
                p = np.asarray(x.transformFrom(b[:2]))
                out.append(p if planar_anchors else np.append(p, b[2]))
            else:
                out.append(np.asarray(ctx.initial_value(ctx.pose_key(robot, int(k))).transformFrom(b)))
        return np.array(out)


INITIALIZERS = [Multilateration]
