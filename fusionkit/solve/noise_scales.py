"""Variance-component estimation of factor entries' noise scales (`noise_scale: estimate`).

At a least-squares estimate, the whitened residuals v_g of an entry g (m_g rows in all) have
E[v_g^T v_g] = r_g, its redundancy: r_g = m_g - tr(A_g Sigma A_g^T), with A_g the entry's whitened Jacobian
rows and Sigma the posterior covariance of the variables (the redundancies of all factors add up to
rows - unknowns). If the entry's sigmas are off by a factor s, v_g^T v_g / r_g estimates s^2; each round
multiplies the sigmas by sqrt(v_g^T v_g / r_g) (stretched, see ScaleIteration) and solves again from the
last estimate, until every v_g^T v_g / r_g is within a tenth of its standard deviation sqrt(2 / r_g) of 1
(Foerstner 1979; Koch 1999, Parameter Estimation and Hypothesis Testing in Linear Models, sec. 3.6). The scale's standard deviation is s / sqrt(2 r_g) (chi-square with r_g degrees of
freedom). Each factor's share tr(A_f Sigma_f A_f^T) needs only the joint covariance of its own variables
(from one Bayes tree of the whole graph at the estimate).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from ..errors import DataError
from .covariance_recovery import clique_covariances, joint_covariance
from .factorization import eliminate, resolved_ordering

STOP = 0.1  # the rounds stop when every chi2 / redundancy is within STOP of its standard deviation of 1
MAX_ROUNDS = 20
REDUNDANCY_FLOOR = 1e-6  # rows' worth: an entry with less has no residual left to estimate its noise from


@dataclass
class EntryFit:
    """An entry's whitened chi-square (sum of squared whitened residuals), redundancy and row count."""

    chi2: float = 0.0
    redundancy: float = 0.0
    rows: int = 0

    @property
    def variance_factor(self) -> float:
        """chi2 / redundancy: the square of the factor its sigmas are off by."""
        return self.chi2 / self.redundancy


def entry_fits(problem, values: gtsam.Values, labels: set[str], solver: dict | None = None) -> dict[str, EntryFit]:
    """Chi-square and redundancy of the factors of each entry in `labels`, at `values` (an estimate), the
    Bayes tree eliminated as the `solver:` section asks (Cholesky or QR, ordering; default Cholesky, COLAMD).
    An entry with no redundancy has no scale to estimate: DataError."""
    fits = redundancies(problem, values, labels, solver)
    for label, fit in fits.items():
        if fit.redundancy <= REDUNDANCY_FLOOR:
            raise DataError(f"{label}: noise_scale: estimate: the entry's factors have redundancy "
                            f"{fit.redundancy:.3g} in {fit.rows} rows (the estimate absorbs them all): its noise cannot "
                            "be estimated from this data; give noise_scale a number")
    return fits


def redundancies(problem, values: gtsam.Values, labels: set[str] | None = None,
                 solver: dict | None = None) -> dict[str, EntryFit]:
    """Chi-square, redundancy and rows of each entry in `labels` at `values`, as `entry_fits` computes them,
    without judging them; `labels` None: every entry, a part with its own noise as `label [part]`."""
    evaluator = problem.evaluator()
    qr, ordering = (solver["factorization"] == "qr", resolved_ordering(solver["ordering"], evaluator.largest_degree())) \
        if solver else (False, "colamd")
    linear = evaluator.linearize(values)
    try:
        tree = eliminate(linear, qr, ordering)
    except RuntimeError:  # Cholesky on an ill-conditioned system (rank.py): QR, as the solve itself falls back to
        if qr:
            raise
        tree = eliminate(linear, True, ordering)
    clique_of, joint = clique_covariances(tree, values)
    of_record = dict(zip(evaluator.linear_order(), range(linear.size())))  # each record's linear factor
    errors = evaluator.record_errors(values)
    every = labels is None
    fits: dict[str, EntryFit] = {} if every else {label: EntryFit() for label in labels}
    for i, record in enumerate(problem.records):
        if every:
            fit = fits.setdefault(record.label if record.part is None else f"{record.label} [{record.part}]", EntryFit())
        elif record.part is not None:  # a part with the plugin's own noise is not scaled
            continue
        else:
            fit = fits.get(record.label)
        if fit is None:
            continue
        factor = linear.at(of_record[i])
        A = factor.jacobian()[0]  # whitened
        covariance = joint_covariance(clique_of, joint, list(factor.keys()))
        fit.chi2 += 2.0 * errors[i]
        fit.rows += A.shape[0]
        fit.redundancy += A.shape[0] - float(np.einsum("ij,jk,ik->", A, covariance, A))
    return fits


class ScaleIteration:
    """The rounds' scales. The plain update log s += 0.5 log(chi2 / r) converges linearly and slowly when an
    entry starts badly weighted (its redundancy then grows a little each round: 19 rounds measured for one
    three times too large a sigma); each entry's step is stretched by the secant of its last two rounds
    (1 to `MAX_STRETCH` times the plain step)."""

    MAX_STRETCH = 4.0

    def __init__(self, labels):
        self.scales = {label: 1.0 for label in labels}
        self.previous: dict[str, tuple[float, float]] = {}  # label -> (log scale, its plain step)
        self.done = False

    def update(self, fits: dict[str, EntryFit]) -> None:
        """The next round's scales from this round's fits; none when every entry fits (`done`)."""
        self.done = all(abs(fits[label].variance_factor - 1.0) <= STOP * np.sqrt(2.0 / fits[label].redundancy)
                        for label in self.scales)
        if self.done:
            return
        for label, scale in self.scales.items():
            x, step = float(np.log(scale)), 0.5 * float(np.log(fits[label].variance_factor))
            stretch = 1.0
            if label in self.previous:
                x0, step0 = self.previous[label]
                if x != x0 and step != step0:
                    slope = (step - step0) / (x - x0)  # d step / d log scale: in (-1, 0) while contracting
                    if slope < 0:
                        stretch = float(np.clip(-1.0 / slope, 1.0, self.MAX_STRETCH))
            self.previous[label] = (x, step)
            self.scales[label] = float(np.exp(x + stretch * step))


def scale_report(scales: dict[str, float], fits: dict[str, EntryFit], rounds: int) -> dict[str, dict]:
    """report.json's `noise_scales`: per entry, the scale its written sigmas were multiplied by, its standard
    deviation, the redundancy and rows it rests on, and the rounds taken."""
    return {label: {"scale": scale, "sigma": scale / float(np.sqrt(2.0 * fits[label].redundancy)),
                    "redundancy": fits[label].redundancy, "rows": fits[label].rows, "rounds": rounds}
            for label, scale in scales.items()}


def scale_text(fit: dict) -> str:
    """One entry of `scale_report` as the run summary and report.html show it."""
    return (f"{fit['scale']:.4g} ± {fit['sigma']:.2g} (estimated; redundancy {fit['redundancy']:.1f} of {fit['rows']} "
            f"rows, {fit['rounds']} rounds)")
