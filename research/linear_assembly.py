"""Issue 18's open question, measured: would assembling the linear system outside GTSAM's factor objects
beat fusionkit's current batch path on a graph of vectorized factors?

One Gauss-Newton step on a scaled-VO chain (N poses, a scale, `pose.scaled_relative` between consecutive
poses as one vectorized group, a native prior on the first pose and on the scale, native absolute poses
every 100 states), two ways, with the same step as the check:

- gtsam (fusionkit today): GraphEvaluator.linearize (native factors through GTSAM, the group as N
  JacobianFactors built from its arrays), GTSAM's multifrontal Cholesky in a COLAMD or a METIS order
  (computed once, as fusionkit's LM does; `ordering: auto` takes METIS above 2,000 factors on the scale),
  Values.retract;
- scipy: the group's whitened Jacobian written straight into sparse triplets, the native factors'
  through GaussianFactorGraph.sparseJacobian_, the normal equations solved by SuperLU (COLAMD), the step
  turned back into a VectorValues (one insert per variable) and retracted.

Not part of fusionkit: a measurement to decide on. Run: python research/linear_assembly.py
"""

from __future__ import annotations

import time

import gtsam
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from fusionkit.graph.builder import FactorRecord
from fusionkit.graph.evaluator import GraphEvaluator
from fusionkit.graph.vectorized import ValueReader, VectorizedGroup
from fusionkit.solve.factorization import elimination_order
from fusionkit_plugins.pose.residuals import SCALED_BETWEEN

SCALE = 10**9
SIGMAS = np.array([0.002] * 3 + [0.004] * 3)


def problem(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    truth = [gtsam.Pose3()]
    for _ in range(n - 1):
        truth.append(truth[-1].compose(gtsam.Pose3.Expmap(np.r_[rng.normal(size=3) * 0.02, 0.1, 0, 0])))
    values = gtsam.Values()
    for i, p in enumerate(truth):
        values.insert(i, p.compose(gtsam.Pose3.Expmap(rng.normal(size=6) * 0.01)))
    values.insert(SCALE, 2.3)
    measured = np.array([(lambda d: gtsam.Pose3(d.rotation(), d.translation() / 2.5).matrix())(a.between(b))
                         for a, b in zip(truth, truth[1:])])
    keys = np.column_stack([np.arange(n - 1), np.arange(1, n), np.full(n - 1, SCALE)])
    group = VectorizedGroup(SCALED_BETWEEN, keys, {"measured": measured}, np.tile(SIGMAS, (n - 1, 1)), None)
    native = gtsam.NonlinearFactorGraph()
    native.add(gtsam.PriorFactorPose3(0, truth[0], gtsam.noiseModel.Isotropic.Sigma(6, 1e-3)))
    native.add(gtsam.PriorFactorDouble(SCALE, 2.5, gtsam.noiseModel.Isotropic.Sigma(1, 0.5)))
    for i in range(0, n, 100):
        native.add(gtsam.PriorFactorPose3(i, truth[i], gtsam.noiseModel.Isotropic.Sigma(6, 0.01)))
    return values, group, native


def gtsam_step(values, evaluator, order, ordering="colamd"):
    linear = evaluator.linearize(values)
    order = order or elimination_order(linear, ordering)
    return values.retract(linear.eliminateMultifrontal(order).optimize()), order


def scipy_step(values, group, native, layout):
    keys, offsets, dims, total = layout
    reader = ValueReader(values)
    x = reader.variables(SCALED_BETWEEN.variables, group.keys)
    r, jac = SCALED_BETWEEN.evaluate(x, group.data, True)
    n, m = r.shape
    rows, cols, vals, rhs = [], [], [], [-(r / group.sigmas).ravel()]
    row_index = np.arange(n * m).reshape(n, m)
    for j, J in enumerate(jac):
        start = offsets[np.searchsorted(keys, group.keys[:, j])]
        d = J.shape[2]
        rows.append(np.broadcast_to(row_index[:, :, None], (n, m, d)).ravel())
        cols.append((start[:, None, None] + np.arange(d)[None, None, :]).repeat(m, axis=1).ravel())
        vals.append((J / group.sigmas[:, :, None]).ravel())
    linear = native.linearize(values)
    nr, nc, nv = linear.sparseJacobian_()  # columns: the native graph's own variables, in key order
    nr, nc = nr.astype(int) - 1, nc.astype(int) - 1
    own = np.array(sorted(linear.keys()), dtype=np.int64)
    own_dims = dims[np.searchsorted(keys, own)]
    own_start = np.concatenate([[0], np.cumsum(own_dims)])
    is_b = nc == own_start[-1]
    which = np.searchsorted(own_start, nc[~is_b], side="right") - 1
    rows.append(nr[~is_b] + n * m)
    cols.append(offsets[np.searchsorted(keys, own[which])] + nc[~is_b] - own_start[which])
    vals.append(nv[~is_b])
    b_native = np.zeros(int(nr.max()) + 1)
    b_native[nr[is_b]] = nv[is_b]
    rhs.append(b_native)
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n * m + len(b_native), total))
    b = np.concatenate(rhs)
    H = (A.T @ A).tocsc()
    step = sla.splu(H, permc_spec="COLAMD").solve(A.T @ b)
    delta = gtsam.VectorValues()
    for k, o, d in zip(keys, offsets, dims):
        delta.insert(int(k), step[o:o + d])
    return values.retract(delta)


def layout_of(values):
    zero = values.zeroVectors()
    keys = np.array(sorted(values.keys()), dtype=np.int64)
    dims = np.array([zero.at(int(k)).shape[0] for k in keys])
    offsets = np.concatenate([[0], np.cumsum(dims)[:-1]])
    return keys, offsets, dims, int(dims.sum())


def median_time(fn, repeats=5):
    times = []
    for _ in range(repeats):
        tic = time.perf_counter()
        fn()
        times.append(time.perf_counter() - tic)
    return float(np.median(times))


def run(sizes=(1000, 10000, 100000)) -> str:
    lines = ["one Gauss-Newton step, scaled-VO chain (vectorized group + native priors): us per state",
             f"{'states':>7}  {'gtsam, colamd':>13}  {'gtsam, metis':>12}  {'scipy path':>10}  {'scipy/metis':>11}  "
             f"{'max |step difference|':>21}"]
    for n in sizes:
        values, group, native = problem(n)
        evaluator = GraphEvaluator([FactorRecord(None, "vo", 0.0, group, i) for i in range(len(group.keys))])
        evaluator.plain = native
        layout = layout_of(values)
        a, order = gtsam_step(values, evaluator, None)
        _, metis = gtsam_step(values, evaluator, None, "metis")
        b = scipy_step(values, group, native, layout)
        gap = float(np.abs(a.localCoordinates(b).vector()).max())
        t_colamd = median_time(lambda: gtsam_step(values, evaluator, order))
        t_metis = median_time(lambda: gtsam_step(values, evaluator, metis))
        t_scipy = median_time(lambda: scipy_step(values, group, native, layout))
        lines.append(f"{n:>7}  {t_colamd / n * 1e6:>13.1f}  {t_metis / n * 1e6:>12.1f}  {t_scipy / n * 1e6:>10.1f}  "
                     f"{t_scipy / t_metis:>10.2f}x  {gap:>21.1e}")
    return "\n".join(lines)


if __name__ == "__main__":
    print(run())
