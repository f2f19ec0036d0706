"""Python factors in iSAM2 and the fixed-lag smoother, linearized by fusionkit, never called from C++.

GTSAM's incremental solvers linearize factors from C++, where a Python factor costs a callback and a
copy of the whole Values per call (benchmarks/README.md, (a2)), and every few updates iSAM2
re-eliminates the whole tree in batch, linearizing every factor it holds again: in a fixed-lag window
of Python factors, a periodic slow step. Instead, each factor of a vectorized group
(graph/vectorized.py) and each plain Python factor (`gtsam.CustomFactor`) enters as a
`gtsam.LinearContainerFactor` holding its whitened Jacobian at the solver's linearization point theta,
which the solver evaluates natively (moved to another point to first order); a group is linearized
in one call, a Python factor by its own `linearize`. Native GTSAM factors enter as they are.

iSAM2 relinearizes a variable when, at the start of an update, its step delta (from the previous
solution) reaches `relinearize_threshold` in any component; its theta then becomes theta (+) delta, the
estimate handed out after the previous update. fusionkit applies the same test before each update and,
in that same update, swaps the factors on those variables for ones linearized at their new theta
(removed by index, re-added; one call per group). So the solver holds, at every update, the
linearizations it would have made itself: the same results as the factors handed over as CustomFactors
(tests: equal to 1e-12), with no callback into Python and no copy of the Values.

iSAM2 checks relinearization only at every `relinearizeSkip`-th update (`solver.relinearize_skip`), and never
moves the linearization point of a variable in its fixed set: those on the marginal factors the fixed-lag
smoother leaves when it marginalizes states (ISAM2::marginalizeLeaves), a static calibration parameter among them
as soon as the first state leaves the window. fusionkit mirrors both: a fixed variable's factors are linearized
at its frozen point, as GTSAM's own factors on it are, so each variable has one linearization point (the
consistency first-estimate Jacobians exist for). `solver.relinearize_marginal_variables: true` instead
linearizes the Python factors on fixed variables at their current estimate whenever their step passes the
threshold (fusionkit before commit d5a7bf9): two linearization points for one variable, and on a scaled-VO fixed-lag run
the scale's factors swapped at every update (benchmarks/bench_fixed_lag.py)."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..graph.evaluator import in_group
from ..graph.vectorized import ValueReader


def tracked(record) -> str | None:
    """How a factor enters an incremental solver: "group" (linearized with its vectorized group), "factor" (a
    Python factor linearized alone), None (a native factor, handed over as it is)."""
    if in_group(record):
        return "group"
    return "factor" if isinstance(record.factor, gtsam.CustomFactor) else None


def _fixed_variables(solver):
    """The variables whose linearization point iSAM2 holds (gtsam.ISAM2 or IncrementalFixedLagSmoother)."""
    isam = solver.getISAM2() if hasattr(solver, "getISAM2") else solver
    return isam.getFixedVariables()


def _entry(record, kind: str) -> tuple:
    """A tracked factor: (group, row, its variables) or (None, Python factor, its variables)."""
    if kind == "group":
        return record.group, record.row, tuple(record.group.keys[record.row].tolist())
    return None, record.factor, tuple(record.factor.keys())


@dataclass
class Step:
    """What one solver update adds: the factors in order, the tracked entries among them (their position in
    `graph` and the entry, see _entry) and the solver indices of factors to remove."""

    graph: gtsam.NonlinearFactorGraph = field(default_factory=gtsam.NonlinearFactorGraph)
    entries: list[tuple[int, tuple]] = field(default_factory=list)
    remove: list[int] = field(default_factory=list)


class LinearContainers:
    """Tracks the Python factors handed to one incremental solver: which solver index holds which entry
    (_entry), and which of them sit on each variable."""

    def __init__(self, threshold: float, vartype_of, skip: int = 1, relinearize_fixed: bool = False):
        self.threshold = threshold
        self.vartype_of = vartype_of  # key -> VarType
        self.skip = skip  # iSAM2's relinearizeSkip: the relinearization test runs at every skip-th update
        self.relinearize_fixed = relinearize_fixed  # solver.relinearize_marginal_variables
        self.updates = 0  # updates so far (iSAM2's update_count_)
        self.slot: dict[int, tuple] = {}  # solver factor index -> _entry
        self.on_key: dict[int, set[int]] = {}  # variable key -> solver indices of tracked factors on it
        self.swaps: list[int] = []  # per update: tracked factors removed and added again (relinearized)
        self.held_count: list[int] = []  # per update: tracked factors the solver held before it
        self.held: list[int] = []  # per update: fixed variables whose step passed the threshold, held (GTSAM's rule)
        self._dims: dict[int, int] = {}

    def relinearizing(self, delta: gtsam.VectorValues, keys: list[int], fixed=frozenset()) -> set[int]:
        """Those of `keys` the solver's next update relinearizes: iSAM2's test on the current step (largest
        component >= threshold), but for the variables in `fixed` (the solver's fixed set), whose linearization
        point iSAM2 never moves; with `relinearize_fixed` those pass it too (module docstring)."""
        if not keys:
            return set()
        dims = np.array([self.dim(k) for k in keys])
        step = np.abs(np.asarray(delta.vector(keys), dtype=float).ravel())  # the keys' steps, in their order
        largest = np.maximum.reduceat(step, np.concatenate([[0], np.cumsum(dims)[:-1]]))
        passed = {k for k, m in zip(keys, largest) if m >= self.threshold}
        if self.relinearize_fixed or not passed:
            return passed
        held = passed & set(fixed)  # a gtsam.KeySet: iterable
        self.held[-1] += len(held)
        return passed - held

    def dim(self, key: int) -> int:
        if key not in self._dims:
            self._dims[key] = self.vartype_of(key).dim
        return self._dims[key]

    def step(self, records, solver, new_values: gtsam.Values) -> Step:
        """The next update of `solver` (gtsam.ISAM2 or IncrementalFixedLagSmoother): `records`' native factors
        as they are, their Python ones and the tracked ones on variables the update relinearizes, linearized
        (one call per group) at theta as it will be after the update's relinearization: the current estimate
        for those variables, theta for the others, `new_values` for new variables."""
        self.updates += 1
        self.swaps.append(0)
        self.held.append(0)
        self.held_count.append(len(self.slot))
        out = Step()
        entries = []
        for r in records:
            kind = tracked(r)
            if kind is None:
                out.graph.add(r.factor)
            else:
                entries.append(_entry(r, kind))
        if not entries and not self.slot:
            return out
        delta = solver.getDelta()
        moving = set()
        if self.updates % self.skip == 0:  # iSAM2 checks relinearization at this update
            moving = self.relinearizing(delta, [k for k, on in self.on_key.items() if on], _fixed_variables(solver))
        swapped = sorted({i for k in moving for i in self.on_key.get(k, ())})
        self.swaps[-1] = len(swapped)
        for index in swapped:
            entry = self.slot.pop(index)
            for k in entry[2]:
                self.on_key[k].discard(index)
            out.remove.append(index)
            entries.append(entry)
        if not entries:
            return out
        at = self._linearization_point(solver.getLinearizationPoint(), delta, moving)  # a copy: only when needed
        at.insert(new_values)
        reader = ValueReader(at)
        by_group: dict[int, list[tuple]] = {}
        for entry in entries:
            if entry[0] is None:
                self._add(out, entry, entry[1].linearize(at), at)
            else:
                by_group.setdefault(id(entry[0]), []).append(entry)
        for group_entries in by_group.values():
            rows = np.asarray([row for _, row, _ in group_entries])
            for entry, linear in zip(group_entries, group_entries[0][0].subset(rows).linear_factors(reader)):
                self._add(out, entry, linear, at)
        return out

    def swap_statistics(self) -> dict:
        """Per update (those that held tracked factors): tracked factors relinearized (removed and added again),
        their share of those held, and fixed variables held at their frozen point although their step passed
        the threshold (report.json solver.relinearized_python_factors)."""
        held = np.asarray(self.held_count, dtype=float)
        swaps = np.asarray(self.swaps, dtype=float)
        some = held > 0
        if not some.any():
            return {}
        share = swaps[some] / held[some]
        return {"updates": int(some.sum()), "updates_with_swaps": int((swaps[some] > 0).sum()),
                "per_update_p50": float(np.median(swaps[some])),
                "per_update_max": int(swaps[some].max()), "share_p50": float(np.median(share)),
                "fixed_variables_held_per_update_p50": float(np.median(np.asarray(self.held)[some]))}

    @staticmethod
    def _linearization_point(theta: gtsam.Values, delta: gtsam.VectorValues, moving: set[int]) -> gtsam.Values:
        """theta with the variables in `moving` at theta (+) delta (the estimate the previous update handed
        out), in C++ (gtsam.Values.insert of a float costs ~35 us in its overload resolution); a copy of all
        of theta (LinearContainerFactor keeps only its own keys of it)."""
        steps = gtsam.VectorValues()
        for k in moving:
            steps.insert(k, delta.at(k))
        return theta.retract(steps)  # variables without a step are copied as they are

    @staticmethod
    def _add(out: Step, entry: tuple, linear: gtsam.GaussianFactor, at: gtsam.Values) -> None:
        out.entries.append((out.graph.size(), entry))
        # GTSAM keeps only the factor's own keys of the point it is given (LinearContainerFactor.cpp)
        out.graph.add(gtsam.LinearContainerFactor(linear, at))

    def added(self, step: Step, new_indices) -> None:
        """Record the solver indices the update gave the step's factors."""
        indices = list(new_indices)
        for position, entry in step.entries:
            index = int(indices[position])
            self.slot[index] = entry
            for k in entry[2]:
                self.on_key.setdefault(k, set()).add(index)

    def forget(self, keys) -> None:
        """Variables the smoother marginalized: it removed their factors itself."""
        for k in keys:
            for index in self.on_key.pop(k, set()):
                for other in self.slot.pop(index)[2]:
                    if other != k and other in self.on_key:
                        self.on_key[other].discard(index)
