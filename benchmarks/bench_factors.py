"""(a) Cost per factor evaluation: fusionkit's `pose.scaled_relative` (vectorized: one call for all
factors, as fusionkit's solvers evaluate it; and one factor at a time, as GTSAM's own callers do) vs a
minimal hand-written CustomFactor with the same math vs native gtsam.BetweenFactorPose3.

Every variant evaluates N factors over the same Values: a NonlinearFactorGraph's linearize(values) and
error(values), or for the vectorized path fusionkit's GraphEvaluator (the linear factors it hands GTSAM,
and the cost); we divide by N. Rounds are interleaved (every variant once per round) so that machine
noise hits all variants alike; we report the median.
"""

from __future__ import annotations

import gc
import statistics
import time

import gtsam
import numpy as np

from fusionkit.api import vectorized_factor
from fusionkit.graph.builder import FactorRecord
from fusionkit.graph.evaluator import GraphEvaluator
from fusionkit.graph.vectorized import InstanceCache, VectorizedGroup
from fusionkit_plugins.cable_rigid.factors import elastic_cable_factor
from fusionkit_plugins.cable_rigid.residuals import elastic_cable_residual
from fusionkit_plugins.pose.residuals import SCALED_BETWEEN

from _timing import ratio, table, us

SIGMAS = [0.002] * 3 + [0.004] * 3  # what the quickstart's pose.scaled_relative entry uses
SCALE_KEY = 10**9


def gaussian(sigmas) -> gtsam.noiseModel.Base:
    """GTSAM's diagonal noise model (unit when every sigma is 1), given to every variant alike."""
    return gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, dtype=float))


# --- the variants ----------------------------------------------------------------------------
def native_between(a, b, s, delta, noise):
    """Native C++ factor (no scale variable: the closest native equivalent of the same residual)."""
    return gtsam.BetweenFactorPose3(a, b, delta, noise)


_Z6, _I6, _C61 = np.zeros(6), np.eye(6), np.zeros((6, 1))


def custom_floor(a, b, s, delta, noise):
    """CustomFactor that does no math (constant residual and Jacobians): the Python-callback floor."""
    def f(this, v, H):
        if H is not None:
            H[0], H[1], H[2] = _I6, _I6, _C61
        return _Z6
    return gtsam.CustomFactor(noise, [a, b, s], f)


def bare_scaled(a, b, s, measured, noise):
    """Minimal hand-written CustomFactor, same formula as fusionkit's scaled_between_residual
    (plugins/pose/residuals.py): B = xa^-1 xb, B_s = (R_B, t_B / s), e = Log(measured^-1 B_s).
    `check_same_math` fails loudly if the plugin's formula changes and this copy does not."""
    def f(this, v, H):
        xa, xb, sc = v.atPose3(a), v.atPose3(b), v.atDouble(s)
        between = xa.between(xb)
        t = between.translation()
        e = gtsam.Pose3.Logmap(measured.between(gtsam.Pose3(between.rotation(), t / sc)))
        if H is not None:
            j = gtsam.Pose3.LogmapDerivative(e)
            jd = j.copy()
            jd[:, 3:] /= sc
            H[1] = jd
            H[0] = -jd @ between.inverse().AdjointMap()
            H[2] = (j[:, 3:] @ (-between.rotation().unrotate(t) / sc**2)).reshape(6, 1)
        return e
    return gtsam.CustomFactor(noise, [a, b, s], f)


def scaled_between_factor(a, b, s, measured, noise):
    """fusionkit's pose.scaled_relative factor on its own: the vectorized residual at N = 1."""
    return vectorized_factor(SCALED_BETWEEN, noise, [a, b, s], {"measured": measured.matrix()[None]})


def _keys_and_data(meas):
    n = len(meas)
    keys = np.column_stack([np.arange(n), np.arange(1, n + 1), np.full(n, SCALE_KEY)])
    return keys, {"measured": np.array([m.matrix() for m in meas])}


