"""Vectorized factors in iSAM2 and the fixed-lag smoother, without a Python call per factor.

GTSAM's incremental solvers linearize factors from C++, where a Python factor costs a callback and a
copy of the whole Values per call (benchmarks/README.md, (a2)). Instead, each factor of a vectorized
group (graph/vectorized.py) enters as a `gtsam.LinearContainerFactor` holding its whitened Jacobian at
the solver's linearization point theta, which the solver evaluates natively.

iSAM2 relinearizes a variable when, at the start of an update, its step delta (from the previous
solution) reaches `relinearize_threshold` in any component; its theta then becomes theta (+) delta, the
estimate handed out after the previous update. fusionkit applies the same test before each update and,
in that same update, swaps the factors on those variables for ones linearized at their new theta
(removed by index, re-added; one call per group). So the solver holds, at every update, the
linearizations it would have made itself: the same results as the factors as CustomFactors (tests), with
no callback into Python and no copy of the Values."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..graph.evaluator import in_group
from ..graph.vectorized import ValueReader


@dataclass
class Step:
    """What one solver update adds: the factors in order, the grouped entries among them (their
    position in `graph`, group, row) and the solver indices of factors to remove."""

    graph: gtsam.NonlinearFactorGraph = field(default_factory=gtsam.NonlinearFactorGraph)
    entries: list[tuple[int, object, int]] = field(default_factory=list)
    remove: list[int] = field(default_factory=list)


class LinearContainers:
    """Tracks the vectorized factors handed to one incremental solver: which solver index holds which
    (group, row), and which of them sit on each variable."""

    def __init__(self, threshold: float, vartype_of):
        self.threshold = threshold
        self.vartype_of = vartype_of  # key -> VarType
        self.slot: dict[int, tuple[object, int]] = {}  # solver factor index -> (group, row)
        self.on_key: dict[int, set[int]] = {}  # variable key -> solver indices of tracked factors on it
        self._dims: dict[int, int] = {}

    def relinearizing(self, delta: gtsam.VectorValues) -> set[int]:
        """The variables with tracked factors that the solver's next update relinearizes (iSAM2's test on
        the current step: largest component >= threshold)."""
        keys = [k for k, on in self.on_key.items() if on]
        if not keys:
            return set()
        dims = np.array([self.dim(k) for k in keys])
        step = np.abs(np.asarray(delta.vector(keys), dtype=float).ravel())  # the keys' steps, in their order
        largest = np.maximum.reduceat(step, np.concatenate([[0], np.cumsum(dims)[:-1]]))
        return {k for k, m in zip(keys, largest) if m >= self.threshold}

    def dim(self, key: int) -> int:
        if key not in self._dims:
            self._dims[key] = self.vartype_of(key).dim
        return self._dims[key]

    def step(self, records, solver, new_values: gtsam.Values) -> Step:
        """The next update of `solver` (gtsam.ISAM2 or IncrementalFixedLagSmoother): `records`' plain factors
        as they are, their vectorized ones and the tracked ones on variables the update relinearizes,
        linearized in one call per group at theta as it will be after the update's relinearization: the
        current estimate for those variables, theta for the others, `new_values` for new variables."""
        out = Step()
        delta = solver.getDelta() if self.slot else None
        moving = self.relinearizing(delta) if delta is not None else set()
        grouped = []
        for index in sorted({i for k in moving for i in self.on_key.get(k, ())}):
            g, row = self.slot.pop(index)
            for k in g.keys[row].tolist():
                self.on_key[k].discard(index)
            out.remove.append(index)
            grouped.append((g, row))
        for r in records:
            if in_group(r):
                grouped.append((r.group, r.row))
            else:
                out.graph.add(r.factor)
        if not grouped:
            return out
        theta = solver.getLinearizationPoint()
        relinearized = gtsam.Values()  # theta (+) delta of the variables the update relinearizes
        for k in moving:
            relinearized.insert(k, self.vartype_of(k).read(theta, k))
        if moving:
            relinearized = relinearized.retract(delta)
        at = gtsam.Values()
        for k in dict.fromkeys(k for g, row in grouped for k in g.keys[row].tolist()):
            source = relinearized if k in moving else theta if theta.exists(k) else new_values
            at.insert(k, self.vartype_of(k).read(source, k))
        reader = ValueReader(at)
        by_group: dict[int, tuple[object, list[int]]] = {}
        for g, row in grouped:
            by_group.setdefault(id(g), (g, []))[1].append(row)
        for g, rows in by_group.values():
            for row, linear in zip(rows, g.subset(np.asarray(rows)).linear_factors(reader)):
                out.entries.append((out.graph.size(), g, row))
                # GTSAM keeps only the factor's own keys of the point it is given (LinearContainerFactor.cpp)
                out.graph.add(gtsam.LinearContainerFactor(linear, at))
        return out

    def added(self, step: Step, new_indices) -> None:
        """Record the solver indices the update gave the step's factors."""
        indices = list(new_indices)
        for position, g, row in step.entries:
            index = int(indices[position])
            self.slot[index] = (g, row)
            for k in g.keys[row].tolist():
                self.on_key.setdefault(k, set()).add(index)

    def forget(self, keys) -> None:
        """Variables the smoother marginalized: it removed their factors itself."""
        for k in keys:
            for index in self.on_key.pop(k, set()):
                g, row = self.slot.pop(index)
                for other in g.keys[row].tolist():
                    if other != k and other in self.on_key:
                        self.on_key[other].discard(index)
