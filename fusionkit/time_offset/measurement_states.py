"""Measurement-time states: what a factor entry with a `time_offset:` is given instead of the nearest state.

`ctx.associate` pairs each sample of such an entry (stamp t, inside the states' span at the offset's
value in the description) with a measurement-time state of its own, numbered after the robot's states
(index len(states) + i), so the factor's code does not change: `ctx.state_key` (`pose_key`,
`state_keys`) gives it a key of its own for the robot's state at the sample's time, `ctx.state_time`
the time of the later state of its pair, and per-state variables and time-varying parameters at that
index are those of the nearest state (`ctx.state_index`). Entries with the same offset share the key
for samples with the same stamp.

That key is no variable: after the initializers (which may set the offset, `time.offset_guess`),
`finish()` replaces every factor on it by a shifted factor (interpolation.shifted_factor) that evaluates
the factor with the state on the curve through a window of up to four states around t + offset, at the
time of the window's last state (incremental solvers add it once that state exists). A sample that the
initial offset moves outside the states is left out. `beyond_windows()` tells, after solving, which
estimates moved samples past their windows.
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from ..data.association import Association
from ..data.stream import Stream
from ..errors import DataError
from ..graph.keys import MEASUREMENT, STATE
from ..graph.variables import POSE3, VELOCITY3
from .config import TimeOffset
from .interpolation import Shift, Timing, interpolate, shifted_factor

WINDOW_MARGIN = 1  # states added on each side of the build-time pair


@dataclass
class MeasurementState:
    """One sample's state at its own time: robot, offset, stamp (s, sensor clock), the robot's state nearest
    to it and the later state of its pair at build time, the margin; its key and shift once used."""

    robot: str
    offset: TimeOffset
    stamp: float
    nearest: int
    upper: int
    margin: float  # s: how far outside the states' span it may lie (the entry's tolerance)
    key: int | None = None
    shift: Shift | None = None


class MeasurementStates:
    """The measurement-time states of a BuildContext."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.items: dict[str, list[MeasurementState]] = {}  # robot -> its measurement states (index - len(states))
        self._index: dict[tuple, int] = {}  # (robot, offset, stamp) -> position in items[robot]
        self.by_key: dict[int, MeasurementState] = {}
        self.labels: set[str] = set()  # entries that asked for a time offset

    # --- during building ---------------------------------------------------------------------
    def _initial(self, robot: str, name: str | None) -> float:
        """A parameter's value in the description (0 until an initializer sets one it lacks)."""
        if name is None:
            return 0.0
        param = self.ctx.robot(robot).parameters[name]
        return float(param.values[0]) if param.known else 0.0

    def associate(self, stream: Stream, robot: str, spec, offset: TimeOffset) -> Association:
        """Every sample whose time t + offset lies inside the robot's states (or within the entry's `tolerance`
        of their span), each with its measurement state."""
        t = self.ctx.state_set(robot, spec).t
        margin = float(spec.get("tolerance", 0.0))
        if len(t) < 2:
            raise DataError(f"{spec.label}: robot {robot!r} has {len(t)} state(s); a time offset interpolates "
                            "between two")
        self.labels.add(spec.label)
        tau = stream.t + self._initial(offset.robot, offset.parameter) + \
            self._initial(offset.robot, offset.rate) * (stream.t - t[0])
        rows = np.flatnonzero((tau >= t[0] - margin) & (tau <= t[-1] + margin))
        upper = np.clip(np.searchsorted(t, tau[rows], side="right"), 1, len(t) - 1)
        nearest = np.where(tau[rows] - t[upper - 1] <= t[upper] - tau[rows], upper - 1, upper)
        items = self.items.setdefault(robot, [])
        index = np.empty(len(rows), dtype=np.int64)
        for i, (row, up, near) in enumerate(zip(rows.tolist(), upper.tolist(), nearest.tolist())):
            stamp = float(stream.t[row])
            found = self._index.get((robot, offset, stamp))
            if found is None:
                found = self._index[(robot, offset, stamp)] = len(items)
                items.append(MeasurementState(robot, offset, stamp, near, up, margin))
            index[i] = found
        unmatched = len(stream) - len(rows)
        note = (f"{spec.label}: {unmatched} of {len(stream)} samples of stream {stream.name!r} lie outside the states "
                f"of {robot!r} (by more than {margin} s) at time offset {offset.label} and were not used")
        if unmatched and note not in self.ctx.notes:  # an entry may associate the same stream more than once
            self.ctx.notes.append(note)
        return Association(len(t) + index, rows, unmatched)

    def get(self, robot: str, k: int) -> MeasurementState:
        return self.items[robot][k - len(self.ctx.states[robot])]

    def key(self, robot: str, k: int) -> int:
        """The key that stands for the robot's state at measurement state k's time (not a variable)."""
        m = self.get(robot, k)
        if m.key is None:
            states = self.ctx.states[robot]
            own = m.offset.robot == robot
            name = f"{states.family.name}@{m.offset.parameter if own else m.offset.robot + '.' + m.offset.parameter}"
            m.key = self.ctx.keys.family(robot, name, states.family.vartype, MEASUREMENT).key(k - len(states))
            self.by_key[m.key] = m
        return m.key

    # --- after the initializers --------------------------------------------------------------
    def _parameter_key(self, m: MeasurementState, name: str | None) -> int | None:
        if name is None:
            return None
        owner = m.offset.robot
        if not self.ctx.robot(owner).parameters[name].time_varying:
            return self.ctx.parameter(owner, name)
        k = m.nearest if owner == m.robot else \
            int(np.argmin(np.abs(self.ctx.states[owner].t - m.stamp)))
        return self.ctx.parameter(owner, name, None, k)

    def _shift(self, m: MeasurementState) -> Shift | None:
        """The shift of a used measurement state at the offset's initial value; None when that puts it
        outside the states."""
        ctx, states = self.ctx, self.ctx.states[m.robot]
        t = states.t
        offset, rate = self._parameter_key(m, m.offset.parameter), self._parameter_key(m, m.offset.rate)
        rho = 0.0 if rate is None else ctx.initial_value(rate)
        tau = m.stamp + ctx.initial_value(offset) + rho * (m.stamp - t[0])
        if not t[0] - m.margin <= tau <= t[-1] + m.margin:
            return None
        j = int(np.clip(np.searchsorted(t, tau, side="right") - 1, 0, len(t) - 2))
        window = list(range(max(j - WINDOW_MARGIN, 0), min(j + 2 + WINDOW_MARGIN, len(t))))
        return Shift(m.key, states.family.vartype, Timing(m.stamp, float(t[0]), t[window]),
                     tuple(ctx.state_keys(m.robot, window)), offset, rate, self._velocities(m, [j, j + 1]),
                     j - window[0])

    def _velocities(self, m: MeasurementState, pair: list[int]) -> tuple[int, int] | None:
        """The keys of the pair's world-frame velocities: Pose3 states of a robot with one per-state
        velocity3 variable family (imu.preintegrated's) that covers the pair; None otherwise, or with
        `velocities: false`."""
        states = self.ctx.states[m.robot]
        if not m.offset.velocities or states.family.vartype.name != POSE3.name:
            return None
        families = [f for f in self.ctx.keys.families()
                    if f.robot == m.robot and f.kind == STATE and f.vartype.name == VELOCITY3.name]
        if len(families) != 1:
            return None
        keys = tuple(families[0].keys(pair))
        return keys if all(self.ctx.has_variable(k) for k in keys) else None

    def finish(self) -> None:
        """Replace every factor on a measurement-time key by its shifted factor; leave out those whose sample
        the offset's initial value (an initializer's guess) moves outside the states."""
        ctx = self.ctx
        if not self.by_key:
            return
        outside: dict[int, str] = {}
        for key, m in self.by_key.items():
            m.shift = self._shift(m)
            if m.shift is None:
                outside[key] = m.offset.label
        vartype_of = lambda key: ctx.keys.decode(key)[0].vartype  # noqa: E731
        kept, left_out = [], set()
        for r in ctx.records:
            if r.label in self.labels:
                shifts = [self.by_key[k].shift for k in r.factor.keys() if k in self.by_key]
                if None in shifts:
                    left_out.update(r.factor.keys())
                    continue
                if shifts:
                    r.factor = shifted_factor(r.factor, shifts, vartype_of)
                    r.group = None  # now a factor of its own: evaluated through gtsam, not with its group
                    r.time = max(r.time, *(ctx.key_time[sh.window[-1]] for sh in shifts))
            kept.append(r)
        ctx.records[:] = kept
        self._drop_orphans(left_out)
        for label in sorted(set(outside.values())):
            count = sum(v == label for v in outside.values())
            ctx.notes.append(f"time offset {label}: {count} sample(s) lie outside the states at the offset's initial "
                             "value and were not used")

    def _drop_orphans(self, keys: set[int]) -> None:
        """Per-state variables (a state's velocity, force, correction: not the states themselves) that only the
        left-out factors used go with them: declared for those samples, nothing else determines them."""
        ctx = self.ctx
        used = {k for r in ctx.records for k in r.factor.keys()}
        own = {states.family for states in ctx.states.values()}
        orphans = [k for k in sorted(keys) if k not in used and k not in self.by_key and ctx.has_variable(k)
                   and ctx.keys.decode(k)[0].kind == STATE and ctx.keys.decode(k)[0] not in own]
        for k in orphans:
            ctx.forget(k)
        if orphans:
            names = sorted({ctx.keys.decode(k)[0].name for k in orphans})
            ctx.notes.append(f"{len(orphans)} per-state variable(s) ({', '.join(names)}) used only by those samples "
                             "were left out with them")

    def initial_value(self, key: int):
        """The state a measurement-time key stands for, on the curve through the initial values."""
        m = self.by_key[key]
        sh = m.shift or self._shift(m)
        if sh is None:
            raise KeyError(f"{self.ctx.keys.name_of(key)} lies outside the states")
        rho = 0.0 if sh.rate is None else self.ctx.initial_value(sh.rate)
        velocities = None if sh.velocities is None else [self.ctx.initial_value(k) for k in sh.velocities]
        return interpolate(sh.vartype, sh.timing.window_t, [self.ctx.initial_value(k) for k in sh.window],
                           sh.timing.tau(self.ctx.initial_value(sh.offset), rho), velocities, sh.pair)

    # --- after solving -----------------------------------------------------------------------
    def beyond_windows(self, values: gtsam.Values) -> list[str]:
        """A note per offset whose estimate moved samples past the states their curve was built on."""
        out: dict[str, list] = {}
        for m in self.by_key.values():
            if m.shift is None:
                continue
            t, sh = self.ctx.states[m.robot].t, m.shift
            delta = values.atDouble(sh.offset)
            tau, w = sh.timing.tau(delta, 0.0 if sh.rate is None else values.atDouble(sh.rate)), sh.timing.window_t
            lo = w[0] - (m.margin if w[0] == t[0] else 0.0)  # the trajectory's ends: the entry's tolerance
            hi = w[-1] + (m.margin if w[-1] == t[-1] else 0.0)
            count = out.setdefault(m.offset.label, [0, 0, delta])
            count[0] += not lo <= tau <= hi
            count[1] += 1
        return [f"time offset {label}: the estimate {delta:.6g} s moves {n} of {total} samples past the states "
                f"their interpolation was built on (within {WINDOW_MARGIN} state interval(s) of the pair at the "
                "initial offset); those were extrapolated: start from this estimate (its `value:` in the robot "
                "description, or a time.offset_guess initializer) and run again"
                for label, (n, total, delta) in out.items() if n]