class OneAtATime:
    """fusionkit's pose.scaled_relative factors as ctx.add_vectorized makes them for GTSAM's own callers:
    CustomFactors sharing an InstanceCache (the first call at new values evaluates all of them)."""

    def __init__(self, meas, noise):
        keys, data = _keys_and_data(meas)
        cache = InstanceCache(SCALED_BETWEEN, keys, data)
        self.graph = gtsam.NonlinearFactorGraph()
        for i in range(len(meas)):
            self.graph.add(cache.factor(i, noise))
        self.linearize, self.error = self.graph.linearize, self.graph.error


class Vectorized:
    """fusionkit's solvers' path: the N factors as one group, linearized and costed in one call each."""

    def __init__(self, meas, noise):
        keys, data = _keys_and_data(meas)
        group = VectorizedGroup(SCALED_BETWEEN, keys, data, np.tile(SIGMAS, (len(meas), 1)), None)
        self.evaluator = GraphEvaluator([FactorRecord(None, "vo", 0.0, group, i) for i in range(len(meas))])
        self.linearize, self.error = self.evaluator.linearize, self.evaluator.error


class JacobianFactorFloor:
    """The binding's floor for any Python-made linearization: N gtsam.JacobianFactors built from
    ready-made arrays (what the vectorized path pays on top of its numpy evaluation)."""

    def __init__(self, meas, noise):
        rng = np.random.default_rng(0)
        self.blocks = [np.asfortranarray(rng.normal(size=(6, 6))) for _ in range(3)]
        self.blocks[2] = np.asfortranarray(rng.normal(size=(6, 1)))
        self.b = list(rng.normal(size=(len(meas), 6)))
        self.unit = gtsam.noiseModel.Unit.Create(6)

    def linearize(self, values):
        graph = gtsam.GaussianFactorGraph()
        A0, A1, A2 = self.blocks
        for i, b in enumerate(self.b):
            graph.push_back(gtsam.JacobianFactor(i, A0, i + 1, A1, SCALE_KEY, A2, b, self.unit))
        return graph

    def error(self, values):
        return 0.0


VARIANTS = [
    ("native gtsam.BetweenFactorPose3", native_between),
    ("CustomFactor floor (no math)", custom_floor),
    ("hand-written CustomFactor (same math)", bare_scaled),
    ("fusionkit pose.scaled_relative, one at a time", OneAtATime),
    ("fusionkit pose.scaled_relative, a lone factor", scaled_between_factor),
    ("fusionkit pose.scaled_relative, vectorized", Vectorized),
    ("JacobianFactor construction floor", JacobianFactorFloor),
]
NATIVE, BARE, FUSIONKIT, VECTORIZED = VARIANTS[0][0], VARIANTS[2][0], VARIANTS[3][0], VARIANTS[5][0]


