"""D-optimal pose selection before any data are taken (docs/models/serial_arm.md#pose-selection).

From M candidate configurations, pick N whose measurements maximize the determinant of the
information matrix of the identifiable kinematic parameters, and predict each parameter's 1-sigma.

Each candidate c contributes the whitened kinematic regressor block G_c (m x k; m = 6 for a pose tracker, 3 for
a position tracker; joint readings taken as exact) of the k parameter axes the candidates identify
(identifiability.analyze on all candidates: the held ones are left out, as a run holds them), each column scaled
by the parameter's prior sigma (1 SI unit without a prior); the choice itself is fusionkit's D-optimal design
(fusionkit.api.d_optimal: greedy by the determinant lemma, then Fedorov exchange).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from fusionkit.api import Choice, d_optimal, information, prior_information

from .chain import SerialChain
from .diagnosis import element_name, parameter_axes, prior_sigma
from .factors import entry_layout
from .identifiability import analyze, kinematic_regressor
from .kinematics import Layout, Parameters, parameters_of
from .model import arm_of

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


@dataclass
class Selection(Choice):
    """The core's Choice of candidates, with the design's kept and held columns (Design.names indices)."""

    kept: list[int] = field(default_factory=list)
    held: list[int] = field(default_factory=list)


def select(design: Design, candidates: np.ndarray, kind: str, sigma: np.ndarray, count: int) -> Selection:
    """D-optimal choice of `count` of the candidate configurations (M, n). `sigma`: the tracker's 1-sigma per
    residual axis (pose: [rotation x3 (rad), translation x3 (m)]; position: 3 (m))."""
    if kind not in KINDS:
        raise ValueError(f"kind {kind!r}; expected one of {KINDS}")
    candidates = np.asarray(candidates, float)
    G_all = regressor_blocks(design, candidates, kind, sigma)
    held = analyze(G_all.reshape(-1, G_all.shape[2]), np.ones(G_all.shape[2])).held
    kept = [j for j in range(G_all.shape[2]) if j not in held]
    G = G_all[:, :, kept]
    choice = d_optimal(G, prior_information(G, design.prior[kept]), design.scale[kept], count)
    return Selection(**vars(choice), kept=kept, held=held)


def predicted_sigma(design: Design, configurations: np.ndarray, kind: str, sigma: np.ndarray,
                    selection: Selection) -> np.ndarray:
    """The 1-sigma (SI units) of the selection's kept columns that measurements at `configurations`
    would give, with the same priors: how any set of configurations compares with the selection."""
    G = regressor_blocks(design, configurations, kind, sigma)[:, :, selection.kept]
    return np.sqrt(np.diag(np.linalg.inv(information(G, selection.prior, range(len(G)))))) * selection.scale
