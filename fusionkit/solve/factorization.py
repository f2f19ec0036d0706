"""How the batch solvers solve each linear system: the factorization and the elimination ordering.

Cholesky factors A^T A, whose condition number is the square of A's: a whitened Jacobian with
condition 1e8 (heavy sagging cables: the equilibrium orientation moves the catenaries by metres
per milliradian, while pulleys are seen through a few poses) is already singular to it. QR
factors A itself (GTSAM's EliminateQR; `solver.factorization: qr`).

GTSAM orders the elimination by COLAMD. Where a few variables touch nearly every factor (UWB
anchors and time-varying biases along a 10,000-epoch trajectory, a VO scale, a robot's calibration)
COLAMD's own cost and the elimination in its order grow faster than the graph, and METIS's nested
dissection is faster: 9x on the UWB graph (0.21 s vs 1.9 s), and on a scaled-VO chain per state
order + elimination 8.8 vs 6.1 us at 3,000 states, 19 vs 8.9 us at 10,000, 143 vs 10 us at 100,000
(research/linear_assembly.py's graph). On a chain without such a variable COLAMD is faster
(4.0 vs 6.9 us per state at 10,000). `solver.ordering: auto` (default) takes METIS when some variable
is in more than METIS_DEGREE factors, else COLAMD.
"""

from __future__ import annotations

import gtsam


METIS_DEGREE = 2000  # factors on one variable from which METIS orders faster (crossover measured 1,000-3,000)


def linear_settings(settings: dict) -> tuple[bool, str]:
    """(qr, ordering) of a batch solver's resolved settings: `factorization` and `ordering` (colamd or
    metis; `auto` is resolved by `resolved_ordering` before)."""
    return settings["factorization"] == "qr", settings["ordering"]


def resolved_ordering(ordering: str, largest_degree: int) -> str:
    """`auto` -> metis when a variable is in more than METIS_DEGREE factors, else colamd; others as given."""
    if ordering != "auto":
        return ordering
    return "metis" if largest_degree > METIS_DEGREE else "colamd"


def elimination_order(linear: gtsam.GaussianFactorGraph, ordering: str = "colamd") -> gtsam.Ordering:
    """COLAMD's or METIS's elimination order of `linear`'s variables (what GTSAM computes by default)."""
    return (gtsam.Ordering.MetisGaussianFactorGraph(linear) if ordering == "metis"
            else gtsam.Ordering.ColamdGaussianFactorGraph(linear))


def eliminate(linear: gtsam.GaussianFactorGraph, qr: bool, ordering: str | gtsam.Ordering = "colamd"):
    """The multifrontal Bayes tree of `linear` by QR or Cholesky, in `ordering`: "colamd", "metis", or an
    order already computed (an iterative solver's systems share one structure, so one order serves all)."""
    order = elimination_order(linear, ordering) if isinstance(ordering, str) else ordering
    return linear.eliminateMultifrontal(order, gtsam.EliminateQR) if qr else linear.eliminateMultifrontal(order)
