"""D-optimal pose selection before any data are taken (docs/models/serial_arm.md#pose-selection).

From M candidate configurations, pick N whose measurements maximize the determinant of the
information matrix of the identifiable kinematic parameters, and predict each parameter's 1-sigma.

Model: each candidate c contributes the whitened kinematic regressor block G_c (m x k; m = 6 for a
pose tracker, 3 for a position tracker; joint readings taken as exact) of the k parameter axes the
candidates identify (identifiability.analyze on all candidates: the held ones are left out, as a run
holds them), each column scaled by the parameter's prior sigma (1 SI unit without a prior). The
information of a set S is

    I(S) = P + sum_{c in S} G_c^T G_c,   P = diag(1 with a prior, EPSILON * g_i without)

(g_i: the information one candidate gives axis i on average: a vanishing prior that keeps the first
steps finite and the matrix well conditioned, whatever the axis's unit)

and the predicted sigma of axis i is sqrt(inv(I)_ii) times its scale. Greedy selection adds the
candidate of largest log det gain, by the matrix determinant lemma for a rank-m update,
log det(I + G^T G) = log det I + log det(1_m + G I^-1 G^T), evaluated for all candidates at once,
and keeps I^-1 by the Woodbury identity; a Fedorov exchange pass then swaps a selected candidate for
an unselected one while that raises log det (Fedorov 1972; the D-optimal pose selection of Sun and
Hollerbach 2008).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .chain import SerialChain
from .diagnosis import element_name, parameter_axes, prior_sigma
from .factors import entry_layout
from .identifiability import analyze, kinematic_regressor
from .kinematics import Layout, Parameters, parameters_of
from .model import arm_of

EPSILON = 1e-6           # prior information of a parameter without a prior, per candidate's average information
EXCHANGE_TOLERANCE = 1e-9  # least log det gain of a Fedorov swap
KINDS = ("pose", "position")


@dataclass
class Design:
    """What the selection needs of a serial_arm description: its chain, the layout of its kinematic
    parameters at their nominal values, and each regressor column's name, unit and prior sigma (inf:
    no prior); `free`: the layout's columns that are estimated (not `fixed: true`)."""

    chain: SerialChain
    layout: Layout
    nominal: Parameters
    names: list[str]
    units: list[str]
    prior: np.ndarray
    free: np.ndarray

    @property
    def scale(self) -> np.ndarray:
        return np.where(np.isfinite(self.prior), self.prior, 1.0)


def design_of(desc) -> Design:
    """The Design of a serial_arm description (its base, tool, offsets and placements)."""
    arm = arm_of(desc)
    tool = desc.parameters[arm.tool].vartype.name if arm.tool else ""
    layout, variables = entry_layout(arm, {}, tool)
    nominal = parameters_of(layout, [desc.parameters[name].values[index or 0] for name, index in variables])
    names, units, prior, free, c = [], [], [], [], 0
    for _, name, index, axes in parameter_axes(layout, variables, desc, arm.chain):
        for a, label, unit in axes:
            if not desc.parameters[name].fixed:
                names.append(element_name(desc, name, index) + label)
                units.append(unit)
                prior.append(prior_sigma(desc, name, index, a))
                free.append(c)
            c += 1
    return Design(arm.chain, layout, nominal, names, units, np.array(prior, float), np.array(free, int))


def regressor_blocks(design: Design, configurations: np.ndarray, kind: str, sigma: np.ndarray) -> np.ndarray:
    """(M, m, k) whitened regressor blocks of the free columns, each scaled by its parameter's scale."""
    q = np.asarray(configurations, float)
    A = kinematic_regressor(design.chain, design.layout, design.nominal, q, kind, sigma)[:, design.free]
    return (A * design.scale).reshape(len(q), -1, len(design.free))


def prior_information(design: Design, kept: list[int], G: np.ndarray) -> np.ndarray:
    """P of the kept columns (scaled units) for the candidate blocks G (M, m, len(kept)): 1 for a
    parameter with a prior, EPSILON times the candidates' average information on it without."""
    average = np.einsum("cmi,cmi->i", G, G) / len(G)
    return np.diag(np.where(np.isfinite(design.prior[kept]), 1.0, EPSILON * average))


