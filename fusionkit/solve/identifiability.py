"""What the data determine of the calibration parameters, from the estimate alone (no truth, no second solve).

The parameters are the static unknowns (not fixed; axes a factor holds are left out). Their joint posterior
covariance S is the inverse of their marginal information: the graph linearized at the estimate, every other
variable eliminated (GTSAM's partial multifrontal elimination: what is left is the Schur complement on the
parameters), the held axes' rows and columns dropped before inverting (they are pinned). From S, per scalar component (a pose parameter's tangent axes named like `arm/base.rz`):

- **correlated pairs**: |rho| > CORRELATED. The data fix a combination of the two, not each.
- **the prior decides**: a component with a prior whose posterior sigma exceeds PRIOR_DECIDES times the
  prior's: the data add less than half its information.
- **rests on a prior**: a component whose estimate a prior-decided component's prior moves by more than
  RESTS_ON of its own sigma when that prior's mean moves by one prior sigma (d x_i / d mu_j = S_ij / P_j):
  its value is as good as that prior, and whatever else acts along the pair (a wheel slip in a turn acts
  like a heading scale) is absorbed into it.
- **hardly told apart**: each group of components linked by either, with its weakest direction
  (the top eigenvector of the group's correlation matrix: the combination whose error the data leave
  largest), written as one posterior sigma along it in each component's units. A factor type that knows
  what separates the group says so (`FactorType.separation_hint`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..graph.builder import Problem
from .prior_check import description_priors

CORRELATED = 0.9  # |rho| beyond which two components are reported as confused
PRIOR_DECIDES = 0.7  # posterior sigma over prior sigma beyond which the prior, not the data, decides
RESTS_ON = 0.5  # a prior moving a component by more than this share of its sigma, per prior sigma
SHOWN = 8  # lines of each kind the console prints (report.json has all)
MAX_DIM = 400  # parameter components analysed at most (the joint covariance is dense)
STATIC = float("-inf")


@dataclass
class Direction:
    """A group of components the data hardly tell apart: its members (indices), one posterior sigma along its
    weakest direction in each member's units, and what would separate them (factor types' hints)."""

    members: list[int]
    step: list[float]
    hints: list[str] = field(default_factory=list)


@dataclass
class Identifiability:
    """The report: component names and units, posterior sigmas, correlation matrix, and what it says."""

    names: list[str]
    units: list[str]
    sigma: np.ndarray
    correlation: np.ndarray
    prior_sigma: dict[int, float]
    pairs: list[tuple[int, int, float]]
    prior_decides: list[int]
    rests_on: list[tuple[int, int, float]]  # (component, prior-decided component, sigmas moved per prior sigma)
    directions: list[Direction]

    def scaled(self, factor: float) -> None:
        """Sigmas and steps multiplied by `factor` (sigma0 under solver.a_posteriori_sigmas, as the covariances
        are); correlations and the judgements made against the priors stay as computed."""
        self.sigma = self.sigma * factor
        for d in self.directions:
            d.step = [s * factor for s in d.step]

    def to_json(self) -> dict:
        return {"parameters": self.names, "units": self.units, "sigma": self.sigma.tolist(),
                "correlation": np.round(self.correlation, 4).tolist(),
                "correlated_pairs": [{"a": self.names[i], "b": self.names[j], "rho": round(r, 4)}
                                     for i, j, r in self.pairs],
                "prior_decides": [{"parameter": self.names[i], "sigma_over_prior": round(self.sigma[i] /
                                                                                     self.prior_sigma[i], 4)}
                                  for i in self.prior_decides],
                "rests_on_prior": [{"parameter": self.names[i], "prior_of": self.names[j], "sigmas_per_prior_sigma":
                                    round(m, 4)} for i, j, m in self.rests_on],
                "hardly_told_apart": [{"parameters": [self.names[i] for i in d.members], "one_sigma_step": d.step,
                                       "hints": d.hints} for d in self.directions]}

    def lines(self) -> list[str]:
        """The console's short section (empty when the data determine every component on its own): one line
        for the prior-decided components, one per component resting on a prior, one per group hardly told
        apart (its correlations, its weakest combination, what would separate it); at most SHOWN of each."""
        out = []
        if self.prior_decides:
            listed = ", ".join(f"{self.names[i]} {self.sigma[i] / self.prior_sigma[i]:.2f}"
                               for i in self.prior_decides[:SHOWN])
            out.append(f"the prior decides, not the data (sigma over the prior's): {listed}"
                       + _more(len(self.prior_decides)))
        out += [f"rests on the prior of {self.names[j]}: {self.names[i]} (moved {m:+.2f} of its sigma per sigma of "
                "that prior)" for i, j, m in self.rests_on[:SHOWN]]
        if len(self.rests_on) > SHOWN:
            out.append(f"... and {len(self.rests_on) - SHOWN} more resting on priors (report.json)")
        for d in self.directions[:SHOWN]:
            inside = [float(self.correlation[i, j]) for a, i in enumerate(d.members) for j in d.members[a + 1:]]
            rho = f"; rho {min(inside):+.2f} .. {max(inside):+.2f}" if len(inside) > 1 else (
                f"; rho {inside[0]:+.2f}" if inside else "")
            along = ", ".join(f"{s:+.3g}{(' ' + self.units[i]) if self.units[i] else ''} {self.names[i]}"
                              for i, s in zip(d.members, d.step))
            out.append(f"hardly told apart{rho}: one sigma along their weakest combination is {along}"
                       + "".join(f"; {h}" for h in d.hints))
        if len(self.directions) > SHOWN:
            out.append(f"... and {len(self.directions) - SHOWN} more groups hardly told apart (report.json)")
        return out


def _more(count: int) -> str:
    return f", and {count - SHOWN} more (report.json)" if count > SHOWN else ""


def parameter_indices(parameters: list[str], robot: str, name: str) -> set[int]:
    """The element indices i of `robot/name[i]` among `parameters` (full names, as `FactorType.separation_hint`
    is given them): e.g. the cables whose pulley is in a group."""
    pattern = re.compile(rf"{re.escape(robot)}/{re.escape(name)}\[(\d+)\]")
    return {int(m.group(1)) for m in map(pattern.fullmatch, parameters) if m}


def parameter_keys(problem: Problem) -> list[int]:
    """The static unknowns the report covers: not fixed (axes a factor holds are left out of the report)."""
    return sorted(k for k, t in problem.key_time.items() if t == STATIC and k not in problem.fixed_keys)


def marginal_factors(problem: Problem, values: gtsam.Values, keys: list[int], qr: bool = False,
                     linear: gtsam.GaussianFactorGraph | None = None) -> gtsam.GaussianFactorGraph:
    """What the graph says of `keys` at `values` (`linear`: the graph linearized there, if at hand), every other
    variable eliminated: linear factors on `keys` alone, whose information is the Schur complement on them."""
    linear = problem.evaluator().linearize(values) if linear is None else linear
    full = gtsam.Ordering.ColamdConstrainedLastGaussianFactorGraph(linear, gtsam.KeyVector(keys))
    wanted = set(keys)
    others = gtsam.Ordering()
    for i in range(full.size()):
        if full.at(i) not in wanted:
            others.push_back(full.at(i))
    try:
        _, rest = (linear.eliminatePartialMultifrontal(others, gtsam.EliminateQR) if qr
                   else linear.eliminatePartialMultifrontal(others))
    except RuntimeError:  # Cholesky on an ill-conditioned system: QR, as the solve falls back to
        if qr:
            raise
        _, rest = linear.eliminatePartialMultifrontal(others, gtsam.EliminateQR)
    return rest


def marginal_information(problem: Problem, values: gtsam.Values, keys: list[int], qr: bool = False,
                         linear: gtsam.GaussianFactorGraph | None = None) -> np.ndarray:
    """The information of `keys` (their tangent spaces, in `keys`' order) at `values`, every other variable
    eliminated: the Schur complement on `keys` (marginal_factors as one matrix)."""
    rest = marginal_factors(problem, values, keys, qr, linear)
    order = gtsam.Ordering()
    for k in keys:
        order.push_back(k)
    information = rest.augmentedHessian(order)[:-1, :-1]
    return 0.5 * (information + information.T)


def covariance_of(information: np.ndarray) -> np.ndarray:
    """The inverse of an information matrix, scaled to unit diagonal first (the components' units differ by
    orders of magnitude); a singular one by its pseudo-inverse."""
    d = np.sqrt(np.maximum(np.diag(information), np.finfo(float).tiny))
    scaled = information / np.outer(d, d)
    try:
        inverse = np.linalg.inv(scaled)
    except np.linalg.LinAlgError:
        inverse = np.linalg.pinv(scaled, hermitian=True)
    return inverse / np.outer(d, d)


def identifiability(problem: Problem, values: gtsam.Values, qr: bool = False, hints=None,
                    parameter=None, linear: gtsam.GaussianFactorGraph | None = None) -> Identifiability | None:
    """The report for `problem`'s parameters at the estimate `values`; None without parameters, or with more
    than MAX_DIM components. `hints(names)`: what would separate a group of parameters (their full names,
    `robot/name`), a list of sentences; `parameter(robot, name)`: the description's Parameter (its unit and
    component names; pose axes are rad and m), None if none; `linear`: the graph linearized at `values`, if at
    hand."""
    keys = parameter_keys(problem)
    dims = [problem.keys.decode(k)[0].vartype.dim for k in keys]
    if not keys or sum(dims) > MAX_DIM:
        return None
    information = marginal_information(problem, values, keys, qr, linear)
    names, units, owner, kept = [], [], [], []
    for k, dim in zip(keys, dims):
        family, _ = problem.keys.decode(k)
        declared = parameter(family.robot, family.name) if parameter else None
        axes = declared.axes if declared is not None and declared.axes else family.vartype.names()[1]
        base = problem.keys.name_of(k)
        held = problem.held[k].axes if k in problem.held else ()
        for axis in range(dim):
            kept.append(axis not in held)
            if axis in held:
                continue
            names.append(base if dim == 1 else f"{base}.{axes[axis]}")
            units.append(family.vartype.unit(axis, (declared.unit or "") if declared is not None else ""))
            owner.append(base)
    prior_sigma = _prior_sigmas(problem, keys, dims, np.flatnonzero(kept))
    if not names:
        return None
    covariance = covariance_of(information[np.ix_(kept, kept)])  # held axes pinned: conditioned on them
    sigma = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    scale = np.where(sigma > 0, sigma, 1.0)
    correlation = covariance / np.outer(scale, scale)
    n = len(names)
    pairs = [(i, j, float(correlation[i, j])) for i in range(n) for j in range(i + 1, n)
             if abs(correlation[i, j]) > CORRELATED]
    decides = sorted(i for i, s in prior_sigma.items() if sigma[i] > PRIOR_DECIDES * s)
    rests_on = [(i, j, float(covariance[i, j] / prior_sigma[j] / scale[i])) for j in decides for i in range(n)
                if i != j and abs(covariance[i, j] / prior_sigma[j]) > RESTS_ON * sigma[i]]
    directions = []
    for group in _groups(n, pairs + rests_on):
        w, v = np.linalg.eigh(correlation[np.ix_(group, group)])
        top = v[:, -1] * np.sqrt(w[-1])
        top = top if top[np.argmax(np.abs(top))] > 0 else -top
        step = [float(c * sigma[i]) for c, i in zip(top, group)]
        parameters = sorted({owner[i] for i in group})
        directions.append(Direction(group, step, list(hints(parameters)) if hints else []))
    return Identifiability(names, units, sigma, correlation, prior_sigma, pairs, decides, rests_on, directions)


def _prior_sigmas(problem: Problem, keys: list[int], dims: list[int], kept: np.ndarray) -> dict[int, float]:
    """Reported component index -> its description prior's sigma, for the components that have one; `kept`:
    the reported components' indices among all of `keys`' axes."""
    start = dict(zip(keys, np.cumsum([0] + dims[:-1])))
    reported = {int(c): i for i, c in enumerate(kept)}
    out = {}
    for key, factor in description_priors(problem):
        if key not in start:
            continue
        for axis, s in enumerate(factor.noiseModel().sigmas()):
            component = int(start[key]) + axis
            if component in reported:
                out[reported[component]] = float(s)
    return out


def _groups(n: int, pairs: list[tuple[int, int, float]]) -> list[list[int]]:
    """The connected components of the correlated pairs, each sorted, in order of their first member."""
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i
    for i, j, _ in pairs:
        parent[root(i)] = root(j)
    groups: dict[int, list[int]] = {}
    for i, j, _ in pairs:
        for m in (i, j):
            groups.setdefault(root(m), [])
            if m not in groups[root(m)]:
                groups[root(m)].append(m)
    return sorted((sorted(g) for g in groups.values()), key=lambda g: g[0])
