"""Whether the data agree with the robot description's priors, and whether they add anything to them.

A prior x ~ N(mu, P) on a parameter is a measurement like any other; at the estimate its whitened residual
e = P^-1/2 (x_hat - mu) has covariance Q = I - A S A^T (A = P^-1/2 in the parameter's tangent space, S its
posterior covariance). Each eigen-direction of Q with eigenvalue q is a direction in which the data carry the
share q of the information (1 - posterior variance / prior variance):

- **prior_conflict**: T = e^T Q^+ e over the directions the data inform (q >= DATA_SHARE) is chi-square with
  as many degrees of freedom when prior and data agree (Baarda's test of one observation, 1968). Beyond its
  1 - ALPHA / n quantile (n priors tested: Bonferroni, so ALPHA is the chance of any false alarm) the data
  put the parameter where its description says it cannot be: a unit, a sign or swapped columns in the data,
  or a wrong prior. A warning, not a rejection: the fit itself may be fine (the data absorbed the fault).
- **prior_only**: directions with q < DATA_SHARE: the data reduce the prior's variance by less than 1 % there;
  the reported value is the prior's, not a calibration.

Needs the posterior covariances (solver.marginals); parameters held (ctx.hold) or fixed are not judged.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from ..graph.builder import Problem
from .rank import index_ranges
from .result import SolveWarning
from .chi_square import quantile, survival

ALPHA = 1e-3  # the chance that any of the tested priors is flagged when all agree with the data
DATA_SHARE = 0.01  # a direction where the data carry less of the information is determined by the prior alone
PRIOR_LABEL = "prior:"


@dataclass
class PriorTest:
    """One prior at the estimate: its parameter, the test statistic over the informed directions, their number,
    and how many directions the prior alone determines."""

    factor: gtsam.NonlinearFactor
    key: int
    name: str
    statistic: float
    dof: int
    prior_only: int
    dim: int


def description_priors(problem: Problem) -> list[tuple[int, gtsam.NonlinearFactor]]:
    """(key, prior factor) of each robot description's prior on a parameter (builder label `prior:robot/name`)."""
    out = []
    for record in problem.records:
        keys = list(record.factor.keys())
        if record.label.startswith(PRIOR_LABEL) and len(keys) == 1:
            out.append((keys[0], record.factor))
    return out


def prior_tests(problem: Problem, values: gtsam.Values, covariances: dict[int, np.ndarray]) -> list[PriorTest]:
    """The test of each description prior on a parameter with a posterior covariance in `covariances`."""
    tests = []
    for key, factor in description_priors(problem):
        if key in problem.held or key in problem.fixed_keys or key not in covariances:
            continue
        A, b = factor.linearize(values).jacobian()  # whitened; b = -e
        q, u = np.linalg.eigh(np.eye(len(b)) - A @ covariances[key] @ A.T)
        informed = q >= DATA_SHARE
        statistic = float(np.sum((u[:, informed].T @ b) ** 2 / q[informed]))
        tests.append(PriorTest(factor, key, problem.keys.name_of(key), statistic, int(informed.sum()),
                               int((~informed).sum()), len(b)))
    return tests


def prior_check(problem: Problem, values: gtsam.Values, covariances: dict[int, np.ndarray]) -> list[SolveWarning]:
    """`prior_conflict` naming the parameters the data pull beyond chance from their priors, and `prior_only`
    naming those the data do not inform (module docstring); none when all is well."""
    tests = prior_tests(problem, values, covariances)
    judged = [t for t in tests if t.dof]
    warnings = []
    conflicts = [t for t in judged if t.statistic > quantile(1 - ALPHA / len(judged), t.dof)]
    if conflicts:
        conflicts.sort(key=lambda t: survival(t.statistic, t.dof))
        text = "; ".join(_conflict_text(problem, values, covariances, t) for t in conflicts)
        warnings.append(SolveWarning("prior_conflict", (
            f"the data pull {len(conflicts)} of {len(judged)} parameters beyond chance from their priors (beyond the "
            f"1 - {ALPHA:g}/{len(judged)} quantile): {text}; the data may carry a wrong unit, sign or column, or the "
            "prior is wrong")))
    alone = [t for t in tests if t.prior_only]
    if alone:
        partly = any(t.prior_only < t.dim for t in alone)
        warnings.append(SolveWarning("prior_only", (
            f"the data reduce the prior variance of {_members_text(problem, [t.key for t in alone])} by less than "
            f"{DATA_SHARE:.0%}{' (in some of their directions)' if partly else ''}: the values reported are their "
            "priors -- as meant for a surveyed or known value; one meant to be calibrated needs a recording that "
            "moves it, or a measurement of it")))
    return warnings


def _conflict_text(problem: Problem, values: gtsam.Values, covariances: dict[int, np.ndarray], t: PriorTest) -> str:
    vt = problem.keys.decode(t.key)[0].vartype
    if t.dim != 1:
        return f"{t.name} (chi-square {t.statistic:.3g} on {t.dof} directions)"
    value, sigma = float(np.ravel(vt.read(values, t.key))[0]), float(np.sqrt(covariances[t.key][0, 0]))
    mean, prior_sigma = float(np.ravel(t.factor.prior())[0]), float(t.factor.noiseModel().sigmas()[0])
    return (f"{t.name} = {value:.5g} ± {sigma:.2g}, {abs(value - mean) / prior_sigma:.3g} prior sigmas from its "
            f"prior {mean:.5g} ± {prior_sigma:.2g} ({np.sqrt(t.statistic):.3g} sigma of that difference, whose "
            "sigma is sqrt(prior^2 - posterior^2))")


def _members_text(problem: Problem, keys: list[int]) -> str:
    """`anchors/anchor[0..3]`, `robot/axle_length`, `arm/joint_offsets[elbow_joint, wrist_1_joint]`."""
    parts = []
    for family, members in problem.keys.group(keys):
        indices = [problem.keys.decode(k)[1] for k in members]
        if not family.indexed:
            parts.append(family.label())
        elif family.elements:
            parts.append(f"{family.label()}[{', '.join(family.elements[i] for i in indices)}]")
        else:
            parts.append(f"{family.label()}[{index_ranges(indices)}]")
    return ", ".join(parts)
