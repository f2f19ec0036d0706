"""Which data train and which are held out: the units of a recording (its samples, or blocks of time), the
folds they form, and each factor record's place in a fold.

A unit is one state time (`sample`: a static configuration, a frame) or one block of time (`segment`: a
stretch of trajectory, a run of several recordings laid end to end). A factor belongs to the units of the
times of its per-state variables (static parameters have none: their priors and pseudo-measurements always
train). In a fold, a factor whose units are all held out is held out, one whose units all train trains, and
one that links a training unit with a held-out one (odometry across the cut) is in neither: no information
crosses the cut.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from ..data.recordings import gaps
from ..graph.builder import STATIC_TIME, Problem, record_times

BY = ("sample", "segment", "file")  # and "auto", the default
CUT_TOLERANCE = 1e-6  # s: a state this close before a segment boundary belongs to the segment after it


@dataclass(frozen=True)
class Plan:
    """How to cut: `by` sample, segment, file or auto (files when a source reads several recordings, else segments
    when a factor links two state times, else samples); `folds` K, or `leave_one_out`, or `split` (the training
    share, the first part in time); `cuts`: segment boundaries (s) instead of K equal blocks."""

    by: str
    folds: int | None = None
    leave_one_out: bool = False
    split: float | None = None
    cuts: tuple[float, ...] = ()

    def describe(self) -> str:
        if self.by == "file":
            return "leave one recording (file) out"
        if self.split is not None:
            return f"train on the first {self.split:.0%} ({self.by}s), predict the rest"
        if self.leave_one_out:
            return f"leave one {self.by} out"
        return f"{self.folds} folds by {self.by}"


@dataclass(frozen=True)
class Units:
    """The units of a problem: `labels` (a time in s, or a block [start, end) in s) and, per record, the
    units of its per-state variables (empty: static only); `plan` with `by` resolved."""

    plan: Plan
    labels: list[str]
    of_record: list[np.ndarray]  # per record: its units (sorted, unique)


def state_times(problem: Problem) -> np.ndarray:
    """The distinct times (s) of the problem's per-state variables."""
    return np.unique([t for t in problem.key_time.values() if t != STATIC_TIME])


def units(problem: Problem, plan: Plan) -> Units:
    times = state_times(problem)
    if len(times) < 2:
        raise ConfigError(f"crossval needs at least two state times to hold some out; the problem has {len(times)}")
    if plan.by == "file" or (plan.by == "auto" and plan.split is None):
        cuts = recording_cuts(problem)
        if cuts:
            plan = dataclasses.replace(plan, by="file", cuts=cuts)
        elif plan.by == "file":
            raise ConfigError("--by file: every source reads one file; give the recordings as a list (`path: [a.csv, "
                              "b.csv]`), or hold out stretches of time (--by segment)")
    if plan.by in ("auto", "sample"):
        samples = _units(problem, times, np.concatenate([times, [np.inf]]))
        if plan.by == "auto":
            plan = dataclasses.replace(plan, by="segment" if any(len(u) > 1 for u in samples) else "sample")
        if plan.by == "sample":
            return Units(plan, [f"t = {t:g} s" for t in times], samples)
    if plan.leave_one_out and not plan.cuts:
        raise ConfigError("--leave-one-out by segment (a factor links consecutive states): name the segments with "
                          "--cuts T1,T2,... or use --folds K for K equal stretches of time")
    edges = _segment_edges(times, plan)
    labels = [f"t = {a:g} .. {b:g} s" for a, b in zip(edges[:-1], edges[1:])]
    return Units(plan, labels, _units(problem, times, edges))


def recording_cuts(problem: Problem) -> tuple[float, ...]:
    """Where the recordings of a source given several files meet: the middle of each gap between them (the gaps
    of all such streams, overlapping ones merged)."""
    merged: list[list[float]] = []
    for end, start in gaps(problem.context.streams) if problem.context is not None else []:
        if merged and end <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], start)
        else:
            merged.append([end, start])
    return tuple(0.5 * (end + start) for end, start in merged)


def _units(problem: Problem, times: np.ndarray, edges: np.ndarray) -> list[np.ndarray]:
    """Per record, the units (between consecutive `edges`) of its per-state variables' times."""
    inner = np.concatenate([edges[:-1] - CUT_TOLERANCE, [np.inf]])  # the last unit ends past the last state
    unit = np.searchsorted(inner, times, side="right") - 1
    unit_of_time = dict(zip(times.tolist(), unit.tolist()))
    out = []
    for r in problem.records:
        out.append(np.array(sorted({unit_of_time[t] for t in record_times(r, problem.key_time)}), int))
    return out


def _segment_edges(times: np.ndarray, plan: Plan) -> np.ndarray:
    """Block boundaries from the first state time to past the last: the given cuts, a split, or K equal blocks."""
    first, last = float(times[0]), float(times[-1])
    end = np.nextafter(last, np.inf)
    if plan.cuts:
        inside = [c for c in plan.cuts if first < c <= last]
        if len(inside) != len(plan.cuts):
            raise ConfigError(f"--cuts {','.join(f'{c:g}' for c in plan.cuts)}: expected times inside the states' "
                              f"span t = {first:g} .. {last:g} s (exclusive of the first)")
        return np.array([first, *sorted(inside), end])
    if plan.split is not None:
        return np.array([first, first + plan.split * (last - first), end])
    return np.linspace(first, end, plan.folds + 1)


def folds(plan: Plan, count: int) -> list[np.ndarray]:
    """The held-out units of each fold, of `count` units (time-ordered)."""
    if plan.split is not None:
        if plan.by == "segment":
            return [np.array([1])]
        keep = int(round(plan.split * count))
        if not 0 < keep < count:
            raise ConfigError(f"--split {plan.split}: leaves no {'held-out' if keep >= count else 'training'} sample "
                              f"of {count}")
        return [np.arange(keep, count)]
    if plan.leave_one_out or plan.by in ("segment", "file"):  # segments, recordings: each is one fold
        return [np.array([u]) for u in range(count)]
    if not 2 <= plan.folds <= count:
        raise ConfigError(f"--folds {plan.folds}: expected 2 .. {count} (the problem has {count} samples)")
    return [np.arange(k, count, plan.folds) for k in range(plan.folds)]  # interleaved: every K-th sample


def partition(of_record: list[np.ndarray], held: np.ndarray) -> tuple[list[int], list[int], int]:
    """(training record indices, held-out record indices, records linking the two, in neither)."""
    held_set = set(held.tolist())
    train, out, across = [], [], 0
    for i, us in enumerate(of_record):
        inside = [u in held_set for u in us.tolist()]
        if all(inside) and inside:
            out.append(i)
        elif not any(inside):
            train.append(i)
        else:
            across += 1
    return train, out, across
