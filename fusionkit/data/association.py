"""Associate stream samples with states: nearest stamp within a tolerance, or pose interpolation."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# an entry's `tolerance:` (s): a sample pairs with the nearest state at most this far away in time
TOLERANCE_SCHEMA = {"type": "number", "minimum": 0, "default": 0.005}


@dataclass
class Association:
    """`state[i]` is paired with stream row `row[i]`; `unmatched` rows had no state near enough."""

    state: np.ndarray
    row: np.ndarray
    unmatched: int


def nearest(state_t: np.ndarray, sample_t: np.ndarray, tolerance: float) -> Association:
    """Pair each state with the closest sample within `tolerance` seconds: one sample per state, or all the
    samples stamped like the closest one (a round-robin log's readings of one epoch); a sample pairs with at
    most one state."""
    idx = np.clip(np.searchsorted(state_t, sample_t), 1, len(state_t) - 1) if len(state_t) > 1 else \
        np.zeros(len(sample_t), dtype=int)
    if len(state_t) > 1:
        left = idx - 1
        pick_left = np.abs(sample_t - state_t[left]) <= np.abs(state_t[idx] - sample_t)
        idx = np.where(pick_left, left, idx)
    dt = np.abs(state_t[idx] - sample_t)
    ok = dt <= tolerance
    rows = np.flatnonzero(ok)
    states = idx[ok]
    # keep for each state the closest sample, and the samples that repeat its stamp
    order = np.lexsort((dt[rows], states))
    rows, states = rows[order], states[order]
    first = np.ones(len(states), dtype=bool)
    first[1:] = states[1:] != states[:-1]
    closest = sample_t[rows[first]][np.cumsum(first) - 1]
    keep = sample_t[rows] == closest
    rows, states = rows[keep], states[keep]
    return Association(states, rows, int(len(sample_t) - len(rows)))


def interpolate_poses(sample_t: np.ndarray, poses: np.ndarray, query_t: np.ndarray,
                      max_gap: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Poses (N, 7: x y z qx qy qz qw) at `query_t`: linear position, slerp rotation.

    Returns (mask of queries inside the sample span and not across a gap > max_gap, (M, 7) poses).
    """
    from scipy.spatial.transform import Rotation, Slerp
    if len(query_t) == len(sample_t) and np.array_equal(query_t, sample_t):
        return np.ones(len(query_t), dtype=bool), poses.copy()  # states clocked by this stream
    inside = (query_t >= sample_t[0]) & (query_t <= sample_t[-1])
    q = query_t[inside]
    out = np.empty((len(q), 7))
    if len(sample_t) == 1:
        out[:] = poses[0]
        return inside, out
    for axis in range(3):
        out[:, axis] = np.interp(q, sample_t, poses[:, axis])
    out[:, 3:] = Slerp(sample_t, Rotation.from_quat(poses[:, 3:]))(q).as_quat()
    if max_gap is not None:
        hi = np.clip(np.searchsorted(sample_t, q), 1, len(sample_t) - 1)
        gap = sample_t[hi] - sample_t[hi - 1]
        on_sample = (q == sample_t[hi]) | (q == sample_t[hi - 1])  # no interpolation needed
        ok = (gap <= max_gap) | on_sample
        full = np.flatnonzero(inside)
        inside = inside.copy()
        inside[full[~ok]] = False
        out = out[ok]
    return inside, out


def segment_ids(sample_t: np.ndarray, query_t: np.ndarray, max_gap: float | None) -> np.ndarray:
    """For each query time, the index of the gap-free stretch of samples it falls in (stretches are
    separated by sample gaps longer than `max_gap`); queries in different stretches must not be
    linked by a relative measurement."""
    if max_gap is None or len(sample_t) < 2:
        return np.zeros(len(query_t), dtype=int)
    seg = np.concatenate([[0], np.cumsum(np.diff(sample_t) > max_gap)])
    lo = np.clip(np.searchsorted(sample_t, query_t, side="right") - 1, 0, len(sample_t) - 1)
    return seg[lo]
