"""Vectorized factors in iSAM2 and the fixed-lag smoother (fusionkit/solve/linear_containers.py): no factor
is evaluated one at a time (no Python callback from GTSAM's C++), factors are linearized again when their
variables move past the threshold, and the estimates match those of the same factors handed to the
solvers as CustomFactors, and batch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fusionkit
from fusionkit.graph.variables import POSE3
from fusionkit.graph.vectorized import VectorizedGroup, VectorizedResidual
from fusionkit.solve import linear_containers

SCALED_VO = Path(__file__).resolve().parents[2] / "configs" / "scaled_vo_mocap.yaml"
SHORT = ["sources.0.params.duration=8"]
SOLVERS = {"isam2": ["solver={type: isam2}"], "fixed_lag": ["solver={type: fixed_lag, lag: 3.0}"],
           "fixed_lag_warmup": ["solver={type: fixed_lag, lag: 3.0, warmup: 2.0}"]}


def _pose_gap(a, b) -> float:
    states = a.problem.states["cam"]
    return max(float(np.abs(POSE3.local(a.solution.values.atPose3(states.key(k)),
                                        b.solution.values.atPose3(states.key(k)))).max())
               for k in range(len(states)))


@pytest.fixture(scope="module")
def runs():
    """Each incremental solver with containers (counting the residual's calls made outside a group: one
    factor at a time, as GTSAM calls a CustomFactor) and with the vectorized factors handed over one by
    one (the plain CustomFactor path), plus batch LM."""
    calls = {"group": 0, "alone": 0}
    inside = [False]
    evaluate, linear_factors, residuals = (VectorizedResidual.evaluate, VectorizedGroup.linear_factors,
                                           VectorizedGroup.residuals)

    def counted(self, x, data, jacobians):
        calls["group" if inside[0] else "alone"] += 1
        return evaluate(self, x, data, jacobians)

    def in_group(method):
        def wrapped(self, reader):
            inside[0] = True
            try:
                return method(self, reader)
            finally:
                inside[0] = False
        return wrapped

    out = {"lm": fusionkit.run(SCALED_VO, SHORT)}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(VectorizedResidual, "evaluate", counted)
        mp.setattr(VectorizedGroup, "linear_factors", in_group(linear_factors))
        mp.setattr(VectorizedGroup, "residuals", in_group(residuals))
        for name, extra in SOLVERS.items():
            calls.update(group=0, alone=0)
            out[name] = fusionkit.run(SCALED_VO, SHORT + extra + ["solver.marginals=false"])
            out[name + "_calls"] = dict(calls)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(linear_containers, "in_group", lambda record: False)
        for name, extra in SOLVERS.items():
            out[name + "_one_by_one"] = fusionkit.run(SCALED_VO, SHORT + extra + ["solver.marginals=false"])
    return out


@pytest.mark.parametrize("name", SOLVERS)
def test_incremental_solvers_never_evaluate_a_vectorized_factor_one_at_a_time(runs, name):
    calls = runs[name + "_calls"]
    assert sum(r.group is not None for r in runs[name].problem.records) > 100
    assert calls["alone"] == 0 and calls["group"] > 100


@pytest.mark.parametrize("name", SOLVERS)
def test_incremental_estimates_with_containers_match_the_one_by_one_factors(runs, name):
    gap = _pose_gap(runs[name], runs[name + "_one_by_one"])
    assert gap < (2e-3 if name == "isam2" else 5e-3), gap
    scale = lambda r: float(r.parameters["cam"]["vo_scale"].values[0])  # noqa: E731
    sigma = float(runs["lm"].parameters["cam"]["vo_scale"].sigma[0, 0])
    assert scale(runs[name]) == pytest.approx(scale(runs[name + "_one_by_one"]), abs=0.2 * sigma)


def test_isam2_with_containers_reaches_the_batch_solution(runs):
    assert _pose_gap(runs["lm"], runs["isam2"]) < 1e-3
    assert runs["isam2"].solution.final_error == pytest.approx(runs["lm"].solution.final_error, rel=1e-3)
