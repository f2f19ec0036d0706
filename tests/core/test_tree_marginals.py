"""tree_marginals (one elimination, one top-down pass through the Bayes tree) against
gtsam.Marginals on the two shapes it meets: many states hanging on the same parameters, and a chain."""

import gtsam
import numpy as np

from fusionkit.solve.covariance_recovery import tree_marginals


def _star_graph(rng, n_states=40):
    """Vector states each tied by a between-like factor to two shared parameters (an arm's joints and
    its kinematic parameters)."""
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    P, Q = 10_000, 10_001
    values.insert(P, gtsam.Pose3(gtsam.Rot3.Rodrigues(*rng.normal(size=3) * 0.3), rng.normal(size=3)))
    values.insert(Q, gtsam.Point3(*rng.normal(size=3)))
    graph.add(gtsam.PriorFactorPose3(P, values.atPose3(P), gtsam.noiseModel.Isotropic.Sigma(6, 0.5)))
    graph.add(gtsam.PriorFactorPoint3(Q, values.atPoint3(Q), gtsam.noiseModel.Isotropic.Sigma(3, 0.5)))
    for k in range(n_states):
        pose = gtsam.Pose3(gtsam.Rot3.Rodrigues(*rng.normal(size=3)), rng.normal(size=3))
        values.insert(k, pose)
        graph.add(gtsam.BetweenFactorPose3(P, k, values.atPose3(P).between(pose),
                                           gtsam.noiseModel.Diagonal.Sigmas(rng.uniform(0.01, 0.1, 6))))
        graph.add(gtsam.BearingRangeFactor3D(k, Q, pose.bearing(values.atPoint3(Q)), pose.range(values.atPoint3(Q)),
                                             gtsam.noiseModel.Isotropic.Sigma(3, 0.05)))
    return graph, values


def _chain_graph(rng, n_states=30):
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    pose = gtsam.Pose2()
    values.insert(0, pose)
    graph.add(gtsam.PriorFactorPose2(0, pose, gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
    for k in range(1, n_states):
        step = gtsam.Pose2(1.0, rng.normal(scale=0.1), rng.normal(scale=0.1))
        pose = pose.compose(step)
        values.insert(k, pose)
        graph.add(gtsam.BetweenFactorPose2(k - 1, k, step, gtsam.noiseModel.Diagonal.Sigmas([0.05, 0.05, 0.02])))
    return graph, values


def test_tree_marginals_equal_gtsam_marginals_on_shared_parameters_and_on_a_chain():
    rng = np.random.default_rng(3)
    for graph, values in (_star_graph(rng), _chain_graph(rng)):
        keys = set(values.keys())
        ours = tree_marginals(graph, values, keys)
        reference = gtsam.Marginals(graph, values)
        assert set(ours) == keys
        for k in keys:
            expected = reference.marginalCovariance(k)
            np.testing.assert_allclose(ours[k], expected, rtol=1e-7, atol=1e-12 * np.abs(expected).max())


def test_tree_marginals_of_a_subset_hold_only_the_asked_keys():
    graph, values = _star_graph(np.random.default_rng(4), n_states=10)
    ours = tree_marginals(graph, values, {2, 5, 10_000})
    assert set(ours) == {2, 5, 10_000}
    np.testing.assert_allclose(ours[5], gtsam.Marginals(graph, values).marginalCovariance(5), rtol=1e-7)


def test_recovered_qr_marginals_equal_gtsam_marginals_with_either_ordering():
    """The sparse QR path (solver.factorization: qr): top-down recovery through the Bayes tree, on both
    shapes and with COLAMD and METIS orderings, against gtsam.Marginals (these graphs are well conditioned;
    measured: 2.7e-12 relative)."""
    from fusionkit.solve.covariance_recovery import recovered_marginals
    rng = np.random.default_rng(5)
    for graph, values in (_star_graph(rng), _chain_graph(rng)):
        keys = set(values.keys())
        reference = gtsam.Marginals(graph, values)
        for ordering in ("colamd", "metis"):
            ours = recovered_marginals(graph, values, keys, ordering)
            assert set(ours) == keys
            for k in keys:
                expected = reference.marginalCovariance(k)
                np.testing.assert_allclose(ours[k], expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
