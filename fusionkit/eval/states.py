"""Per-state variables of any family (poses, velocities, biases, joint vectors) as time series, and
their errors against truth: differences in the type's tangent space (vectors: plain differences), the
RMSE per axis and the share of errors inside 1/2/3 sigma per axis."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np

from ..data.association import nearest
from ..data.stream import Stream
from ..graph.keys import STATE
from ..graph.variables import VarType
from .trajectory import MATCH_TOLERANCE


@dataclass
class StateSeries:
    """One family of one robot at its states: times (s), values, 1-sigma per tangent axis (or None)."""

    robot: str
    family: str
    vartype: VarType
    t: np.ndarray
    values: list[Any]
    sigma: np.ndarray | None  # (n, dim)

    def stream(self) -> Stream:
        """The values as a stream: `t` and the type's components (e.g. c0..c5 for a vector6)."""
        rows = [self.vartype.to_list(v) for v in self.values]
        return Stream(f"{self.robot}.{self.family}", self.t, self.vartype.names()[0],
                      np.asarray(rows, float).reshape(len(self.t), -1))

    def table(self) -> tuple[list[str], np.ndarray]:
        """(columns, rows) of states/<robot>.<family>.csv: t, the components, sigma_<axis> when known."""
        values, axes = self.vartype.names()
        data = self.stream().values
        if self.sigma is None:
            return ["t", *values], np.column_stack([self.t, data])
        return ["t", *values, *(f"sigma_{a}" for a in axes)], np.column_stack([self.t, data, self.sigma])


def state_series(problem, values: gtsam.Values, covariances: dict[int, np.ndarray]) -> dict[tuple[str, str], StateSeries]:
    """Every per-state family of every robot, over the states a factor declared it at."""
    out = {}
    present = set(values.keys())
    for fam in problem.keys.families():
        if fam.kind != STATE or fam.robot not in problem.states:
            continue
        states = problem.states[fam.robot]
        ks = [k for k, key in enumerate(fam.keys(range(len(states)))) if key in present]
        if not ks:
            continue
        keys = fam.keys(ks)
        sigma = np.array([np.sqrt(np.diag(covariances[k])) for k in keys]) \
            if all(k in covariances for k in keys) else None
        out[(fam.robot, fam.name)] = StateSeries(fam.robot, fam.name, fam.vartype, states.t[ks],
                                                 [fam.vartype.read(values, k) for k in keys], sigma)
    return out


def _value(vartype: VarType, row: np.ndarray) -> Any:
    """A file row's value of the type (a type held as a float, as scalar, from the row's one number)."""
    return vartype.from_list(float(row[0]) if isinstance(vartype.zero(), float) else row)


def state_errors(series: StateSeries, truth: Stream) -> dict:
    """Errors of `series` at the states that have a truth sample within MATCH_TOLERANCE: the tangent
    vector from truth to estimate per state; its RMSE per axis; with sigmas, the share inside 1/2/3 sigma."""
    names = series.vartype.names()
    missing = [c for c in names[0] if c not in truth.columns]
    if missing:
        raise ValueError(f"truth of {series.robot}.{series.family} lacks column(s) {', '.join(missing)}")
    a = nearest(truth.t, series.t, MATCH_TOLERANCE)
    out: dict[str, Any] = {"states": len(series.t), "matched": int(len(a.row)), "axes": list(names[1])}
    if not len(a.row):
        return out
    rows = np.column_stack([truth.column(c) for c in names[0]])[a.state]
    err = np.array([series.vartype.local(_value(series.vartype, r), series.values[i]) for i, r in zip(a.row, rows)])
    out["rmse_per_axis"] = np.sqrt(np.mean(err ** 2, axis=0)).tolist()
    if series.sigma is not None:
        z = np.abs(err) / series.sigma[a.row]
        out["consistency_percent"] = {axis: {f"{n}sigma": float(np.mean(z[:, i] <= n) * 100) for n in (1, 2, 3)}
                                      for i, axis in enumerate(names[1])}
    return out
