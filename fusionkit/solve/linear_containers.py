"""Vectorized factors in iSAM2 and the fixed-lag smoother, without a Python call per factor.

GTSAM's incremental solvers linearize factors from C++, where a Python factor costs a callback and a
copy of the whole Values per call (benchmarks/README.md, (a2)). Instead, each factor of a vectorized
group (graph/vectorized.py) enters as a `gtsam.LinearContainerFactor`: its whitened Jacobian at an
estimate, which the solver re-evaluates natively, to first order, at any linearization point (b shifted
by A times the step). After each update, the factors on variables whose estimate has moved more than
`relinearize_threshold` (largest tangent component, iSAM2's own test) since they were linearized are
linearized again, in one call per group, and swapped in with the next update (removed by index and
re-added): iSAM2's relinearization rule, applied by fusionkit to the factors it evaluates."""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..graph.evaluator import MAX_VECTORIZED_VARIABLES
from ..graph.vectorized import ValueReader


@dataclass
class Step:
    """What one solver update adds: the factors in order, the grouped entries among them (their
    position in `graph`, group, row) and the factor indices to remove."""

    graph: gtsam.NonlinearFactorGraph = field(default_factory=gtsam.NonlinearFactorGraph)
    entries: list[tuple[int, object, int]] = field(default_factory=list)
    remove: list[int] = field(default_factory=list)


class LinearContainers:
    """Tracks the vectorized factors handed to one incremental solver: which solver index holds which
    (group, row), the value each variable had when its factors were last linearized, and what is due."""

    def __init__(self, threshold: float, vartype_of):
        self.threshold = threshold
        self.vartype_of = vartype_of  # key -> VarType
        self.slot: dict[int, tuple[object, int]] = {}  # solver factor index -> (group, row)
        self.on_key: dict[int, set[int]] = {}  # variable key -> solver indices of tracked factors on it
        self.point: dict[int, object] = {}  # variable key -> value at its factors' last linearization
        self.due: list[tuple[object, int]] = []  # (group, row) to linearize again with the next update
        self.retired: list[int] = []  # their old solver indices

    @staticmethod
    def vectorized(record) -> bool:
        return record.group is not None and len(record.group.residual.variables) <= MAX_VECTORIZED_VARIABLES

    def step(self, records, estimate: gtsam.Values, new_values: gtsam.Values) -> Step:
        """The update for `records` (plus the factors due again): plain factors as they are, vectorized ones
        linearized at the estimate (new variables at `new_values`) in one call per group."""
        out = Step(remove=self.retired)
        grouped = list(self.due)
        for r in records:
            if self.vectorized(r):
                grouped.append((r.group, r.row))
            else:
                out.graph.add(r.factor)
        self.due, self.retired = [], []
        if not grouped:
            return out
        at = self._values_at([k for g, row in grouped for k in g.keys[row].tolist()], estimate, new_values)
        reader = ValueReader(at)
        by_group: dict[int, tuple[object, list[int]]] = {}
        for g, row in grouped:
            by_group.setdefault(id(g), (g, []))[1].append(row)
        for g, rows in by_group.values():
            for row, linear in zip(rows, g.subset(np.asarray(rows)).linear_factors(reader)):
                keys = g.keys[row].tolist()
                point = gtsam.Values()
                for k in keys:
                    point.insert(k, self.vartype_of(k).read(at, k))
                    self.point.setdefault(k, self.vartype_of(k).read(at, k))
                out.entries.append((out.graph.size(), g, row))
                out.graph.add(gtsam.LinearContainerFactor(linear, point))
        return out

    def _values_at(self, keys: list[int], estimate: gtsam.Values, new_values: gtsam.Values) -> gtsam.Values:
        at = gtsam.Values()
        for k in dict.fromkeys(keys):
            source = estimate if estimate.exists(k) else new_values
            at.insert(k, self.vartype_of(k).read(source, k))
        return at

    def added(self, step: Step, new_indices) -> None:
        """Record the solver indices the update gave the step's factors."""
        indices = list(new_indices)
        for position, g, row in step.entries:
            index = int(indices[position])
            self.slot[index] = (g, row)
            for k in g.keys[row].tolist():
                self.on_key.setdefault(k, set()).add(index)

    def review(self, estimate: gtsam.Values, candidates) -> bool:
        """After an update: the tracked factors on any of `candidates` (keys the solver touched) whose
        estimate moved past the threshold are due again; returns whether any is."""
        moved = []
        for k in candidates:
            if k not in self.point or not estimate.exists(k):
                continue
            vt = self.vartype_of(k)
            now = vt.read(estimate, k)
            if np.max(np.abs(vt.local(self.point[k], now))) > self.threshold:
                moved.append(k)
                self.point[k] = now
        for index in sorted({i for k in moved for i in self.on_key.get(k, ())}):
            g, row = self.slot.pop(index)
            for k in g.keys[row].tolist():
                self.on_key[k].discard(index)
            self.due.append((g, row))
            self.retired.append(index)
        return bool(self.due)

    def forget(self, keys) -> None:
        """Variables the smoother marginalized: it removed their factors itself."""
        for k in keys:
            for index in self.on_key.pop(k, set()):
                g, row = self.slot.pop(index)
                for other in g.keys[row].tolist():
                    if other != k and other in self.on_key:
                        self.on_key[other].discard(index)
            self.point.pop(k, None)
