"""Vectorized factors (fusionkit/graph/vectorized.py): a group's one-call linearization and errors equal
those of its instances as gtsam.CustomFactors (and so of the same factors in any GTSAM solver), for every
robust kernel; numerical Jacobians equal the analytic ones on each variable type; the evaluator gives the
graph's cost, and fusionkit's LM the same solution through it; the vectorized SO(3) log is exact to pi."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.api import POINT3, POSE2, POSE3, ROT3, SCALAR, VectorizedResidual, lie
from fusionkit.graph.builder import FactorRecord
from fusionkit.graph.evaluator import GraphEvaluator
from fusionkit.graph.noise import KERNELS
from fusionkit.graph.vectorized import InstanceCache, ValueReader, VectorizedGroup, instance_factor
from fusionkit.solve.levenberg import DampingSettings, levenberg_marquardt
from fusionkit_plugins.pose.residuals import SCALED_BETWEEN

N = 40
SCALE_KEY = 1000


def _chain(rng):
    """N+1 random poses, a scale, N noisy scaled relative measurements and per-instance sigmas."""
    values = gtsam.Values()
    poses = [gtsam.Pose3.Expmap(rng.normal(size=6)) for _ in range(N + 1)]
    for i, p in enumerate(poses):
        values.insert(i, p)
    values.insert(SCALE_KEY, 1.7)
    measured = []
    for a, b in zip(poses, poses[1:]):
        d = a.between(b).compose(gtsam.Pose3.Expmap(0.05 * rng.normal(size=6)))
        measured.append(gtsam.Pose3(d.rotation(), d.translation() / 1.5).matrix())
    keys = np.column_stack([np.arange(N), np.arange(1, N + 1), np.full(N, SCALE_KEY)])
    sigmas = rng.uniform(0.01, 0.1, size=(N, 6))
    return values, keys, {"measured": np.array(measured)}, sigmas


def _instances(residual, keys, data, sigmas, kernel):
    out = []
    for i in range(len(keys)):
        noise = gtsam.noiseModel.Diagonal.Sigmas(sigmas[i])
        if kernel is not None:
            noise = gtsam.noiseModel.Robust.Create(kernel, noise)
        out.append(instance_factor(residual, noise, keys[i], {k: v[i:i + 1] for k, v in data.items()}))
    return out


@pytest.mark.parametrize("kernel_name", [None, "huber", "cauchy"])
def test_group_linear_factors_equal_each_instance_linearized_by_gtsam(kernel_name):
    values, keys, data, sigmas = _chain(np.random.default_rng(0))
    kernel = None if kernel_name is None else KERNELS[kernel_name][0].Create(0.5)
    group = VectorizedGroup(SCALED_BETWEEN, keys, data, sigmas, kernel)
    ours = group.linear_factors(ValueReader(values))
    theirs = [f.linearize(values) for f in _instances(SCALED_BETWEEN, keys, data, sigmas, kernel)]
    worst = max(np.abs(a.augmentedJacobian() - b.augmentedJacobian()).max() for a, b in zip(ours, theirs))
    assert worst < 1e-10


@pytest.mark.parametrize("kernel_name", [None, *KERNELS])
def test_group_errors_equal_gtsam_factor_errors_for_every_kernel(kernel_name):
    values, keys, data, sigmas = _chain(np.random.default_rng(1))
    kernel = None if kernel_name is None else KERNELS[kernel_name][0].Create(KERNELS[kernel_name][1])
    group = VectorizedGroup(SCALED_BETWEEN, keys, data, sigmas, kernel)
    expected = [f.error(values) for f in _instances(SCALED_BETWEEN, keys, data, sigmas, kernel)]
    np.testing.assert_allclose(group.errors(ValueReader(values)), expected, rtol=1e-12, atol=1e-15)


def _mixed(x, data, jacobians):
    """r = [p_xy of a pose2 + R v + point + 2 s] (3 rows): one variable of each kind."""
    pose2, rot, point, s = x
    xy = np.concatenate([pose2[:, :2], pose2[:, 2:3]], axis=1)
    r = xy + np.einsum("nij,j->ni", rot, data["v"][0]) + point + 2 * s[:, None]
    if not jacobians:
        return r
    c, si = np.cos(pose2[:, 2]), np.sin(pose2[:, 2])
    d_pose2 = np.zeros((len(r), 3, 3))
    d_pose2[:, 0, :2] = np.column_stack([c, -si])
    d_pose2[:, 1, :2] = np.column_stack([si, c])
    d_pose2[:, 2, 2] = 1.0
    d_rot = -rot @ lie.skew(np.broadcast_to(data["v"][0], (len(r), 3)))
    return r, [d_pose2, d_rot, np.broadcast_to(np.eye(3), (len(r), 3, 3)), np.full((len(r), 3, 1), 2.0)]


def test_numerical_jacobians_equal_analytic_on_pose2_rot3_point3_scalar_and_pose3():
    rng = np.random.default_rng(2)
    n = 25
    x = [np.column_stack([rng.normal(size=(n, 2)), rng.uniform(-3, 3, n)]),
         lie.exp(np.concatenate([rng.normal(size=(n, 3)), np.zeros((n, 3))], axis=1))[:, :3, :3],
         rng.normal(size=(n, 3)), rng.uniform(0.5, 2, n)]
    data = {"v": np.tile([0.3, -1.2, 0.7], (n, 1))}
    variables = (POSE2, ROT3, POINT3, SCALAR)
    analytic = VectorizedResidual("mixed", variables, 3, _mixed)
    numerical = VectorizedResidual("mixed", variables, 3, _mixed, jacobians="numerical")
    _, ja = analytic.evaluate(x, data, True)
    _, jn = numerical.evaluate(x, data, True)
    for a, b in zip(ja, jn):
        np.testing.assert_allclose(b, a, atol=1e-7)
    values, keys, data3, _ = _chain(rng)
    x3 = ValueReader(values).variables((POSE3, POSE3, SCALAR), keys)
    _, ja = SCALED_BETWEEN.evaluate(x3, data3, True)
    numeric = VectorizedResidual("scaled", SCALED_BETWEEN.variables, 6, SCALED_BETWEEN.function, "numerical")
    _, jn = numeric.evaluate(x3, data3, True)
    for a, b in zip(ja, jn):
        np.testing.assert_allclose(b, a, atol=2e-6)


def test_evaluator_cost_and_lm_solution_equal_those_of_the_plain_graph():
    values, keys, data, sigmas = _chain(np.random.default_rng(3))
    group = VectorizedGroup(SCALED_BETWEEN, keys, data, sigmas, None)
    records = [FactorRecord(f, "vo", float(i), group, i)
               for i, f in enumerate(_instances(SCALED_BETWEEN, keys, data, sigmas, None))]
    records.append(FactorRecord(gtsam.PriorFactorPose3(0, values.atPose3(0), gtsam.noiseModel.Isotropic.Sigma(6, 1e-3)),
                                "origin", -np.inf))
    records.append(FactorRecord(gtsam.PriorFactorDouble(SCALE_KEY, 1.5, gtsam.noiseModel.Isotropic.Sigma(1, 0.1)),
                                "scale", -np.inf))
    graph = gtsam.NonlinearFactorGraph()
    for r in records:
        graph.add(r.factor)
    evaluator = GraphEvaluator(records)
    assert len(evaluator.groups) == 1 and evaluator.plain.size() == 2
    assert evaluator.error(values) == pytest.approx(graph.error(values), rel=1e-12)
    np.testing.assert_allclose(evaluator.record_errors(values), [r.factor.error(values) for r in records], rtol=1e-12)
    fast, fast_history = levenberg_marquardt(evaluator, values, 1e-9, 1e-12, 50, DampingSettings())
    slow, slow_history = levenberg_marquardt(graph, values, 1e-9, 1e-12, 50, DampingSettings())
    assert len(fast_history) == len(slow_history) > 3
    np.testing.assert_allclose(fast_history, slow_history, rtol=1e-9, atol=1e-12)
    assert abs(fast.atDouble(SCALE_KEY) - slow.atDouble(SCALE_KEY)) < 1e-9
    assert fast.atPose3(N).equals(slow.atPose3(N), 1e-9)


def test_rotation_log_is_gtsams_logmap_up_to_pi():
    rng = np.random.default_rng(4)
    axes = rng.normal(size=(3000, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    angles = np.concatenate([rng.uniform(0, np.pi, 2000), np.pi - 10 ** rng.uniform(-12, -3, 500),
                             10 ** rng.uniform(-14, -4, 500)])
    R = np.array([gtsam.Rot3.Expmap(a * w).matrix() for a, w in zip(angles, axes)])
    ours = lie.rotation_log(R)
    back = np.array([gtsam.Rot3.Expmap(w).matrix() for w in ours])
    assert np.abs(back - R).max() < 1e-14
    assert np.linalg.norm(ours, axis=1).max() <= np.pi + 1e-15
    inside = angles < 3.0
    reference = np.array([gtsam.Rot3.Logmap(gtsam.Rot3(r)) for r in R[inside]])
    assert np.abs(ours[inside] - reference).max() < 1e-12


def test_instance_cache_serves_each_factor_at_the_values_it_is_called_with():
    """Factors made for GTSAM's own callers share one evaluation per set of values: at the start values, at
    moved values, and with values holding only one factor's variables (evaluated alone), each factor's
    linearization is that of a lone factor at the same values."""
    values, keys, data, sigmas = _chain(np.random.default_rng(6))
    noise = [gtsam.noiseModel.Diagonal.Sigmas(s) for s in sigmas]
    cache = InstanceCache(SCALED_BETWEEN, keys, data)
    shared = [cache.factor(i, noise[i]) for i in range(N)]
    alone = [instance_factor(SCALED_BETWEEN, noise[i], keys[i], {k: v[i:i + 1] for k, v in data.items()})
             for i in range(N)]
    step = gtsam.VectorValues()
    for k in values.keys():
        step.insert(k, 0.01 * np.ones(values.zeroVectors().at(k).shape[0]))
    for at in (values, values.retract(step), values):
        for a, b in zip(shared, alone):
            assert np.abs(a.linearize(at).augmentedJacobian() - b.linearize(at).augmentedJacobian()).max() < 1e-12
            assert a.error(at) == pytest.approx(b.error(at), rel=1e-12)
    few = gtsam.Values()
    for k in keys[3]:
        few.insert(int(k), values.atPose3(int(k)) if k != SCALE_KEY else values.atDouble(SCALE_KEY) + 0.2)
    assert np.abs(shared[3].linearize(few).augmentedJacobian()
                  - alone[3].linearize(few).augmentedJacobian()).max() < 1e-12


def test_a_residual_outside_its_domain_stops_the_solve_with_a_solver_error_naming_it():
    from fusionkit.errors import SolverError

    def outside(x, data, jacobians):
        raise ValueError("an attachment point lies inside a pulley's circle")
    residual = VectorizedResidual("test.domain", (POSE3, POSE3, SCALAR), 6, outside)
    values, keys, data, sigmas = _chain(np.random.default_rng(7))
    group = VectorizedGroup(residual, keys, data, sigmas, None)
    with pytest.raises(SolverError, match=r"^test\.domain: an attachment point lies inside a pulley's circle: "
                                          r"the estimate left the model's domain"):
        group.linear_factors(ValueReader(values))


def test_auto_ordering_takes_metis_when_a_variable_is_in_more_than_2000_factors():
    from fusionkit.solve.factorization import METIS_DEGREE, resolved_ordering
    values, keys, data, sigmas = _chain(np.random.default_rng(8))
    group = VectorizedGroup(SCALED_BETWEEN, keys, data, sigmas, None)
    records = [FactorRecord(None, "vo", 0.0, group, i) for i in range(N)]
    records.append(FactorRecord(gtsam.PriorFactorDouble(SCALE_KEY, 1.5, gtsam.noiseModel.Isotropic.Sigma(1, 0.1)),
                                "scale", -np.inf))
    assert GraphEvaluator(records).largest_degree() == N + 1  # the scale: every VO factor and its prior
    assert METIS_DEGREE == 2000
    assert resolved_ordering("auto", 2001) == "metis" and resolved_ordering("auto", 2000) == "colamd"
    assert resolved_ordering("colamd", 10**6) == "colamd" and resolved_ordering("metis", 1) == "metis"
