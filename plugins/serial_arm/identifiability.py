"""Which kinematic parameters the recorded configurations identify
(docs/models/serial_arm.md#identifiability).

The kinematic regressor stacks, over every measurement, the Jacobian of the whitened residual with
respect to the parameters (joint values held at their readings) at the nominal parameters. Its
columns are scaled by each parameter's prior sigma (1 in SI units without a prior), so the rank
decision does not depend on units. QR with column pivoting gives the rank r: a pivot |R_ii| below
`TOLERANCE` |R_00| adds no new direction. The n - r dimensional null space holds the combinations of
parameter changes that move no measurement. The parameters held to remove it are chosen from the
lowest priority up (the regressor's columns are in priority order: base, tool, joint offsets,
placements): a column is held when the null space restricted to the held columns stays of full
rank, so that fixing them removes the whole null space. Each held parameter's combination is the
null vector that is 1 on it and 0 on the other held ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import vectorized_kinematics
from .chain import SerialChain
from .kinematics import Layout, Parameters
from fusionkit.api import lie

TOLERANCE = 1e-8   # relative pivot below which a column is a combination of the others
SUPPORT = 1e-6     # relative weight below which a parameter is not part of a combination


def kinematic_regressor(chain: SerialChain, layout: Layout, p: Parameters, configurations: np.ndarray,
                        kind: str, sigma: np.ndarray) -> np.ndarray:
    """Stacked whitened Jacobians (rows: measurements x their dimension; columns: the layout's tangent
    axes in key order) at parameters `p`. kind: "pose" (6 rows, sigma [rotation x3, translation x3]),
    "position" (3 rows) or "relative" (configurations (N, 2, n): pairs a, b; 6 rows)."""
    q = np.asarray(configurations, float)
    N = len(q)
    if kind == "relative":
        a = vectorized_kinematics.marker_poses(chain, layout, q[:, 0], p, True)
        b = vectorized_kinematics.marker_poses(chain, layout, q[:, 1], p, True)
        back = lie.adjoint(lie.inverse(lie.inverse(a.T) @ b.T))
        J = np.concatenate([y - back @ x for x, y in zip(a.blocks[1:], b.blocks[1:])] or [np.zeros((N, 6, 0))], axis=2)
    else:
        poses = vectorized_kinematics.marker_poses(chain, layout, q, p, True)
        J = np.concatenate(poses.blocks[1:] or [np.zeros((N, 6, 0))], axis=2)
        if kind == "position":
            J = poses.T[:, :3, :3] @ J[:, 3:]
    A = J.reshape(-1, J.shape[2])
    return A / np.tile(np.asarray(sigma, float), N)[:, None]


@dataclass
class Identifiability:
    """The rank of the regressor, which columns are held and why, and the data-only sigmas."""

    rank: int
    held: list[int]                                  # held columns, in column order
    combinations: dict[int, list[tuple[int, float]]]  # held -> [(column, change per unit change of the held one)]
    sigma: np.ndarray                                # 1-sigma from the data alone (kept columns; 0 held)
    condition: float                                 # of the scaled regressor of the kept columns

    @property
    def identifiable(self) -> bool:
        return not self.held


def analyze(A: np.ndarray, scale: np.ndarray) -> Identifiability:
    """Rank, held columns and data-only sigmas of the whitened regressor A (columns in priority order,
    `scale` the characteristic size of each column's parameter)."""
    import scipy.linalg
    n = A.shape[1]
    As = A * scale
    _, R, piv = scipy.linalg.qr(As, mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > TOLERANCE * d[0])) if len(d) and d[0] > 0 else 0
    null = np.zeros((n, n - rank))
    if rank < n:  # A P [-R11^-1 R12; I] = 0
        null_p = np.vstack([-scipy.linalg.solve_triangular(R[:rank, :rank], R[:rank, rank:])
                            if rank else np.zeros((0, n)), np.eye(n - rank)])
        null[piv] = null_p
        null = np.linalg.qr(null)[0]
    held = _held_columns(null)
    combos = {}
    if held:
        basis = null @ np.linalg.inv(null[held])  # column i: the null vector that is 1 on held[i], 0 on the others
        for i, h in enumerate(held):
            v = basis[:, i] * scale / scale[h]
            big = SUPPORT * np.max(np.abs(v))
            combos[h] = [(j, float(v[j])) for j in np.argsort(-np.abs(v)) if j != h and abs(v[j]) > big]
    kept = [j for j in range(n) if j not in held]
    sigma = np.zeros(n)
    condition = 1.0
    if kept:
        s = np.linalg.svd(As[:, kept], compute_uv=False)
        condition = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
        r = np.linalg.qr(As[:, kept], mode="r")
        if len(r) == len(kept) and np.all(np.abs(np.diag(r)) > 0):
            r_inv = scipy.linalg.solve_triangular(r, np.eye(len(kept)))
            sigma[kept] = np.sqrt(np.sum(r_inv ** 2, axis=1)) * scale[kept]
        else:
            sigma[kept] = np.inf
    return Identifiability(rank, held, combos, sigma, condition)


def _held_columns(null: np.ndarray) -> list[int]:
    """Columns to hold so the null space is removed, taken from the last (lowest priority) backwards."""
    held: list[int] = []
    m = null.shape[1]
    for j in range(null.shape[0] - 1, -1, -1):
        if len(held) == m:
            break
        s = np.linalg.svd(null[held + [j]], compute_uv=False)
        if s[-1] > SUPPORT ** 0.5:
            held.append(j)
    return sorted(held)
