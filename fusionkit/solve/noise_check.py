"""Whether the sigmas agree with the scatter of the residuals, from the data alone.

At a least-squares estimate the chi-square (sum of squared whitened residuals) follows a chi-square
distribution with dof = rows - unknowns when the sigmas are right. Beyond its 1 - P quantile the residuals
scatter more than the sigmas say (`noise_understated`: the reported sigmas are too small, or the model misses
an effect); below its P quantile they scatter less (`noise_overstated`: the reported sigmas are too large).
With many degrees of freedom a few percent is beyond chance; the warning also needs chi2/dof beyond
VARIANCE_FACTOR or below its inverse (sigmas off by more than 41 %), what changes a reported sigma's meaning.
Either names the entries responsible by their own variance factor, chi-square / redundancy (noise_scales.py:
E[chi2_g] = r_g for an entry g with the right sigmas), those beyond chance on their own redundancy first.
A chi-square beyond solver.max_cost_ratio per dof is the gate's rejection, not a warning; the fixed-lag
smoother's estimate is no least-squares estimate of the whole graph (health.py judges it by windows); with a
robust loss on any factor the cost is no chi-square (a Cauchy loss with the right sigmas gives about 0.3 per
row): not judged."""

from __future__ import annotations

import gtsam
import numpy as np

from ..graph.builder import Problem
from .health import WINDOW_P as P  # the chi-square's tail probability beyond which the sigmas are judged wrong
from .noise_scales import EntryFit, redundancies
from .result import SolveWarning
from .chi_square import quantile

VARIANCE_FACTOR = 2.0  # chi2/dof beyond it or below its inverse (and beyond chance) is judged
MIN_REDUNDANCY = 0.5  # an entry with less redundancy (a prior the data barely test) is not named
NAMED = 3  # entries named at most


def noise_check(problem: Problem, values: gtsam.Values, chi2_total: float, dof: int,
                settings: dict) -> list[SolveWarning]:
    """A `noise_understated` or `noise_overstated` warning when the chi-square at the estimate `values` is
    beyond its 1 - P or below its P quantile for `dof`, and chi2/dof beyond VARIANCE_FACTOR or below its
    inverse; none when the sigmas are scaled a posteriori
    (`solver.a_posteriori_sigmas`) or the gate rejects the fit."""
    if dof <= 0 or settings["a_posteriori_sigmas"] or settings["type"] == "fixed_lag":
        return []
    per_dof = chi2_total / dof
    low, high = quantile(P, dof), quantile(1 - P, dof)
    if low <= chi2_total <= high or per_dof > settings["max_cost_ratio"]:
        return []
    if 1 / VARIANCE_FACTOR <= per_dof <= VARIANCE_FACTOR or _robust(problem):  # the scan of every factor last
        return []
    over = bool(chi2_total > high)
    times = np.sqrt(per_dof) if over else 1 / np.sqrt(max(per_dof, 1e-300))
    beyond = f"{'above' if over else 'below'} its {'1 - ' if over else ''}{P:g} quantile for {dof} degrees of freedom"
    scatter = (f"the residuals scatter about {times:.3g} times {'more' if over else 'less'} than the sigmas say, so "
               f"the reported sigmas are that much too {'small' if over else 'large'}"
               + (" (or the model misses an effect)" if over else ""))
    text = (f"chi-square per degree of freedom {per_dof:.3g} is far {'above' if over else 'below'} 1 ({beyond}): "
            f"{scatter}; where it shows, chi-square per redundancy by entry (about 1 expected; an entry's residuals also "
            f"carry the misfit of what it is measured against): "
            f"{_entries_text(problem, values, settings, over)}; check those sigmas, or set "
            "solver.a_posteriori_sigmas: true")
    return [SolveWarning("noise_understated" if over else "noise_overstated", text)]


def _entries_text(problem: Problem, values: gtsam.Values, settings: dict, over: bool) -> str:
    """The entries that pull the chi-square the way it went, most extreme first: those beyond chance on their
    own redundancy, else the most extreme one."""
    fits = {label: fit for label, fit in redundancies(problem, values, None, settings).items()
            if fit.redundancy >= MIN_REDUNDANCY}
    if not fits:
        return "no entry has redundancy to judge"
    ranked = sorted(fits.items(), key=lambda item: item[1].variance_factor, reverse=over)
    beyond = [(label, fit) for label, fit in ranked if _beyond(fit, over)]
    shown = beyond[:NAMED] or ranked[:1]
    more = f", and {len(beyond) - NAMED} more" if len(beyond) > NAMED else ""
    return ", ".join(f"{label} {fit.variance_factor:.3g} (redundancy {fit.redundancy:.3g} of {fit.rows} rows)"
                     for label, fit in shown) + more


def _robust(problem: Problem) -> bool:
    """Whether a factor has a robust loss: its cost (capped for outliers) is then no chi-square."""
    return any(isinstance(r.factor.noiseModel(), gtsam.noiseModel.Robust) for r in problem.records
               if hasattr(r.factor, "noiseModel"))


def _beyond(fit: EntryFit, over: bool) -> bool:
    return fit.chi2 > quantile(1 - P, fit.redundancy) if over else fit.chi2 < quantile(P, fit.redundancy)
