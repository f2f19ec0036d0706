"""Incremental solvers: iSAM2 and the fixed-lag smoother. Factors enter in time order (the time
of the latest state they touch; static-only factors first). The per-step latency is the wall
time a real-time user waits for each step: the update plus `calculateEstimate()`, which hands the
new estimate out (the estimate after the last step is the result).

`warmup: SECONDS` solves the factors of the first SECONDS (from the first state) as one batch
(Levenberg-Marquardt) and hands the result to the incremental solver in its first update: the
start-up phase in which static parameters are not yet observable (a VO scale after a few
millimetres of motion, pulleys before the calibration motion has covered three axes). Added one
step at a time, such a phase makes Gauss-Newton jump far from the truth (a negative scale), and
iSAM2 spends the rest of the run relinearizing, or diverges. Its wall time is reported apart
from the per-step latency.

`new_states: carried` starts each new state from the previous state's estimate moved by the initial values'
step (carried_forward), instead of its initial value: for initial values from drifting odometry."""

from __future__ import annotations

import time
from itertools import groupby
from typing import Callable, Iterator

import gtsam
import numpy as np

from ..errors import SolverError
from ..graph.builder import Problem
from ..graph.evaluator import GraphEvaluator
from ..graph.keys import STATE
from .checks import check_constrained, unconstrained_message
from .covariance_recovery import tree_marginals
from .health import RevisionMonitor, first_jump, remedies
from .linear_containers import LinearContainers
from .result import SolveResult, SolveWarning


def _isam2_params(settings: dict) -> gtsam.ISAM2Params:
    p = gtsam.ISAM2Params()
    p.setRelinearizeThreshold(settings["relinearize_threshold"])
    p.relinearizeSkip = settings["relinearize_skip"]
    # a removed factor leaves an empty slot in iSAM2's factor list, and fusionkit removes factors at every update
    # (linear_containers: swapped when relinearized): reuse the slots, or the list and each update's cost grow
    p.findUnusedFactorSlots = True
    # QR by default (config.schema.SOLVER_TYPE_DEFAULTS): Cholesky declared weakly observed directions
    # (a scale with a loose prior) singular; `factorization: cholesky` is faster where the graph is well conditioned
    p.setFactorization("CHOLESKY" if settings["factorization"] == "cholesky" else "QR")
    return p


def value_subset(problem: Problem, keys: list[int], source: gtsam.Values | None = None) -> gtsam.Values:
    """A Values holding only `keys` (copied from `source`, default the initial values)."""
    source = problem.initial if source is None else source
    out = gtsam.Values()
    for k in keys:
        out.insert(k, problem.keys.decode(k)[0].vartype.read(source, k))
    return out


def time_steps(problem: Problem) -> Iterator[tuple[float, list, list[int]]]:
    """(time, factor records, keys first seen) per distinct factor time, in time order."""
    seen: set[int] = set()
    for t, group in groupby(sorted(problem.records, key=lambda r: r.time), key=lambda r: r.time):
        records = list(group)
        new = []
        for r in records:
            for k in r.factor.keys():
                if k not in seen:
                    seen.add(k)
                    new.append(k)
        yield t, records, new


def warm_start(problem: Problem, steps: list, settings: dict) -> tuple[list, gtsam.Values, float, list]:
    """Merge the time steps up to `warmup` seconds after the first state into one, solve it with batch LM
    (the settings' `damping`) from the initial values; returns (its factor records, their solution, last
    merged time, the other steps)."""
    from .levenberg import DampingSettings, levenberg_marquardt
    seconds = settings["warmup"]
    finite = [t for t, _, _ in steps if np.isfinite(t)]
    end = (finite[0] if finite else 0.0) + seconds
    records, keys, rest = [], [], []
    last = float("-inf")
    for t, step_records, new in steps:
        if t <= end:
            records += step_records
            keys += new
            last = t
        else:
            rest.append((t, step_records, new))
    values, _ = levenberg_marquardt(GraphEvaluator(records), value_subset(problem, keys), 1e-6, 1e-9, 100,
                                    DampingSettings.of(settings))
    return records, values, last, rest