# --- data --------------------------------------------------------------------------------------
def _problem(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    values = gtsam.Values()
    for i in range(n + 1):
        values.insert(i, gtsam.Pose3.Expmap(rng.normal(size=6) * 0.3))
    values.insert(SCALE_KEY, 2.5)
    meas = [gtsam.Pose3.Expmap(rng.normal(size=6) * 0.3) for _ in range(n)]
    return values, meas


def _graph(make, meas, noise):
    if isinstance(make, type):
        return make(meas, noise)
    g = gtsam.NonlinearFactorGraph()
    for i, m in enumerate(meas):
        g.add(make(i, i + 1, SCALE_KEY, m, noise))
    return g


def _moved(values: gtsam.Values, rng) -> gtsam.Values:
    """`values` moved by a small random step (each pose by ~1e-3 rad / m, the scale by ~1e-3)."""
    step = gtsam.VectorValues()
    zero = values.zeroVectors()
    for key in values.keys():
        step.insert(key, 1e-3 * rng.normal(size=zero.at(key).shape[0]))
    return values.retract(step)


def check_same_math(values, meas, noise) -> float:
    """Largest difference of residuals and Jacobians between fusionkit and the hand-written copy
    (a few factors; dense Jacobian of a tiny graph)."""
    few = meas[:4]
    ref = _graph(scaled_between_factor, few, noise).linearize(values)
    a_ref, b_ref = ref.jacobian()
    worst = 0.0
    for make in (bare_scaled,):
        a, b = _graph(make, few, noise).linearize(values).jacobian()
        worst = max(worst, float(np.abs(a - a_ref).max()), float(np.abs(b - b_ref).max()))
    return worst


def elastic_cables(n: int, rounds: int) -> list[list[str]]:
    """cable.elastic_length (1 row over pose, pulley, offset) vectorized and one at a time, against GTSAM's
    native range+bias factor (the same length without the stretch) and the native BetweenFactorPose3:
    median us per factor linearization."""
    rng = np.random.default_rng(2)
    values = gtsam.Values()
    for i in range(n):
        values.insert(i, gtsam.Pose3.Expmap(rng.normal(size=6) * 0.3))
    values.insert(PULLEY_KEY, rng.normal(size=3) * 3)
    values.insert(OFFSET_KEY, 0.5)
    b = rng.normal(size=(n, 3)) * 0.2
    z = rng.uniform(2, 4, n)
    stretch = rng.uniform(0, 0.01, n)
    keys = np.column_stack([np.arange(n), np.full(n, PULLEY_KEY), np.full(n, OFFSET_KEY)])
    group = VectorizedGroup(elastic_cable_residual(), keys, {"attachment": b, "stretch": stretch, "z": z},
                            np.full((n, 1), 0.001), None)
    vectorized = GraphEvaluator([FactorRecord(None, "cable", 0.0, group, i) for i in range(n)])
    noise = gaussian([0.001])
    one_by_one, native, between = (gtsam.NonlinearFactorGraph() for _ in range(3))
    for i in range(n):
        one_by_one.add(elastic_cable_factor(i, PULLEY_KEY, OFFSET_KEY, b[i], stretch[i], z[i], noise))
        native.add(gtsam.RangeFactorWithTransformBias3D(i, PULLEY_KEY, OFFSET_KEY, z[i], noise,
                                                        gtsam.Pose3(gtsam.Rot3(), b[i])))
        if i + 1 < n:
            between.add(gtsam.BetweenFactorPose3(i, i + 1, gtsam.Pose3(), gaussian(SIGMAS)))
    variants = {"vectorized": vectorized, "a lone factor (N = 1)": one_by_one, "native range+bias": native,
                "native BetweenFactorPose3": between}
    samples: dict[str, list[float]] = {k: [] for k in variants}
    for _ in range(rounds):
        for name, graph in variants.items():
            tic = time.perf_counter()
            graph.linearize(values)
            samples[name].append((time.perf_counter() - tic) / n)
    med = {k: statistics.median(v) for k, v in samples.items()}
    base = med["native BetweenFactorPose3"]
    return [[name, us(med[name]), ratio(med[name], base)] for name in variants]


PULLEY_KEY, OFFSET_KEY = 10**9 + 1, 10**9 + 2


def inside_cpp(sizes=(250, 1000)) -> list[list[str]]:
    """us per fusionkit CustomFactor linearization when GTSAM's C++ code makes the call (one
    GaussNewtonOptimizer iteration) vs graph.linearize from Python, for growing graphs: pybind11
    hands each Python callback a copy of the whole Values when C++ owns it, so the C++-side cost
    grows with the number of variables. This is what GTSAM's own optimizers and gtsam.Marginals do with
    fusionkit's factors (built as ctx.add_vectorized builds them: CustomFactors sharing an InstanceCache);
    fusionkit's iSAM2 and fixed-lag smoother hand vectorized factors over linearized instead."""
    noise = gaussian(SIGMAS)
    rows = []
    for n in sizes:
        values, meas = _problem(n, seed=1)
        g = OneAtATime(meas, noise).graph
        g.add(gtsam.PriorFactorPose3(0, values.atPose3(0), gaussian([1.0] * 6)))
        g.add(gtsam.PriorFactorDouble(SCALE_KEY, 2.5, gaussian([1.0])))
        tic = time.perf_counter()
        g.linearize(values)
        py = (time.perf_counter() - tic) / n
        params = gtsam.GaussNewtonParams()
        params.setMaxIterations(1)
        tic = time.perf_counter()
        gtsam.GaussNewtonOptimizer(g, values, params).iterate()  # 1 linearize + 1 elimination
        cpp = (time.perf_counter() - tic) / n
        rows.append([f"{n}", us(py), us(cpp), ratio(cpp, py)])
    return rows


# --- run ---------------------------------------------------------------------------------------
def run(quick: bool = False) -> dict:
    n = 2000 if quick else 10000
    rounds = 11 if quick else 9
    noise = gaussian(SIGMAS)
    values, meas = _problem(n)
    graphs = {name: _graph(make, meas, noise) for name, make in VARIANTS}
    mismatch = check_same_math(values, meas, noise)
    samples = {(name, op): [] for name in graphs for op in ("linearize", "error")}
    for name, g in graphs.items():  # warm-up
        g.linearize(values)
        g.error(values)
    rng = np.random.default_rng(7)
    for _ in range(rounds):
        for op in ("linearize", "error"):
            at = _moved(values, rng)  # new values every round: nothing may serve a result kept from before
            for name, g in graphs.items():
                fn = getattr(g, op)
                gc.collect()
                gc.disable()
                tic = time.perf_counter()
                fn(at)
                samples[(name, op)].append((time.perf_counter() - tic) / n)
                gc.enable()
    med = {k: statistics.median(v) for k, v in samples.items()}

    def rel(name, base, op):
        """Median over rounds of the per-round ratio (neighbouring measurements share the machine's
        state, so this is steadier than a ratio of medians), and its min-max over rounds."""
        r = [x / y for x, y in zip(samples[(name, op)], samples[(base, op)])]
        return statistics.median(r), min(r), max(r)

    rows = []
    for name in graphs:
        lin, err = med[(name, "linearize")], med[(name, "error")]
        rows.append([name, us(lin), us(err)] + [f"{rel(name, base, op)[0]:.2f}x" for base in (NATIVE, BARE)
                                                for op in ("linearize", "error")])
    spread = rel(VECTORIZED, BARE, "linearize")
    text = table(["factor (3-key scaled relative pose; native has 2 keys)", "lin us/f", "err us/f",
                  "lin/native", "err/native", "lin/hand", "err/hand"], rows,
                 f"(a) factor evaluation cost: {n} factors, median of {rounds} interleaved rounds")
    text += "\n\n" + table(["cable.elastic_length (1 row; pose, pulley, offset)", "lin us/f", "lin/native Between"],
                            elastic_cables(n, rounds),
                            f"(a3) the elastic cable: {n} factors, median of {rounds} rounds")
    text += "\n\n" + table(["factors (= variables)", "graph.linearize from Python us/f",
                             "GaussNewton iterate (C++ calls) us/f", "C++/Python"], inside_cpp(),
                            "(a2) fusionkit CustomFactor called from C++: Values copied into every call")
    fastest = min(samples[(VECTORIZED, "linearize")]) / min(samples[(BARE, "linearize")])
    text += (f"\nfusionkit vectorized/hand-written linearize per round: median {spread[0]:.2f}x, range "
             f"{spread[1]:.2f}x-{spread[2]:.2f}x over {rounds} rounds; fastest round / fastest round "
             f"{fastest:.2f}x (a wide range means a noisy machine: trust the fastest-round ratio more)")
    text += (f"\nresidual+Jacobian agreement fusionkit vs hand-written: max |diff| = {mismatch:.1e}"
             + ("" if mismatch < 1e-8 else "  <-- WARNING: the hand-written copy no longer computes the plugin's "
                "residual; update bench_factors.bare_scaled")
             + "\nnote: fusionkit's pose.relative / pose.absolute / pose.origin build the native "
             "BetweenFactorPose3 / PriorFactorPose3, so their per-evaluation cost is the native row.")
    return {"text": text, "median_s": {f"{k[0]}|{k[1]}": v for k, v in med.items()}, "n": n,
            "fk_over_hand_lin": spread[0], "fk_over_native_lin": rel(VECTORIZED, NATIVE, "linearize")[0],
            "one_at_a_time_over_native_lin": rel(FUSIONKIT, NATIVE, "linearize")[0]}


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run)
