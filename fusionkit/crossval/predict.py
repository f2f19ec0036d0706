"""One fold: calibrate on the training factors, hold the calibration, solve the held-out states from the
reference streams alone, and compare every other entry's held-out measurements with what the model predicts.

Training is a solve of the training factors with the config's solver (its checks included). The held-out states
are then solved (batch Levenberg-Marquardt) from the held-out factors of the reference entries, of entries that
read no stream (motion models, priors on states) and of the description's priors on per-state variables, with
every static variable held at its training estimate. When that leaves the held-out states free (a reference
that only measures motion, as wheel odometry does), each robot's first held-out state is anchored by the other
entries' measurements at it -- dead reckoning from a measured start -- and those measurements are not scored.

A prediction's error is its factor's unwhitened residual, in the measurement's units, split into the parts its
factor type names (`FactorType.residual_parts`: e.g. position in m, orientation in rad) and scored by each part's
norm. What the model expects of it: the residual's covariance S = R + J P J^T, with R the measurement noise, J the
residual's Jacobian and P the joint covariance of the variables it reads -- the held-out states as the reference
determines them and the calibration with the training data's information on it (the training graph marginalized
onto the static variables). Its expected squared norm per part is the trace of S's block, and e^T S^-1 e per
dimension averages 1 when the model's sigmas are honest (the predictive check).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..errors import SolverError
from ..graph.builder import FIXED_SIGMA, STATIC_TIME, FactorRecord, Problem
from ..graph.noise import gaussian
from ..solve import solve
from ..solve.batch import solve_batch
from ..solve.checks import check_constrained
from ..solve.factorization import linear_settings, resolved_ordering
from ..solve.identifiability import marginal_factors

HELD = "crossval:held"  # label of the priors that hold the static variables at their training estimate


def subproblem(problem: Problem, records: list[FactorRecord], values: gtsam.Values | None = None) -> Problem:
    """`problem` with only `records`, its variables those they touch (values from `values`, default the initial)."""
    source = problem.initial if values is None else values
    keys = sorted({k for r in records for k in r.factor.keys()})
    initial = gtsam.Values()
    for k in keys:
        initial.insert(k, problem.keys.decode(k)[0].vartype.read(source, k))
    return dataclasses.replace(problem, records=records, initial=initial,
                               key_time={k: problem.key_time[k] for k in keys}, _graph=None, _evaluator=None)


@dataclass
class Training:
    """A fold's calibration: the estimate, its fit and checks, and the training data's information on the
    static variables as linear factors (what the held-out prediction's uncertainty starts from)."""

    values: gtsam.Values
    chi2_per_dof: float | None
    rejection: str | None
    warnings: list[str]
    static: list[int]
    information: gtsam.GaussianFactorGraph


def train(problem: Problem, indices: list[int], settings: dict) -> Training:
    sub = subproblem(problem, [problem.records[i] for i in indices])
    result = solve(sub, {**settings, "marginals": False}, set())
    static = sorted(k for k, t in sub.key_time.items() if t == STATIC_TIME)
    information = marginal_factors(sub, result.values, static, result.factorization == "qr")
    return Training(result.values, result.chi2_per_dof, result.rejection,
                    [f"{w.name}: {w.message}" for w in result.warnings], static, information)


@dataclass
class Roles:
    """How a fold's held-out factors are used: entry label -> its stream names, and the reference streams."""

    streams: dict[str, tuple[str, ...]]
    reference: set[str]

    def predicted(self, label: str) -> bool:
        """An entry that reads streams, none of them a reference: its measurements are predicted."""
        names = self.streams.get(label, ())
        return bool(names) and not self.reference.intersection(names)


@dataclass
class Prediction:
    """One predicted measurement: its entry, time (s), unwhitened residual, its predicted covariance S, and
    e^T S^-1 e (nan where S could not be formed)."""

    label: str
    time: float
    residual: np.ndarray
    covariance: np.ndarray
    chi2: float


@dataclass
class HeldOut:
    predictions: list[Prediction] = field(default_factory=list)
    anchored: list[str] = field(default_factory=list)  # entries whose first measurements anchored the states
    unpredicted: int = 0  # predictions that read a variable the reference does not determine


def predict(problem: Problem, training: Training, indices: list[int], roles: Roles, settings: dict) -> HeldOut:
    """Solve the held-out states (module docstring) and predict the held-out measurements of `indices`."""
    records = [problem.records[i] for i in indices]
    used = [r for r in records if not roles.predicted(r.label)]
    targets = [r for r in records if roles.predicted(r.label)]
    if not any(r.label in roles.streams for r in used):
        raise SolverError("no measurement of the reference streams (" + ", ".join(sorted(roles.reference))
                          + ") in the held-out part: nothing to solve its states from")
    out = HeldOut()
    sub = _held_problem(problem, training, used)
    if not _determined(sub, settings):
        anchors = _anchors(problem, targets)
        sub = _held_problem(problem, training, used + anchors)
        if not anchors or not _determined(sub, settings):
            check_constrained(sub, sub.graph(), *linear_settings(settings))  # raises, naming the free directions
        out.anchored = sorted({r.label for r in anchors})
        targets = [r for r in targets if not any(r is a for a in anchors)]
        used = used + anchors
    ordering = resolved_ordering(settings["ordering"], sub.evaluator().largest_degree())
    solved = solve_batch(sub, {**settings, "ordering": ordering}).values
    values = gtsam.Values(solved)
    for k in training.static:
        if not values.exists(k):
            values.insert(k, problem.keys.decode(k)[0].vartype.read(training.values, k))
    marginals = _predictive_marginals(used, training, values)
    groups: dict[tuple[int, ...], list[FactorRecord]] = {}  # by the per-state variables read: one joint each
    for r in targets:
        keys = list(r.factor.keys())
        if not all(values.exists(k) for k in keys):
            out.unpredicted += 1
            continue
        groups.setdefault(tuple(sorted(k for k in keys if problem.key_time.get(k) != STATIC_TIME)), []).append(r)
    for group in groups.values():
        joint = marginals.jointMarginalCovariance(gtsam.KeyVector(list(dict.fromkeys(
            k for r in group for k in r.factor.keys()))))
        for r in group:
            dims = [problem.keys.decode(k)[0].vartype.dim for k in r.factor.keys()]
            out.predictions.append(_prediction(r, dims, values, joint))
    return out


def _held_problem(problem: Problem, training: Training, records: list[FactorRecord]) -> Problem:
    """The held-out solve: `records` plus a prior of FIXED_SIGMA holding each static variable they read at its
    training estimate (values: the training estimate and, for the states, the initializers')."""
    static = sorted({k for r in records for k in r.factor.keys() if problem.key_time.get(k) == STATIC_TIME})
    values = gtsam.Values(problem.initial)
    held = []
    for k in static:
        vartype = problem.keys.decode(k)[0].vartype
        value = vartype.read(training.values, k)
        values.update(k, value)
        held.append(FactorRecord(vartype.prior(k, value, gaussian([FIXED_SIGMA] * vartype.dim)), HELD, STATIC_TIME))
    return subproblem(problem, records + held, values)


def _determined(sub: Problem, settings: dict) -> bool:
    try:
        check_constrained(sub, sub.graph(), *linear_settings(settings))
    except SolverError:
        return False
    return True


def _anchors(problem: Problem, targets: list[FactorRecord]) -> list[FactorRecord]:
    """The predicted measurements at each robot's first held-out state (all their per-state variables at it)."""
    first: dict[str, float] = {}
    for r in targets:
        for k in r.factor.keys():
            t = problem.key_time.get(k, STATIC_TIME)
            if t != STATIC_TIME:
                robot = problem.keys.decode(k)[0].robot
                first[robot] = min(first.get(robot, np.inf), t)
    anchors = []
    for r in targets:
        states = [(problem.keys.decode(k)[0].robot, problem.key_time[k]) for k in r.factor.keys()
                  if problem.key_time.get(k, STATIC_TIME) != STATIC_TIME]
        if states and all(t == first[robot] for robot, t in states):
            anchors.append(r)
    return anchors


def _predictive_marginals(used: list[FactorRecord], training: Training, values: gtsam.Values) -> gtsam.Marginals:
    """Marginals of the held-out solve with the calibration free under the training data's information (linear
    factors at the training estimate, where the held-out solve holds it)."""
    graph = gtsam.NonlinearFactorGraph()
    for r in used:
        graph.add(r.factor)
    for i in range(training.information.size()):
        factor = training.information.at(i)
        if factor is not None:
            graph.add(gtsam.LinearContainerFactor(factor, training.values))
    return gtsam.Marginals(graph, values)


def _prediction(record: FactorRecord, dims: list[int], values: gtsam.Values, joint) -> Prediction:
    """The residual of `record` at the held-out estimate and its covariance S = D (I + A P A^T) D (A: the whitened
    Jacobian, D: the noise sigmas, P: the joint marginal of its variables, of tangent dimensions `dims`, from
    `joint`, a gtsam.JointMarginal over them and maybe more)."""
    factor = record.factor
    keys = list(factor.keys())
    residual = np.asarray(factor.unwhitenedError(values), float)
    jacobian = factor.linearize(values)
    a, b = jacobian.getA(), jacobian.getb()
    offsets = np.concatenate([[0], np.cumsum(dims)])
    p = np.zeros((offsets[-1], offsets[-1]))
    for i, ki in enumerate(keys):
        for j, kj in enumerate(keys):
            p[offsets[i]:offsets[i + 1], offsets[j]:offsets[j + 1]] = joint.at(ki, kj)
    whitened = np.eye(len(b)) + a @ p @ a.T
    d = np.asarray(factor.noiseModel().sigmas(), float)
    covariance = d[:, None] * whitened * d[None, :]
    chi2 = float(b @ np.linalg.solve(whitened, b))
    return Prediction(record.label, record.time, residual, covariance, chi2)
