"""Chi-square quantiles and tail probabilities, from scipy.special (scipy.stats costs a second of import
time on every command for the same two functions)."""

from __future__ import annotations

from scipy.special import chdtrc, chdtri


def quantile(p, dof):
    """The chi-square quantile: x with P(X <= x) = p for `dof` degrees of freedom (scipy.stats.chi2.ppf)."""
    return chdtri(dof, 1.0 - p)


def survival(x, dof):
    """P(X > x) for `dof` degrees of freedom (scipy.stats.chi2.sf)."""
    return chdtrc(dof, x)
