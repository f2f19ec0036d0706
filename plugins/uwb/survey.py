"""Anchor self-survey: planar anchor positions from tag-to-anchor ranges alone, and the frame they
are reported in when no anchor was surveyed.

Ranges z_ij from tag positions p_i to anchors a_j determine both sets only up to a rigid motion
and a mirror image (the gauge). `place_anchors` solves the squared ranges D_ij = |p_i - a_j|^2
in closed form, in the way of the factorization methods for time-of-arrival self-calibration
(Kuang, Burgess, Torstensson and Astrom, "A complete characterization and solution to the
microphone position self-calibration problem", ICASSP 2013): centring D over epochs and anchors
leaves -2 (p_i - p_mean).(a_j - a_mean), a rank-d matrix; its truncated SVD gives both sets up to
an unknown d x d matrix L, and the mean squared range of each epoch, |p_i - a_mean|^2 + const, is
quadratic in the SVD coordinates with the matrix M = L L^T: a linear least-squares fit gives M,
hence L up to a rotation (the gauge). Units: metres.

`anchor_frame` is the documented gauge: anchor 0 at the origin, anchor 1 on the +x axis.
"""

from __future__ import annotations

import gtsam
import numpy as np

SPAN_RATIO = 3.0  # the d-th singular value must exceed the first misfit one by this (path spans d-D)
SCREEN_WINDOW = 4.0  # s: running median of each anchor's ranges, longer than a non-line-of-sight burst
SCREEN_JUMP = 0.25  # m: ranges this far from their running median are left out of the survey


def range_matrix(t_states: np.ndarray, t_ranges: np.ndarray, anchor_index: np.ndarray, ranges: np.ndarray,
                 n: int, window: float) -> np.ndarray:
    """(S, n) mean range (m) from each state's tag to each anchor over the ranges within
    +-window/2 s of the state time (window 0: the state's own epoch); NaN where there is none."""
    out = np.full((len(t_states), n), np.nan)
    for j in range(n):
        m = anchor_index == j
        t, z = t_ranges[m], ranges[m]
        lo = np.searchsorted(t, t_states - window / 2, side="left")
        hi = np.searchsorted(t, t_states + window / 2, side="right")
        total = np.concatenate([[0.0], np.cumsum(z)])
        count = hi - lo
        out[count > 0, j] = (total[hi] - total[lo])[count > 0] / count[count > 0]
    return out


def line_of_sight(t_ranges: np.ndarray, anchor_index: np.ndarray, ranges: np.ndarray) -> np.ndarray:
    """Mask of the ranges (m) within SCREEN_JUMP of their anchor's running median over SCREEN_WINDOW
    s: a non-line-of-sight burst (a reflection, metres long for a second or so) stands out of it."""
    from scipy.ndimage import median_filter
    keep = np.ones(len(ranges), bool)
    for j in np.unique(anchor_index):
        m = np.flatnonzero(anchor_index == j)
        step = np.median(np.diff(t_ranges[m])) if len(m) > 1 else SCREEN_WINDOW
        half = min(int(SCREEN_WINDOW / max(step, 1e-9) / 2), len(m) - 1)
        z = ranges[m]
        # odd extension at both ends: a range that rises or falls there keeps its trend
        padded = np.concatenate([2 * z[0] - z[half:0:-1], z, 2 * z[-1] - z[-2:-half - 2:-1]])
        keep[m] = np.abs(z - median_filter(padded, size=2 * half + 1)[half:half + len(z)]) <= SCREEN_JUMP
    return keep


