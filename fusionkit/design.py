"""Experiment design: choose N of M candidate measurements (arm configurations, cable-robot poses, ...) that
determine the calibration parameters best, before any data are taken (D-optimality).

A robot family supplies each candidate's block G_c (m x k): the whitened Jacobian of the measurements taken
there with respect to the k parameter axes, each column scaled by its parameter's prior sigma (1 SI unit without
one), and the prior information P (k x k, scaled units). The information of a set S of candidates is

    I(S) = P + sum_{c in S} G_c^T G_c

and the predicted 1-sigma of axis i is sqrt(inv(I)_ii) times its scale. Greedy selection adds the candidate of
largest log det gain, by the matrix determinant lemma for a rank-m update,
log det(I + G^T G) = log det I + log det(1_m + G I^-1 G^T), evaluated for all candidates at once, and keeps I^-1
by the Woodbury identity; a Fedorov exchange pass then swaps a selected candidate for an unselected one while
that raises log det (Fedorov 1972; the D-optimal pose selection of Sun and Hollerbach 2008).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EXCHANGE_TOLERANCE = 1e-9  # least log det gain of a Fedorov swap
EPSILON = 1e-6  # prior information of an axis without a prior, per candidate's average information


def prior_information(blocks: np.ndarray, prior_sigma: np.ndarray) -> np.ndarray:
    """P in scaled units for candidate blocks (M, m, k): 1 for an axis with a prior (finite `prior_sigma`),
    EPSILON times the candidates' average information on it without (a vanishing prior that keeps the first
    steps finite and the matrix well conditioned, whatever the axis's unit)."""
    average = np.einsum("cmi,cmi->i", blocks, blocks) / len(blocks)
    return np.diag(np.where(np.isfinite(prior_sigma), 1.0, EPSILON * average))


def information(blocks: np.ndarray, prior: np.ndarray, rows) -> np.ndarray:
    """I = P + sum_c G_c^T G_c over the candidate blocks `rows` (scaled units)."""
    B = blocks[list(rows)].reshape(-1, blocks.shape[2])
    return prior + B.T @ B


def _gains(blocks: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every candidate block G_c: log det(1 + G_c S G_c^T) (the log det gain of adding it to an
    information with inverse S), G_c S and 1 + G_c S G_c^T."""
    GS = blocks @ S
    C = np.eye(blocks.shape[1]) + GS @ np.swapaxes(blocks, 1, 2)
    return np.linalg.slogdet(C)[1], GS, C


@dataclass
class Choice:
    """The chosen candidates (rows, in the order chosen), the predicted 1-sigma of each axis (SI units), the log
    det of the information in scaled units, the number of exchange swaps, and what `sigma_of` needs: the
    candidates' blocks, the prior information and the axes' scales."""

    indices: np.ndarray
    sigma: np.ndarray
    log_det: float
    swaps: int
    blocks: np.ndarray
    prior: np.ndarray
    scale: np.ndarray

    def sigma_of(self, rows) -> np.ndarray:
        """The predicted 1-sigma (SI units) of every axis from the candidates `rows` (any choice of them)."""
        return np.sqrt(np.diag(np.linalg.inv(information(self.blocks, self.prior, rows)))) * self.scale


def d_optimal(blocks: np.ndarray, prior: np.ndarray, scale: np.ndarray, count: int) -> Choice:
    """D-optimal choice of `count` of the candidates whose blocks (M, m, k) are given in scaled units (`scale`: each
    axis's scale, SI units per scaled unit; `prior`: the prior information): greedy, then Fedorov exchange."""
    if not 0 < count <= len(blocks):
        raise ValueError(f"count {count} of {len(blocks)} candidates")
    S = np.linalg.inv(prior)
    log_det = float(np.linalg.slogdet(prior)[1])
    chosen: list[int] = []
    for _ in range(count):  # greedy: largest gain, Woodbury update of S
        gain, GS, C = _gains(blocks, S)
        gain[chosen] = -np.inf
        i = int(np.argmax(gain))
        chosen.append(i)
        log_det += float(gain[i])
        S = S - GS[i].T @ np.linalg.solve(C[i], GS[i])
    swaps = 0
    for _ in range(10 * count):  # Fedorov exchange: the best swap of a chosen candidate for another
        best = (EXCHANGE_TOLERANCE, None, None)
        for a, i in enumerate(chosen):
            GS_i = blocks[i] @ S
            D = np.eye(blocks.shape[1]) - GS_i @ blocks[i].T  # removing i: log det gain log det(D)
            S_without = S + GS_i.T @ np.linalg.solve(D, GS_i)
            gain, _, _ = _gains(blocks, S_without)
            gain[chosen] = -np.inf
            j = int(np.argmax(gain))
            total = float(np.linalg.slogdet(D)[1] + gain[j])
            if total > best[0]:
                best = (total, a, j)
        if best[1] is None:
            break
        chosen[best[1]] = best[2]
        log_det += best[0]
        swaps += 1
        S = np.linalg.inv(information(blocks, prior, chosen))
    return Choice(np.array(chosen), np.sqrt(np.diag(S)) * scale, log_det, swaps, blocks, prior, scale)


def compared_with_random(choice: Choice, counts, draws: int, rng: np.random.Generator) -> dict[int, dict]:
    """{n: {geometric_mean, worst}}: the choice's predicted sigmas divided by those of n candidates picked at
    random (median over `draws` picks; `worst`: the ratio of the largest sigma relative to its scale). Below 1:
    the choice does better than n random candidates."""
    M, out = len(choice.blocks), {}
    for n in counts:
        if n > M:
            continue
        geo, worst = [], []
        for _ in range(draws):
            r = choice.sigma_of(rng.choice(M, n, replace=False))
            geo.append(np.exp(np.mean(np.log(choice.sigma / r))))
            worst.append(np.max(choice.sigma / choice.scale) / np.max(r / choice.scale))
        out[n] = {"geometric_mean": float(np.median(geo)), "worst": float(np.median(worst))}
    return out