def _raise_unconstrained(problem: Problem, exc: RuntimeError, t: float, monitor: RevisionMonitor | None,
                         settings: dict):
    """GTSAM's indeterminate system in an update at `t` as a SolverError: a divergence when `monitor` saw the
    estimates go astray before, else the variable GTSAM names; other errors as they are."""
    msg = unconstrained_message(problem, exc)
    if msg is None:
        raise exc
    astray = first_jump(monitor.revisions) if monitor else None
    if astray is not None:
        raise SolverError(
            f"the incremental solve diverged: GTSAM found the linear system indeterminate while adding the "
            f"measurements at t={t:.3f} s, after the estimates had gone astray from t = {astray.t:.2f} s "
            f"({problem.keys.name_of(astray.key)} revised by {np.sqrt(astray.d2):.3g} sigma by the next update); "
            f"not a missing constraint: try {remedies(settings)}") from None
    raise SolverError(f"{msg} (while adding the measurements at t={t:.3f} s incrementally: a variable the whole "
                      "graph constrains may not be constrained yet by the measurements so far; static parameters "
                      "need a prior until the data constrain them, or solver.warmup)") from None


def _timed_step(problem: Problem, settings: dict, t: float, update: Callable[[], gtsam.Values],
                monitor: RevisionMonitor | None = None) -> tuple[gtsam.Values, float]:
    """Run one solver update, which returns the estimate it hands out; return (estimate, wall time in s),
    turning an indeterminate system into a SolverError (a divergence when `monitor` saw the estimates go astray)."""
    tic = time.perf_counter()
    try:
        values = update()
    except RuntimeError as exc:
        _raise_unconstrained(problem, exc, t, monitor, settings)
    return values, time.perf_counter() - tic


def _isam2_update(isam: gtsam.ISAM2, containers: LinearContainers, records, values: gtsam.Values) -> gtsam.Values:
    """One iSAM2 update with `records` (new variables at `values`), the vectorized factors handed over and
    swapped by `containers`; returns the estimate it hands out."""
    step = containers.step(records, isam, values)
    result = isam.update(step.graph, values, step.remove)
    containers.added(step, result.getNewFactorsIndices())
    return isam.calculateEstimate()


def _isam2_step(isam: gtsam.ISAM2, containers: LinearContainers, records, values: gtsam.Values,
                updates: int) -> gtsam.Values:
    """A time step in `updates` iSAM2 updates: the first adds `records`, each further one (no new factors)
    takes one more Gauss-Newton step, relinearizing what moved (`solver.updates_per_step`)."""
    estimate = _isam2_update(isam, containers, records, values)
    for _ in range(updates - 1):
        estimate = _isam2_update(isam, containers, [], gtsam.Values())
    return estimate


def _settle(isam: gtsam.ISAM2, containers: LinearContainers, estimate: gtsam.Values,
            updates: int = 10) -> gtsam.Values:
    """Updates without new factors until the estimate stops moving (at most `updates`): each update takes
    one Gauss-Newton step, so the factors of the last update are still linearized at their initial values,
    and the final estimate and marginals would carry those Jacobians. Variables whose change stays below
    `relinearize_threshold` are not relinearized (a time offset moving by milliseconds: see
    docs/models/unified_graph.md#time-offsets). Vectorized factors are relinearized as the solver
    relinearizes (linear_containers.py)."""
    for _ in range(updates):
        settled = _isam2_update(isam, containers, [], gtsam.Values())
        moved = np.abs(settled.localCoordinates(estimate).vector()).max()
        estimate = settled
        if moved < 1e-9:
            break
    return estimate


def carried_forward(problem: Problem, keys: list[int], estimate: gtsam.Values) -> gtsam.Values:
    """Values of the variables entering now: a state whose previous state has an estimate starts from that
    estimate moved by the initial values' step between the two (x_k = est_{k-1} (+) (init_{k-1} (-) init_k)),
    so a correction the solver made so far carries to the new states instead of being undone by them (the
    initializers' drift: a VO scale guessed 15 % short, a bridge across a camera dropout); other variables
    (static ones, first states) start from the initial values."""
    out = value_subset(problem, keys)
    for k in keys:
        family, index = problem.keys.decode(k)
        prev = family.key(index - 1)
        if family.kind != STATE or index == 0 or not estimate.exists(prev) or not problem.initial.exists(prev):
            continue
        vt = family.vartype
        moved = gtsam.Values()
        moved.insert(prev, vt.read(estimate, prev))
        delta = gtsam.VectorValues()
        delta.insert(prev, vt.local(vt.read(problem.initial, prev), vt.read(problem.initial, k)))
        out.update(k, vt.read(moved.retract(delta), prev))
    return out


