"""pass_token (API 1.11): inside one pass of fusionkit's GraphEvaluator the token is the same for the Values object
it evaluates and None for any other object or outside a pass; a vectorized residual of more than three variables (a
serial-arm entry) is evaluated once per pass without a factor comparing its variables, and linearizes to the same
numbers as GTSAM calling each factor alone."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np

from fusionkit.api import pass_token
from fusionkit.config.loader import load_config
from fusionkit.graph.passes import evaluation_pass
from fusionkit.pipeline import build_problem, read_sources

CONFIG = Path(__file__).parents[2] / "configs" / "arm_calibration.yaml"


def test_the_token_belongs_to_the_evaluated_values_object_and_its_pass_only():
    values, other = gtsam.Values(), gtsam.Values()
    assert pass_token(values) is None
    with evaluation_pass(values):
        token = pass_token(values)
        assert token is not None and pass_token(values) is token and pass_token(other) is None
        with evaluation_pass(other):
            assert pass_token(other) is not None and pass_token(values) is None
        assert pass_token(values) is token
    assert pass_token(values) is None
    with evaluation_pass(values):
        assert pass_token(values) is not token  # a new pass, a new token


def test_an_arm_entry_is_evaluated_once_per_pass_and_linearizes_as_gtsam_does(monkeypatch):
    """30 configurations of configs/arm_calibration.yaml at perturbed values: fusionkit's pass evaluates the marker
    entry (one vectorized residual of 15 variables per factor) once and no factor compares its variables; the
    linear system and the cost equal GTSAM's, which calls every factor on a copy of the values."""
    from fusionkit.graph.vectorized import InstanceCache
    config = load_config(CONFIG, ["sources.0.params.configurations=30"])
    streams, _ = read_sources(config)
    problem = build_problem(config, streams)
    rng = np.random.default_rng(0)
    zero, step = problem.initial.zeroVectors(), gtsam.VectorValues()
    for key in problem.initial.keys():
        step.insert(key, rng.normal(0.0, 1e-3, zero.at(key).shape))
    values = problem.initial.retract(step)
    entry = next(r.factor for r in problem.records if r.factor.size() > 10)  # a marker factor
    counts = {"evaluations": 0, "compared": 0}
    evaluate_all, holds = InstanceCache._evaluate_all, InstanceCache._holds
    monkeypatch.setattr(InstanceCache, "_evaluate_all", lambda self, *a: (
        counts.__setitem__("evaluations", counts["evaluations"] + 1), evaluate_all(self, *a))[1])
    monkeypatch.setattr(InstanceCache, "_holds", lambda self, *a: (
        counts.__setitem__("compared", counts["compared"] + 1), holds(self, *a))[1])
    ours = problem.evaluator().linearize(values)
    assert counts == {"evaluations": 1, "compared": 0} and entry.size() == 15
    copy = gtsam.Values(values)
    theirs = problem.graph().linearize(copy)
    assert counts["compared"] >= 30
    a, b = ours.jacobian(), theirs.jacobian()
    assert np.abs(np.sort(np.abs(a[0]).ravel()) - np.sort(np.abs(b[0]).ravel())).max() < 1e-9
    assert abs(problem.evaluator().error(values) - problem.graph().error(copy)) < 1e-9 * problem.graph().error(copy)


def test_a_vectorized_residual_over_four_variables_is_evaluated_once_per_pass(monkeypatch):
    """A VectorizedResidual of more than three variables is linearized factor by factor (GTSAM's Python bindings
    build Jacobian factors of at most three blocks): inside an evaluation pass its N = 20 instances are evaluated
    in one call, outside one it serves them from the values it read (one call per new values), and both linear
    systems equal."""
    from fusionkit.api import SCALAR, VectorizedResidual
    from fusionkit.graph.vectorized import InstanceCache
    calls = {"n": 0}

    def weighted_sum(x, data, jacobians):  # e = sum_j w_j x_j - z
        calls["n"] += 1
        e = sum(data["w"][:, j] * x[j] for j in range(4))[:, None] - data["z"][:, None]
        return (e, [data["w"][:, j, None, None] * np.ones((len(e), 1, 1)) for j in range(4)]) if jacobians else e
    residual = VectorizedResidual("test.sum4", (SCALAR,) * 4, 1, weighted_sum)
    rng = np.random.default_rng(1)
    keys = np.array([rng.choice(8, 4, replace=False) for _ in range(20)])
    cache = InstanceCache(residual, keys, {"w": rng.normal(size=(20, 4)), "z": rng.normal(size=20)})
    graph = gtsam.NonlinearFactorGraph()
    for i in range(20):
        graph.add(cache.factor(i, gtsam.noiseModel.Isotropic.Sigma(1, 0.1)))
    values = gtsam.Values()
    for k in range(8):
        values.insert(k, float(rng.normal()))
    compared = {"n": 0}  # factors that read their variables to compare them with the kept ones
    holds = InstanceCache._holds
    monkeypatch.setattr(InstanceCache, "_holds", lambda self, *a: (compared.__setitem__("n", compared["n"] + 1),
                                                                  holds(self, *a))[1])
    with evaluation_pass(values):
        inside = graph.linearize(values)
        assert calls["n"] == 1 and compared["n"] == 0
    outside = graph.linearize(gtsam.Values(values))  # the same numbers in another object: served from the pass's
    assert calls["n"] == 1 and compared["n"] >= 20
    moved = gtsam.Values(values)
    moved.update(0, 5.0)
    graph.linearize(moved)  # new values outside a pass: one call for all that hold them
    assert calls["n"] == 2
    assert np.allclose(inside.jacobian()[0], outside.jacobian()[0]) and np.allclose(inside.jacobian()[1],
                                                                                    outside.jacobian()[1])
