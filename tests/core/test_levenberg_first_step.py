"""The batch solver's first step reuses the linearization and elimination that check_constrained made at the
initial values: the iterates, costs and solution are bit for bit those of linearizing and eliminating again,
for Cholesky, QR and METIS, LM and Gauss-Newton."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.pipeline import build_problem, read_sources
from fusionkit.simulate import simulated_config
from fusionkit.solve.checks import check_constrained
from fusionkit.solve.levenberg import DampingSettings, levenberg_marquardt


@pytest.fixture(scope="module")
def problem():
    with simulated_config("arm.sim", {"configurations": 20}, seed=4) as config:
        streams, _ = read_sources(config)
        return build_problem(config, streams)


@pytest.mark.parametrize("qr, ordering, damping", [(False, "colamd", DampingSettings()), (True, "colamd", None),
                                                    (False, "metis", DampingSettings())])
def test_reusing_the_checks_elimination_changes_no_iterate(problem, qr, ordering, damping):
    graph = problem.evaluator()
    first = check_constrained(problem, problem.graph(), qr, ordering).first
    reused, history = levenberg_marquardt(graph, problem.initial, 1e-6, 1e-9, 100, damping, None, qr, ordering, first)
    again, history_again = levenberg_marquardt(graph, problem.initial, 1e-6, 1e-9, 100, damping, None, qr, ordering)
    assert history == history_again and len(history) > 2
    for key in problem.initial.keys():
        family, _ = problem.keys.decode(key)
        a, b = family.vartype.read(reused, key), family.vartype.read(again, key)
        a, b = (a.matrix(), b.matrix()) if hasattr(a, "matrix") else (a, b)
        assert np.array_equal(a, b), problem.keys.name_of(key)