def new_values(problem: Problem, settings: dict, keys: list[int], estimate: gtsam.Values) -> gtsam.Values:
    """Values of the variables entering now: `new_states: initial` the initial values, `carried` carried_forward."""
    if settings["new_states"] == "carried":
        return carried_forward(problem, keys, estimate)
    return value_subset(problem, keys)


def _checked(problem: Problem, settings: dict) -> tuple[dict, list[SolveWarning]]:
    """check_constrained with the configured factorization; the settings with QR where Cholesky failed on a
    determinate system, and the warning that says so."""
    checked = check_constrained(problem, problem.graph(), settings["factorization"] == "qr")
    if checked.warning is None:
        return settings, []
    return {**settings, "factorization": "qr"}, [SolveWarning("ill_conditioned", checked.warning)]


def _containers(problem: Problem, settings: dict) -> LinearContainers:
    return LinearContainers(settings["relinearize_threshold"], lambda k: problem.keys.decode(k)[0].vartype,
                            settings["relinearize_skip"], settings["relinearize_marginal_variables"])


def leaving_keys(window: dict[int, float], stamps: dict[int, float], lag: float) -> list[int]:
    """The keys IncrementalFixedLagSmoother marginalizes in an update that adds `stamps` to its timestamps
    `window`: its rule (FixedLagSmoother::findKeysBefore), those stamped before the latest stamp minus the lag."""
    stamped = {**window, **stamps}
    if not stamped:
        return []
    horizon = max(stamped.values()) - lag
    return [k for k, kt in stamped.items() if kt < horizon]


def _check_marginalized(problem: Problem, before: set[int], after: set[int], expected: set[int]) -> None:
    """The smoother marginalized exactly the keys leaving_keys named (their last estimates are kept): anything
    else is a fusionkit error, never a silently lost state."""
    gone = before - after
    if gone != expected:
        odd = sorted(gone ^ expected)[:3]
        raise RuntimeError("the fixed-lag smoother marginalized other keys than expected: "
                           + ", ".join(problem.keys.name_of(k) for k in odd))


def solve_isam2(problem: Problem, settings: dict, progress: Callable[[int, float], None] | None = None) -> SolveResult:
    settings, warnings = _checked(problem, settings)
    isam = gtsam.ISAM2(_isam2_params(settings))
    containers = _containers(problem, settings)
    latency = []
    start = time.perf_counter()
    steps, warmup, estimate = list(time_steps(problem)), 0.0, gtsam.Values()
    if settings["warmup"] > 0:
        tic = time.perf_counter()
        first, values, t, steps = warm_start(problem, steps, settings)
        estimate, _ = _timed_step(problem, settings, t, lambda: _isam2_update(isam, containers, first, values))
        warmup = time.perf_counter() - tic
    monitor = RevisionMonitor(problem)
    for i, (t, records, new) in enumerate(steps):
        estimate, dt = _timed_step(problem, settings, t, lambda: _isam2_step(
            isam, containers, records, new_values(problem, settings, new, estimate), settings["updates_per_step"]),
            monitor)
        latency.append(dt)
        monitor.step(t, new, estimate, isam)
        if progress and i % 100 == 0:
            progress(i, float("nan"))
    estimate = _settle(isam, containers, estimate)
    seconds = time.perf_counter() - start
    cost = problem.evaluator().error
    return SolveResult(estimate, "isam2", cost(problem.initial), cost(estimate), len(latency),
                       seconds, step_latency=np.asarray(latency), marginal=isam.marginalCovariance,
                       warmup_seconds=warmup, factorization=settings["factorization"], warnings=warnings,
                       swaps=containers.swap_statistics(), revisions=monitor.revisions)