def place_anchors(ranges: np.ndarray, d: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Anchor positions (n, d) and tag positions (K, d), in an arbitrary frame, from a complete
    (K epochs, n anchors) matrix of ranges (m). Raises ValueError with the reason when the ranges
    do not determine them: fewer than d + 1 anchors, or a tag path that does not span d-D."""
    K, n = ranges.shape
    if n < d + 1:
        raise ValueError(f"{n} anchors; placing anchors from ranges alone needs at least {d + 1}")
    unknowns = 1 + d + d * (d + 1) // 2
    if K < 2 * unknowns:
        raise ValueError(f"{K} epochs have a range to every anchor; at least {2 * unknowns} are needed")
    D = ranges ** 2
    centred = D - D.mean(axis=0) - D.mean(axis=1, keepdims=True) + D.mean()
    U, s, Vt = np.linalg.svd(centred, full_matrices=False)
    misfit = s[d] if n > d + 1 else 0.0
    if s[d - 1] <= SPAN_RATIO * misfit or s[d - 1] <= 1e-9 * s[0]:
        raise ValueError(_flat_path_message(d))
    X, Y = U[:, :d] * np.sqrt(s[:d]), Vt[:d].T * np.sqrt(s[:d])
    # mean_j D_ij = kappa + 2 u.x_i + x_i^T M x_i  (x_i: SVD coordinates of epoch i)
    rows, cols = np.triu_indices(d)
    quadratic = np.column_stack([X[:, i] * X[:, j] * (1.0 if i == j else 2.0) for i, j in zip(rows, cols)])
    solution, *_ = np.linalg.lstsq(np.column_stack([np.ones(K), 2 * X, quadratic]), D.mean(axis=1), rcond=None)
    M = np.zeros((d, d))
    M[rows, cols] = solution[1 + d:]
    M = M + M.T - np.diag(np.diag(M))
    if np.linalg.eigvalsh(M)[0] <= 0:
        raise ValueError(_flat_path_message(d))
    L = np.linalg.cholesky(M)
    offset = np.linalg.solve(L, solution[1:1 + d])  # mean tag position minus mean anchor position
    return -0.5 * np.linalg.solve(L, Y.T).T, offset + X @ L


def _flat_path_message(d: int) -> str:
    return (f"the tag's path does not span {'the plane' if d == 2 else '3-D'} among the anchors (move across "
            "the site, not along a line; record longer)")


def anchor_frame(anchors: np.ndarray) -> gtsam.Pose2:
    """The planar transform into the anchor frame: anchor 0 to the origin, anchor 1 onto +x."""
    a0, a1 = anchors[0], anchors[1]
    theta = np.arctan2(a1[1] - a0[1], a1[0] - a0[0])
    return gtsam.Pose2(0.0, 0.0, -theta).compose(gtsam.Pose2(-a0[0], -a0[1], 0.0))


def rigid_fit(source: np.ndarray, target: np.ndarray) -> gtsam.Pose2:
    """The planar rotation and translation (no mirror, no scale) that best maps points `source`
    onto `target` (n, 2), least squares (Umeyama, 1991)."""
    ms, mt = source.mean(axis=0), target.mean(axis=0)
    H = (source - ms).T @ (target - mt)
    theta = np.arctan2(H[0, 1] - H[1, 0], H[0, 0] + H[1, 1])
    c, s = np.cos(theta), np.sin(theta)
    t = mt - np.array([[c, -s], [s, c]]) @ ms
    return gtsam.Pose2(t[0], t[1], theta)


def _bearing_error(this, values: gtsam.Values, H):
    """The bearing (rad) of a point from the origin: zero on the +x axis, +-pi on the -x axis."""
    x, y = values.atPoint2(this.keys()[0])
    if H is not None:
        H[0] = np.array([[-y, x]]) / max(x * x + y * y, 1e-12)
    return np.array([np.arctan2(y, x)])


def gauge_factors(anchor0: int, anchor1: int, sigma: float, bearing_sigma: float) -> list[gtsam.NonlinearFactor]:
    """Priors that hold the anchor frame: anchor 0 at (0, 0) (sigma m), anchor 1 at bearing 0 from
    it (bearing_sigma rad; a bearing, not y = 0, so that the solver cannot turn the frame by a half
    turn onto -x)."""
    return [gtsam.PriorFactorPoint2(anchor0, np.zeros(2), gtsam.noiseModel.Isotropic.Sigma(2, sigma)),
            gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(1, bearing_sigma), [anchor1], _bearing_error)]
