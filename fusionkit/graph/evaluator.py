"""The graph's cost and linearization for fusionkit's own solvers and reports: plain factors through
gtsam, each vectorized group in one call of its residual (graph/vectorized.py)."""

from __future__ import annotations

import gtsam
import numpy as np

from .passes import evaluation_pass
from .vectorized import ValueReader, VectorizedGroup

MAX_VECTORIZED_VARIABLES = 3  # GTSAM's Python bindings build Jacobian factors of at most three blocks


def in_group(record) -> bool:
    """Whether fusionkit linearizes this record's factor with its group (else through gtsam, alone)."""
    return record.group is not None and len(record.group.residual.variables) <= MAX_VECTORIZED_VARIABLES


class GraphEvaluator:
    """`linearize(values)` and `error(values)` of a list of FactorRecords, as a NonlinearFactorGraph of
    the same factors gives them (equal to rounding; the linear factors come in another order), and
    each record's error and unwhitened residual."""

    def __init__(self, records):
        self.records = records
        self.plain = gtsam.NonlinearFactorGraph()
        self.plain_rows: list[int] = []  # record index of each plain factor
        members: dict[int, tuple[VectorizedGroup, list[int], list[int]]] = {}
        for i, r in enumerate(records):
            if in_group(r):
                entry = members.setdefault(id(r.group), (r.group, [], []))
                entry[1].append(r.row)
                entry[2].append(i)
            else:
                self.plain.add(r.factor)
                self.plain_rows.append(i)
        self.groups = [(group.subset(np.asarray(rows)), np.asarray(indices)) for group, rows, indices in members.values()]

    def largest_degree(self) -> int:
        """The most factors any one variable is in."""
        counts: dict[int, int] = {}
        for i in self.plain_rows:
            for k in self.records[i].factor.keys():
                counts[k] = counts.get(k, 0) + 1
        for group, _ in self.groups:
            keys, n = np.unique(group.keys, return_counts=True)  # a key twice in one factor counts twice
            for k, c in zip(keys.tolist(), n.tolist()):
                counts[k] = counts.get(k, 0) + c
        return max(counts.values(), default=0)

    def linearize(self, values: gtsam.Values) -> gtsam.GaussianFactorGraph:
        with evaluation_pass(values):
            linear = self.plain.linearize(values)
        reader = ValueReader(values)
        for group, _ in self.groups:
            for factor in group.linear_factors(reader):
                linear.push_back(factor)
        return linear

    def linear_order(self) -> list[int]:
        """The record index of each factor of `linearize`'s graph, in its order."""
        return self.plain_rows + [int(i) for _, indices in self.groups for i in indices]

    def error(self, values: gtsam.Values) -> float:
        reader = ValueReader(values)
        with evaluation_pass(values):
            plain = self.plain.error(values)
        return float(plain + sum(float(np.sum(g.errors(reader))) for g, _ in self.groups))

    def record_errors(self, values: gtsam.Values) -> np.ndarray:
        """Each record's error (0.5 |whitened residual|^2, or its kernel's loss), in record order."""
        out = np.empty(len(self.records))
        with evaluation_pass(values):
            for i in self.plain_rows:
                out[i] = self.records[i].factor.error(values)
        reader = ValueReader(values)
        for group, indices in self.groups:
            out[indices] = group.errors(reader)
        return out

    def record_residuals(self, values: gtsam.Values) -> list[np.ndarray]:
        """Each record's unwhitened residual, in record order."""
        out: list[np.ndarray] = [np.empty(0)] * len(self.records)
        with evaluation_pass(values):
            for i in self.plain_rows:
                out[i] = np.asarray(self.records[i].factor.unwhitenedError(values), dtype=float)
        reader = ValueReader(values)
        for group, indices in self.groups:
            for i, r in zip(indices, group.residuals(reader)):
                out[i] = r
        return out