def _gains(G: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For every candidate block G_c: log det(1 + G_c S G_c^T) (the log det gain of adding it to an
    information with inverse S), G_c S and 1 + G_c S G_c^T."""
    GS = G @ S
    C = np.eye(G.shape[1]) + GS @ np.swapaxes(G, 1, 2)
    return np.linalg.slogdet(C)[1], GS, C


@dataclass
class Selection:
    """The chosen candidates (rows of the candidate array, in the order chosen), the kept and held
    columns, the predicted 1-sigma of each kept column (SI units, Design.names[kept]), the log det of
    the information of the kept columns in scaled units (kept up to date by the determinant lemma),
    the number of exchange swaps, and what `sigma_of` needs: the candidates' blocks of the kept
    columns, the prior information and the columns' scales."""

    indices: np.ndarray
    kept: list[int]
    held: list[int]
    sigma: np.ndarray
    log_det: float
    swaps: int
    blocks: np.ndarray
    prior: np.ndarray
    scale: np.ndarray

    def sigma_of(self, rows) -> np.ndarray:
        """The predicted 1-sigma of the kept columns from the candidates `rows` (any choice of them)."""
        return np.sqrt(np.diag(np.linalg.inv(information(self.blocks, self.prior, rows)))) * self.scale


def select(design: Design, candidates: np.ndarray, kind: str, sigma: np.ndarray, count: int) -> Selection:
    """D-optimal choice of `count` of the candidate configurations (M, n): greedy, then Fedorov
    exchange. `sigma`: the tracker's 1-sigma per residual axis (pose: [rotation x3 (rad), translation
    x3 (m)]; position: 3 (m))."""
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r}; expected one of {KINDS}")
    candidates = np.asarray(candidates, float)
    if not 0 < count <= len(candidates):
        raise ValueError(f"count {count} of {len(candidates)} candidates")
    G_all = regressor_blocks(design, candidates, kind, sigma)
    held = analyze(G_all.reshape(-1, G_all.shape[2]), np.ones(G_all.shape[2])).held
    kept = [j for j in range(G_all.shape[2]) if j not in held]
    G = G_all[:, :, kept]
    P = prior_information(design, kept, G)
    S = np.linalg.inv(P)
    log_det = float(np.sum(np.log(np.diag(P))))
    chosen: list[int] = []
    for _ in range(count):  # greedy: largest gain, Woodbury update of S
        gain, GS, C = _gains(G, S)
        gain[chosen] = -np.inf
        i = int(np.argmax(gain))
        chosen.append(i)
        log_det += float(gain[i])
        S = S - GS[i].T @ np.linalg.solve(C[i], GS[i])
    swaps = 0
    for _ in range(10 * count):  # Fedorov exchange: the best swap of a chosen candidate for another
        best = (EXCHANGE_TOLERANCE, None, None)
        for a, i in enumerate(chosen):
            GS_i = G[i] @ S
            D = np.eye(G.shape[1]) - GS_i @ G[i].T  # removing i: log det gain log det(D)
            S_without = S + GS_i.T @ np.linalg.solve(D, GS_i)
            gain, _, _ = _gains(G, S_without)
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
        S = np.linalg.inv(information(G, P, chosen))
    scale = design.scale[kept]
    return Selection(np.array(chosen), kept, held, np.sqrt(np.diag(S)) * scale, log_det, swaps, G, P, scale)


def information(G: np.ndarray, P: np.ndarray, rows) -> np.ndarray:
    """I = P + sum_c G_c^T G_c over the candidate blocks `rows` (scaled units)."""
    B = G[list(rows)].reshape(-1, G.shape[2])
    return P + B.T @ B


def predicted_sigma(design: Design, configurations: np.ndarray, kind: str, sigma: np.ndarray,
                    selection: Selection) -> np.ndarray:
    """The 1-sigma (SI units) of the selection's kept columns that measurements at `configurations`
    would give, with the same priors: how any set of configurations compares with the selection."""
    G = regressor_blocks(design, configurations, kind, sigma)[:, :, selection.kept]
    return np.sqrt(np.diag(np.linalg.inv(information(G, selection.prior, range(len(G)))))) * selection.scale


def compared_with_random(selection: Selection, counts, draws: int, rng: np.random.Generator) -> dict[int, dict]:
    """{n: {geometric_mean, worst}}: the selection's predicted sigmas divided by those of n candidates
    picked at random (median over `draws` picks; `worst`: the ratio of the largest sigma relative to
    its scale). Below 1: the selection does better than n random candidates."""
    M, out = len(selection.blocks), {}
    for n in counts:
        if n > M:
            continue
        geo, worst = [], []
        for _ in range(draws):
            r = selection.sigma_of(rng.choice(M, n, replace=False))
            geo.append(np.exp(np.mean(np.log(selection.sigma / r))))
            worst.append(np.max(selection.sigma / selection.scale) / np.max(r / selection.scale))
        out[n] = {"geometric_mean": float(np.median(geo)), "worst": float(np.median(worst))}
    return out
