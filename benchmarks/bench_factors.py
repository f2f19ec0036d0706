"""(a) Cost per factor evaluation: fusionkit's `pose.scaled_relative` CustomFactor vs a minimal
hand-written CustomFactor with the same math vs native gtsam.BetweenFactorPose3.

Every variant is put in its own NonlinearFactorGraph of N factors over the same Values; we time
graph.linearize(values) and graph.error(values) and divide by N. Rounds are interleaved (every
variant once per round) so that machine noise hits all variants alike; we report the median.
"""

from __future__ import annotations

import gc
import statistics
import time

import gtsam
import numpy as np

from fusionkit.graph.noise import gaussian
from fusionkit_plugins.pose.factors import scaled_between_factor

from _timing import ratio, table, us

SIGMAS = [0.002] * 3 + [0.004] * 3  # what the quickstart's pose.scaled_relative entry uses
SCALE_KEY = 10**9


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


def bare_scaled(a, b, s, delta, noise):
    """Minimal hand-written CustomFactor, same formula as fusionkit's scaled_between_residual."""
    rot, t = delta.rotation(), np.asarray(delta.translation())

    def f(this, v, H):
        xa, xb, sc = v.atPose3(a), v.atPose3(b), v.atDouble(s)
        between = xa.between(xb)
        err = gtsam.Pose3(rot, sc * t).between(between)
        e = gtsam.Pose3.Logmap(err)
        if H is not None:
            j = gtsam.Pose3.LogmapDerivative(e)
            H[0] = -j @ between.inverse().AdjointMap()
            H[1] = j
            dz = np.concatenate([np.zeros(3), rot.unrotate(t)])
            H[2] = -(j @ (err.inverse().AdjointMap() @ dz)).reshape(6, 1)
        return e
    return gtsam.CustomFactor(noise, [a, b, s], f)


def candidate_scaled(a, b, s, delta, noise):
    """A cheaper formulation of the same residual (suggested fix; NOT what fusionkit does today):
    GTSAM's own chain-rule Jacobians from between()/Logmap(), the constant R^T t precomputed once
    per factor, and Ad(E^-1)[0; v] = [0; R_E^T v] instead of a 6x6 AdjointMap product."""
    rot, t = delta.rotation(), np.asarray(delta.translation())
    rtt = rot.unrotate(t)

    def f(this, v, H):
        xa, xb, sc = v.atPose3(a), v.atPose3(b), v.atDouble(s)
        z = gtsam.Pose3(rot, sc * t)
        if H is None:
            return gtsam.Pose3.Logmap(z.between(xa.between(xb)))
        ha, hb, hl = (np.zeros((6, 6), order="F") for _ in range(3))
        err = z.between(xa.between(xb, ha, hb))
        e = gtsam.Pose3.Logmap(err, hl)
        H[0] = hl @ ha
        H[1] = hl  # d between / d xb is identity
        H[2] = -(hl[:, 3:] @ err.rotation().unrotate(rtt)).reshape(6, 1)
        return e
    return gtsam.CustomFactor(noise, [a, b, s], f)


VARIANTS = [
    ("native gtsam.BetweenFactorPose3", native_between),
    ("CustomFactor floor (no math)", custom_floor),
    ("hand-written CustomFactor (same math)", bare_scaled),
    ("fusionkit pose.scaled_relative", scaled_between_factor),
    ("candidate fix (see README)", candidate_scaled),
]
NATIVE, BARE, FUSIONKIT = VARIANTS[0][0], VARIANTS[2][0], VARIANTS[3][0]


# --- data --------------------------------------------------------------------------------------
def _problem(n: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    values = gtsam.Values()
    for i in range(n + 1):
        values.insert(i, gtsam.Pose3.Expmap(rng.normal(size=6) * 0.3))
    values.insert(SCALE_KEY, 2.5)
    meas = [gtsam.Pose3.Expmap(rng.normal(size=6) * 0.3) for _ in range(n)]
    return values, meas


def _graph(make, meas, noise) -> gtsam.NonlinearFactorGraph:
    g = gtsam.NonlinearFactorGraph()
    for i, m in enumerate(meas):
        g.add(make(i, i + 1, SCALE_KEY, m, noise))
    return g


def check_same_math(values, meas, noise) -> float:
    """Largest difference of residuals and Jacobians between fusionkit, hand-written and candidate
    (a few factors; dense Jacobian of a tiny graph)."""
    few = meas[:4]
    ref = _graph(scaled_between_factor, few, noise).linearize(values)
    a_ref, b_ref = ref.jacobian()
    worst = 0.0
    for make in (bare_scaled, candidate_scaled):
        a, b = _graph(make, few, noise).linearize(values).jacobian()
        worst = max(worst, float(np.abs(a - a_ref).max()), float(np.abs(b - b_ref).max()))
    return worst


# --- run ---------------------------------------------------------------------------------------
def run(quick: bool = False) -> dict:
    n = 2000 if quick else 10000
    rounds = 5 if quick else 7
    noise = gaussian(SIGMAS)
    values, meas = _problem(n)
    graphs = {name: _graph(make, meas, noise) for name, make in VARIANTS}
    mismatch = check_same_math(values, meas, noise)
    samples = {(name, op): [] for name in graphs for op in ("linearize", "error")}
    for name, g in graphs.items():  # warm-up
        g.linearize(values)
        g.error(values)
    for _ in range(rounds):
        for name, g in graphs.items():
            for op in ("linearize", "error"):
                fn = getattr(g, op)
                gc.collect()
                gc.disable()
                tic = time.perf_counter()
                fn(values)
                samples[(name, op)].append((time.perf_counter() - tic) / n)
                gc.enable()
    med = {k: statistics.median(v) for k, v in samples.items()}
    rows = []
    for name in graphs:
        lin, err = med[(name, "linearize")], med[(name, "error")]
        rows.append([name, us(lin), us(err), ratio(lin, med[(NATIVE, "linearize")]),
                     ratio(err, med[(NATIVE, "error")]), ratio(lin, med[(BARE, "linearize")]),
                     ratio(err, med[(BARE, "error")])])
    text = table(["factor (3-key scaled relative pose; native has 2 keys)", "lin us/f", "err us/f",
                  "lin/native", "err/native", "lin/hand", "err/hand"], rows,
                 f"(a) factor evaluation cost: {n} factors, median of {rounds} interleaved rounds")
    text += (f"\nresidual+Jacobian agreement fusionkit vs hand-written/candidate: max |diff| = {mismatch:.1e}"
             "\nnote: fusionkit's pose.relative / pose.absolute / pose.origin build the native "
             "BetweenFactorPose3 / PriorFactorPose3, so their per-evaluation cost is the native row.")
    return {"text": text, "median_s": {f"{k[0]}|{k[1]}": v for k, v in med.items()}, "n": n}


if __name__ == "__main__":
    import sys
    print(run("--quick" in sys.argv)["text"])