def solve_fixed_lag(problem: Problem, settings: dict,
                    progress: Callable[[int, float], None] | None = None,
                    marginal_keys: set[int] | None = None) -> SolveResult:
    """IncrementalFixedLagSmoother with `lag` seconds. Static variables are re-stamped at every
    update so they stay in the window; each state keeps the estimate (and covariance, for
    `marginal_keys`) it had when it left the window: the keys the smoother marginalizes in an update are
    found by its own rule on its own timestamps (leaving_keys) and checked against what it did."""
    settings, warnings = _checked(problem, settings)
    lag = float(settings["lag"])
    smoother = gtsam.IncrementalFixedLagSmoother(lag, _isam2_params(settings))
    containers = _containers(problem, settings)
    static = [k for k, t in problem.key_time.items() if t == float("-inf")]
    final: dict[int, object] = {}
    covariances: dict[int, np.ndarray] = {}
    snapshots: list[tuple[float, gtsam.Values]] = []  # (time, the smoother's estimate then), once per lag
    origin = min((r.time for r in problem.records if np.isfinite(r.time)), default=0.0)  # health.window_fit's
    latency = []
    start = time.perf_counter()
    now, est = None, gtsam.Values()  # est: the estimate handed out after the latest update
    steps, warm_values, warmup = list(time_steps(problem)), None, 0.0
    monitor = RevisionMonitor(problem)
    if settings["warmup"] > 0:
        tic = time.perf_counter()
        first, warm_values, t, steps = warm_start(problem, steps, settings)
        steps.insert(0, (t, first, list(warm_values.keys())))
        # states older than the window leave inside the first update: their covariance from the warm-up solve
        early = set(leaving_keys({}, {k: problem.key_time[k] for k in warm_values.keys()
                                      if problem.key_time[k] != float("-inf")} | {k: t for k in static}, lag))
        if marginal_keys and early & marginal_keys:
            covariances.update(tree_marginals(GraphEvaluator(first), warm_values, early & marginal_keys))
        warmup = time.perf_counter() - tic

    def add(records, values: gtsam.Values, stamps: dict) -> None:
        step = containers.step(records, smoother, values)
        smoother.update(step.graph, values, stamps, step.remove)
        containers.added(step, smoother.getISAM2Result().getNewFactorsIndices())

    def update(records, values: gtsam.Values, stamps: dict, leaving: list[int]) -> gtsam.Values:
        """The time step: its factors and variables added (`leaving` marginalized in that update), then
        `solver.updates_per_step` - 1 updates without new factors, one more Gauss-Newton step each."""
        add(records, values, stamps)
        containers.forget(leaving)  # marginalized inside the update, with their factors
        for _ in range(settings["updates_per_step"] - 1):
            add([], gtsam.Values(), {})
        return smoother.calculateEstimate()

    for i, (t, records, new) in enumerate(steps):
        now = t if np.isfinite(t) else (now if now is not None else 0.0)
        stamps = {k: now for k in static}
        for k in new:
            kt = problem.key_time[k]
            stamps[k] = now if kt == float("-inf") else kt
        values = warm_values if i == 0 and warm_values is not None else new_values(problem, settings, new, est)
        window = smoother.timestamps()
        leaving = leaving_keys(window, stamps, lag)
        for k in leaving:
            vt = problem.keys.decode(k)[0].vartype
            final[k] = vt.read(est, k) if est.exists(k) else vt.read(values, k)
            if marginal_keys and k in marginal_keys and est.exists(k):
                covariances[k] = smoother.marginalCovariance(k)
        est, dt = _timed_step(problem, settings, now, lambda: update(records, values, stamps, leaving), monitor)
        _check_marginalized(problem, set(window) | set(stamps), set(smoother.timestamps()), set(leaving))
        monitor.step(now, new, est, smoother.getISAM2())
        while now >= origin + (len(snapshots) + 1) * lag - 1e-9:  # windows of the health check completed
            snapshots.append((now, gtsam.Values(est)))
        if i == 0 and warm_values is not None:
            warmup += dt
        else:
            latency.append(dt)
        if progress and i % 100 == 0:
            progress(i, float("nan"))
    estimate = gtsam.Values()
    for k in problem.initial.keys():
        vt = problem.keys.decode(k)[0].vartype
        estimate.insert(k, vt.read(est, k) if est.exists(k) else final[k])
        if marginal_keys and k in marginal_keys and est.exists(k):
            covariances[k] = smoother.marginalCovariance(k)
    seconds = time.perf_counter() - start
    cost = problem.evaluator().error
    return SolveResult(estimate, "fixed_lag", cost(problem.initial), cost(estimate), len(latency),
                       seconds, covariances=covariances, step_latency=np.asarray(latency), warmup_seconds=warmup,
                       factorization=settings["factorization"], warnings=warnings, swaps=containers.swap_statistics(),
                       revisions=monitor.revisions, static_snapshots=snapshots)
