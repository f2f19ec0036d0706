"""Dead reckoning aligned to the ranges: a planar robot's start when ranging cannot place it epoch by epoch
(round-robin ranging to far beacons at walking speed: the tag moves a metre or more while the anchors answer in
turn, and headings from the travel of such positions are noise).

The odometry factors between consecutive states (native BetweenFactorPose2) are composed from the origin into a
dead-reckoned path. Odometry drifts (a few % of the distance), so the path is placed in pieces of PIECE_S seconds,
each rigidly (rotation phi, translation t) where it best explains its ranges, by a global search: for each of
ROTATIONS rotations, the translation by Gauss-Newton with Cauchy weights (scale CAUCHY_SCALE: outliers and the
drift of the path hardly pull), started from the anchors' centroid and from the multilaterated positions where
there are any; the best REFINED rotations are then refined with the translation (Gauss-Newton on all three). The
robust cost is sum log(1 + (r / CAUCHY_SCALE)^2) over the ranges, r the range residual of the nearest state's tag.
"""

from __future__ import annotations

import gtsam
import numpy as np

ROTATIONS = 72         # rotations tried, 5 degrees apart
PIECE_S = 30.0         # s: the path is placed in pieces this long (its drift over a piece stays small)
PIECE_RANGES = 20      # a piece with fewer ranges keeps the whole path's placement
CAUCHY_SCALE = 1.0     # m
ITERATIONS = 12        # Gauss-Newton iterations per start
REFINED = 3            # best rotations refined with the rotation free


def odometry_path(factors, state_keys: list[int]) -> np.ndarray | None:
    """(S, 3) x, y, theta composed from the BetweenFactorPose2 factors between consecutive states (the first at the
    origin); None when an interval has none."""
    index = {k: i for i, k in enumerate(state_keys)}
    steps: dict[int, gtsam.Pose2] = {}
    for factor in factors:
        if isinstance(factor, gtsam.BetweenFactorPose2):
            a, b = factor.keys()
            if a in index and b in index and index[b] == index[a] + 1:
                steps.setdefault(index[a], factor.measured())
    if len(steps) < len(state_keys) - 1:
        return None
    pose, out = gtsam.Pose2(), [[0.0, 0.0, 0.0]]
    for i in range(len(state_keys) - 1):
        pose = pose.compose(steps[i])
        out.append([pose.x(), pose.y(), pose.theta()])
    out = np.array(out)
    out[:, 2] = np.unwrap(out[:, 2])
    return out


def _rot(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


def _cauchy_gauss_newton(x: np.ndarray, ranges) -> tuple[np.ndarray, float]:
    """ITERATIONS Gauss-Newton steps with Cauchy weights from x; `ranges(x)` gives the range residuals (R,) and their
    Jacobian (R, len(x)). Returns x and its robust cost sum log(1 + (e / CAUCHY_SCALE)^2)."""
    x = np.array(x, float)
    for _ in range(ITERATIONS):
        e, J = ranges(x)
        w = 1.0 / (1.0 + (e / CAUCHY_SCALE) ** 2)
        H = (J * w[:, None]).T @ J + 1e-9 * np.eye(len(x))
        x = x - np.linalg.solve(H, (J * w[:, None]).T @ e)
    e = ranges(x)[0]
    return x, float(np.sum(np.log1p((e / CAUCHY_SCALE) ** 2)))


def _distances(points: np.ndarray, anchors: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range residuals |p - a| - z and the unit vectors from the anchors (d |p - a| / d p)."""
    d = points - anchors
    r = np.linalg.norm(d, axis=1)
    return r - z, d / np.maximum(r, 1e-9)[:, None]


def _translation(q: np.ndarray, anchors: np.ndarray, z: np.ndarray, t0: np.ndarray) -> tuple[np.ndarray, float]:
    """The translation t minimizing the robust cost of ranges z to anchors from tag points q + t (all (R, 2))."""
    return _cauchy_gauss_newton(t0, lambda t: _distances(q + t, anchors, z))


def _refined(q0: np.ndarray, anchors: np.ndarray, z: np.ndarray, phi: float, t: np.ndarray):
    """(cost, phi, t) after Gauss-Newton with Cauchy weights on rotation and translation together."""
    def ranges(x):
        dR = np.array([[-np.sin(x[0]), -np.cos(x[0])], [np.cos(x[0]), -np.sin(x[0])]])
        e, u = _distances(q0 @ _rot(x[0]).T + x[1:], anchors, z)
        return e, np.column_stack([np.sum(u * (q0 @ dR.T), axis=1), u])
    x, cost = _cauchy_gauss_newton(np.array([phi, *t], float), ranges)
    return cost, float(x[0]), x[1:]


def align(path: np.ndarray, lever: np.ndarray, state_of_range: np.ndarray, anchors: np.ndarray, z: np.ndarray,
          guesses: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """The dead-reckoned `path` (S, 3) placed rigidly where it best explains the ranges z (R,) to `anchors` (R, 2)
    taken from states `state_of_range` (R,) with the tag at `lever` (2,) in the body; `guesses`: (S, 2) positions
    (e.g. multilaterated; NaN where none) that add a start per rotation. Returns the placed path and its robust
    cost."""
    c, s = np.cos(path[:, 2]), np.sin(path[:, 2])
    tag = path[:, :2] + np.column_stack([c * lever[0] - s * lever[1], s * lever[0] + c * lever[1]])
    q0 = tag[state_of_range]
    centroid = anchors.mean(axis=0)
    tried = []
    for phi in np.linspace(0.0, 2 * np.pi, ROTATIONS, endpoint=False):
        q = q0 @ _rot(phi).T
        starts = [centroid - q.mean(axis=0)]
        if guesses is not None and np.isfinite(guesses).all(axis=1).any():
            ok = np.isfinite(guesses).all(axis=1)
            starts.append(np.median(guesses[ok] - path[ok, :2] @ _rot(phi).T, axis=0))
        best = min((_translation(q, anchors, z, t0) for t0 in starts), key=lambda x: x[1])
        tried.append((best[1], phi, best[0]))
    tried.sort(key=lambda x: x[0])
    results = [_refined(q0, anchors, z, phi, t) for _, phi, t in tried[:REFINED]]
    cost, phi, t = min(results, key=lambda x: x[0])
    placed = np.column_stack([path[:, :2] @ _rot(phi).T + t, path[:, 2] + phi])
    return placed, cost


def align_pieces(path: np.ndarray, t_states: np.ndarray, lever: np.ndarray, state_of_range: np.ndarray,
                 anchors: np.ndarray, z: np.ndarray, guesses: np.ndarray | None = None) -> np.ndarray:
    """`align` piece by piece (PIECE_S s of states each; a piece with fewer than PIECE_RANGES ranges keeps the
    whole path's placement): the placed path (S, 3), discontinuous where pieces meet (the solve joins them)."""
    whole, _ = align(path, lever, state_of_range, anchors, z, guesses)
    out = whole.copy()
    piece = np.floor((t_states - t_states[0]) / PIECE_S).astype(int)
    for k in np.unique(piece):
        states = np.flatnonzero(piece == k)
        ranges = np.isin(state_of_range, states)
        if ranges.sum() < PIECE_RANGES:
            continue
        first = states[0]
        local = state_of_range[ranges] - first
        sub_guess = None if guesses is None else guesses[states]
        placed, _ = align(path[states], lever, local, anchors[ranges], z[ranges], sub_guess)
        out[states] = placed
    return out
