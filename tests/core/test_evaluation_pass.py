"""pass_token (API 1.11): inside one pass of fusionkit's GraphEvaluator the token is the same for the Values object
it evaluates and None for any other object or outside a pass; a serial-arm entry served by it reads each variable
once per pass instead of once per factor, and linearizes to the same numbers as GTSAM calling each factor alone."""

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


def test_an_arm_entry_reads_each_variable_once_per_pass_and_linearizes_as_gtsam_does(monkeypatch):
    """30 configurations of configs/arm_calibration.yaml at perturbed values: fusionkit's pass reads each of the
    entry's 44 variables once (without the token: each of 30 factors reads its 15, 450 reads); the linear
    system and the cost equal GTSAM's, which calls every factor on a copy of the values."""
    from fusionkit_plugins.serial_arm import evaluator
    reads = {"n": 0}
    for name in ("_read_pose3", "_read_point3", "_read_scalar", "_read_vector"):
        original = getattr(evaluator, name)
        monkeypatch.setattr(evaluator, name, lambda v, k, f=original: (reads.__setitem__("n", reads["n"] + 1), f(v, k))[1])
    config = load_config(CONFIG, ["sources.0.params.configurations=30"])
    streams, _ = read_sources(config)
    problem = build_problem(config, streams)
    rng = np.random.default_rng(0)
    zero, step = problem.initial.zeroVectors(), gtsam.VectorValues()
    for key in problem.initial.keys():
        step.insert(key, rng.normal(0.0, 1e-3, zero.at(key).shape))
    values = problem.initial.retract(step)
    entry = next(r.factor for r in problem.records if r.factor.size() > 10)  # a marker factor
    unique = len({k for r in problem.records if r.factor.size() > 10 for k in r.factor.keys()})
    reads["n"] = 0
    ours = problem.evaluator().linearize(values)
    assert reads["n"] == unique == 44 and entry.size() == 15
    copy = gtsam.Values(values)
    reads["n"] = 0
    theirs = problem.graph().linearize(copy)
    assert reads["n"] > 10 * unique
    a, b = ours.jacobian(), theirs.jacobian()
    assert np.abs(np.sort(np.abs(a[0]).ravel()) - np.sort(np.abs(b[0]).ravel())).max() < 1e-9
    assert abs(problem.evaluator().error(values) - problem.graph().error(copy)) < 1e-9 * problem.graph().error(copy)
