"""How the batch solvers solve each linear system: the factorization and the elimination ordering.

Cholesky factors A^T A, whose condition number is the square of A's: a whitened Jacobian with
condition 1e8 (heavy sagging cables: the equilibrium orientation moves the catenaries by metres
per milliradian, while pulleys are seen through a few poses) is already singular to it. QR
factors A itself (GTSAM's EliminateQR; `solver.factorization: qr`).

GTSAM orders the elimination by COLAMD. Where a few variables touch nearly every factor (UWB
anchors and time-varying biases along a 10,000-epoch trajectory) METIS's nested dissection
eliminates 9 times faster (0.21 s vs 1.9 s measured); `solver.ordering: metis`.
"""

from __future__ import annotations

import gtsam


def linear_settings(settings: dict) -> tuple[bool, str]:
    """(qr, ordering) of a batch solver's resolved settings: `factorization` and `ordering`."""
    return settings["factorization"] == "qr", settings["ordering"]


def elimination_order(linear: gtsam.GaussianFactorGraph, ordering: str = "colamd") -> gtsam.Ordering:
    """COLAMD's or METIS's elimination order of `linear`'s variables (what GTSAM computes by default)."""
    return (gtsam.Ordering.MetisGaussianFactorGraph(linear) if ordering == "metis"
            else gtsam.Ordering.ColamdGaussianFactorGraph(linear))


def eliminate(linear: gtsam.GaussianFactorGraph, qr: bool, ordering: str | gtsam.Ordering = "colamd"):
    """The multifrontal Bayes tree of `linear` by QR or Cholesky, in `ordering`: "colamd", "metis", or an
    order already computed (an iterative solver's systems share one structure, so one order serves all)."""
    order = elimination_order(linear, ordering) if isinstance(ordering, str) else ordering
    return linear.eliminateMultifrontal(order, gtsam.EliminateQR) if qr else linear.eliminateMultifrontal(order)
