"""Graph builder: the context factor and initializer plugins use to declare variables and factors."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import gtsam
import numpy as np

from ..components import Spec
from ..config.loader import RunConfig
from ..data.association import Association, nearest
from ..data.stream import Stream
from ..errors import PluginError
from ..descriptions.description import Parameter, RobotDescription
from ..time_offset.config import TimeOffset
from ..time_offset.measurement_states import MeasurementStates
from .keys import STATE, STATIC, TIME_VARYING, Family, KeyRegistry
from .noise import gaussian, noise_scale, with_kernel
from ..plugins import variable_type
from .variables import POSE3, VarType
from .evaluator import GraphEvaluator
from .vectorized import InstanceCache, VectorizedGroup, VectorizedResidual

STATIC_TIME = float("-inf")
FIXED_SIGMA = 1e-9  # prior sigma (per tangent axis, SI units) that holds a `fixed: true` parameter


def state_times(states: dict, streams: dict[str, Stream]) -> np.ndarray:
    """The times (s) of a robot's states from its (completed) `states:` settings: every `every`-th
    stamp of `stream` (those in [`start`, `end`] when given), or `rate` Hz from `start` to `end` (default: the
    stream's first and last stamp)."""
    if "rate" not in states:
        t = streams[states["stream"]].t
        t = t[(t >= states.get("start", -np.inf)) & (t <= states.get("end", np.inf))]
        return t[:: states.get("every", 1)]
    span = streams[states["stream"]].t if "stream" in states else None
    start = states.get("start", span[0] if span is not None else 0.0)
    end = states.get("end", span[-1] if span is not None else start)
    count = int(np.floor((end - start) * states["rate"] + 1e-9)) + 1
    return start + np.arange(count) / states["rate"]


@dataclass
class StateSet:
    """The states of one robot: times (s) from its clock stream and the pose family."""

    robot: str
    t: np.ndarray
    family: Family

    def __len__(self) -> int:
        return len(self.t)

    def key(self, k: int) -> int:
        return self.family.key(k)


def record_times(record: "FactorRecord", key_time: dict[int, float]) -> list[float]:
    """The times (s) of the per-state variables a record's factor reads (static variables left out)."""
    return [t for t in (key_time.get(k, STATIC_TIME) for k in record.factor.keys()) if t != STATIC_TIME]


@dataclass(slots=True)
class FactorRecord:
    """A factor with the entry that made it and the time at which an incremental solver adds it;
    a vectorized factor also names its group and its row there (fusionkit's solvers linearize the
    group in one call)."""

    factor: gtsam.NonlinearFactor
    label: str
    time: float
    group: VectorizedGroup | None = None
    row: int = -1
    part: str | None = None  # a named part of the entry with the plugin's own noise (`ctx.add(..., part=)`)


@dataclass(frozen=True)
class Held:
    """Tangent axes of a variable a factor holds at a value the data do not determine (`BuildContext.hold`):
    reports print `held (reason)` for them, not the value and the hold's tiny sigma."""

    axes: tuple[int, ...]  # tangent axes, ascending
    reason: str            # e.g. "not identifiable with base.rz"
    labels: tuple[str, ...] = ()  # the axes' names (`tx`), one per axis; () for a scalar


@dataclass
class Problem:
    """Everything the solver needs, plus what reports need to name things."""

    records: list[FactorRecord]
    initial: gtsam.Values
    keys: KeyRegistry
    states: dict[str, StateSet]
    key_time: dict[int, float]
    notes: list[str] = field(default_factory=list)
    diagnostics: dict[str, dict] = field(default_factory=dict)
    plots: dict[str, Callable[[Path], None]] = field(default_factory=dict)
    fixed_keys: set[int] = field(default_factory=set)  # `fixed: true` parameters: held, not estimated
    value_source: dict[str, str] = field(default_factory=dict)  # value-less parameter -> its initializer
    measurement_states: MeasurementStates | None = None  # entries with a time offset (time_offset/)
    context: "BuildContext | None" = None  # what built it: factor types' review() after solving reads it
    held: dict[int, Held] = field(default_factory=dict)  # key -> the axes a factor holds (BuildContext.hold)
    analyses: list[str] = field(default_factory=list)  # diagnostics about what the data determine (their labels)
    _graph: gtsam.NonlinearFactorGraph | None = None
    _evaluator: GraphEvaluator | None = None

    def graph(self) -> gtsam.NonlinearFactorGraph:
        """All factors in one graph (built once; the records do not change after building)."""
        if self._graph is None:
            self._graph = gtsam.NonlinearFactorGraph()
            for r in self.records:
                self._graph.add(r.factor)
        return self._graph

    def evaluator(self) -> GraphEvaluator:
        """The cost and linearization of all factors for fusionkit's solvers (graph/evaluator.py):
        vectorized groups in one call each."""
        if self._evaluator is None:
            self._evaluator = GraphEvaluator(self.records)
        return self._evaluator


def _sigma_key(model: gtsam.noiseModel.Base) -> tuple:
    return tuple(np.round(np.asarray(model.sigmas(), dtype=float), 12))


class BuildContext:
    """Passed to `FactorType.build` and `Initializer.initialize`."""

    def __init__(self, config: RunConfig, streams: dict[str, Stream]):
        self.config = config
        self.streams = streams
        self.keys = KeyRegistry()
        self.records: list[FactorRecord] = []
        self._values = gtsam.Values()
        self._pending: dict[int, Any] = {}  # declared variables not yet inserted into _values
        self.key_time: dict[int, float] = {}  # every declared variable -> the time it belongs to
        self.notes: list[str] = list(config.notes)
        self.notes += [f"robot {robot!r}: parameter {name!r} is {owner}/{theirs} (shared): one variable, with "
                       f"{owner}'s value and prior; reported under {owner!r}"
                       for robot, setup in config.robots.items() for name, (owner, theirs) in setup.shared.items()]
        self.diagnostics: dict[str, dict] = {}
        self.analyses: list[str] = []  # labels of the diagnostics about identifiability
        self.plots: dict[str, Callable[[Path], None]] = {}
        self.states: dict[str, StateSet] = {}
        self.fixed_keys: set[int] = set()
        self.held: dict[int, Held] = {}
        self._marginals: dict[int, np.ndarray] = {}  # after solving: marginal covariances (tangent) by key
        self.awaiting_value: dict[int, list[str]] = {}  # [robot, parameter] the description gives no value
        self.value_source: dict[str, str] = {}  # such a parameter's name -> the initializer that set it
        self.current_initializer = ""
        self.measurement_states = MeasurementStates(self)
        self._scaled_sigmas: dict[str, set[tuple]] = {}  # label -> sigmas ctx.noise made for a scaled entry
        for name, setup in config.robots.items():
            if setup.states:
                vt = variable_type(setup.states["type"])
                family = self.keys.family(name, setup.states["family"], vt, STATE)
                self.states[name] = StateSet(name, state_times(setup.states, streams), family)

    # --- robots, streams, states -------------------------------------------------------------
    def robot(self, name: str) -> RobotDescription:
        return self.config.robots[name].description

    def stream(self, name: str) -> Stream:
        return self.streams[name]

    def state_set(self, robot: str, spec: Spec | None = None) -> StateSet:
        if robot not in self.states:
            msg = f"robot {robot!r} has no states; add `states: {{stream: ...}}` to robots.{robot}"
            raise (spec.error("robot", msg) if spec else ValueError(msg))
        return self.states[robot]

    def state_time(self, robot: str, k: int) -> float:
        """Time (s) of state k; of a measurement-time state (an entry with a time offset): its pair's later state."""
        t = self.states[robot].t
        return float(t[k] if k < len(t) else t[self.measurement_states.get(robot, k).upper])

    def state_index(self, robot: str, k: int) -> int:
        """The robot's state k stands for: k itself, or for a measurement-time state the state nearest to it."""
        return k if k < len(self.states[robot].t) else self.measurement_states.get(robot, k).nearest

    # --- variables ---------------------------------------------------------------------------
    @property
    def initial(self) -> gtsam.Values:
        """Initial values of every declared variable. A declaration waits in a dict until this is
        read, so a value an initializer sets before then costs one insert, not an insert and an update."""
        if self._pending:
            for key, value in self._pending.items():
                self._values.insert(key, value)
            self._pending.clear()
        return self._values

    def has_variable(self, key: int) -> bool:
        """Whether a factor (or initializer) declared variable `key`."""
        return key in self.key_time

    def sigma(self, key: int) -> np.ndarray | None:
        """After solving (in FactorType.review): the 1-sigma of variable `key` along its tangent axes (its marginal
        covariance's diagonal); None before solving or where no covariance was computed (the run computes them for
        every calibration parameter)."""
        cov = self._marginals.get(key)
        return None if cov is None else np.sqrt(np.diag(cov))

    def record_marginals(self, covariances: dict[int, np.ndarray]) -> None:
        """The solve's marginal covariances, for `sigma` in the reviews that follow."""
        self._marginals = dict(covariances)

    def initial_values(self) -> gtsam.Values:
        """A copy of the initial values of every declared variable (for a plugin's own local solve or error; set
        values with set_initial)."""
        return gtsam.Values(self.initial)

    def base_transform(self, other: str, robot: str, prior_sigma=None, declare: bool = True) -> int | None:
        """The key of `<other>/base_in_<robot>`: robot `other`'s base frame in robot `robot`'s, a static pose3
        (identity start; `prior_sigma` per tangent axis around it) that the families linking two robots share.
        declare=False: its key if some factor declared it, else None."""
        name = f"base_in_{robot}"
        if not declare:
            family = self.keys.get(other, name)
            return None if family is None else family.key(0)
        return self.static_variable(other, name, POSE3, gtsam.Pose3(), prior_sigma)

    def family(self, robot: str, name: str):
        """The variable family `name` of robot `robot` that a factor declared (its `key(k)`), or None."""
        return self.keys.get(robot, name)

    def robot_of(self, key: int) -> str:
        """The robot a declared variable belongs to."""
        return self.keys.decode(key)[0].robot

    def entries(self, type_name: str | None = None, robot: str | None = None) -> list[Spec]:
        """The config's factor entries (of type `type_name` and of robot `robot`, when given), in config order: what
        an entry may need to see of others (a diagnostic over all of a robot's marker entries, whether some entry
        estimates a scale for the robot)."""
        return [s for s in self.config.factors
                if (type_name is None or s.type == type_name) and (robot is None or s.get("robot") == robot)]

    def factors(self, label: str | None = None, robots: tuple[str, ...] | None = None) -> list:
        """The factors added so far: an entry's (`label`), or those whose variables all belong to `robots`."""
        return [r.factor for r in self.records
                if (label is None or r.label == label)
                and (robots is None or all(self.robot_of(k) in robots for k in r.factor.keys()))]

    def note(self, text: str) -> None:
        """A sentence for the run's notes (printed by validate and run, kept in report.json); said once."""
        if text not in self.notes:
            self.notes.append(text)

    def initial_value(self, key: int) -> Any:
        """The current initial value of declared variable `key` (as its type reads from gtsam.Values); of a
        measurement-time key: the state at its time, interpolated between the states' initial values."""
        if key in self.measurement_states.by_key:
            return self.measurement_states.initial_value(key)
        if key in self._pending:
            self._values.insert(key, self._pending.pop(key))
        return self.keys.decode(key)[0].vartype.read(self._values, key)

    def forget(self, key: int) -> None:
        """Undeclare a per-state variable no factor uses any more (the samples it was declared for were left out)."""
        self.key_time.pop(key, None)
        self.held.pop(key, None)
        if self._pending.pop(key, None) is None and self._values.exists(key):
            self._values.erase(key)

    def _declare(self, key: int, initial: Any, time: float) -> int:
        if key not in self.key_time:
            self.key_time[key] = time
            self._pending[key] = initial.copy() if isinstance(initial, np.ndarray) else initial
        return key

    def state_variable(self, robot: str, family: str, vartype: VarType, k: int, initial: Any = None) -> int:
        """A per-state variable of another family (velocity, bias, joints) at state k (state_index(robot, k))."""
        k = self.state_index(robot, k)
        key = self.keys.family(robot, family, vartype, STATE).key(k)
        if key not in self.key_time:
            self._declare(key, vartype.zero() if initial is None else initial, self.state_time(robot, k))
        return key

    def state_key(self, robot: str, k: int) -> int:
        """The robot's state variable at state k (its `states:` type and family; declared with the
        type's zero -- identity pose, zero vector -- until initialized). k past the states: the key of a
        measurement-time state (from `associate` on an entry with a time offset; not a variable)."""
        s = self.states[robot]
        if k >= len(s.t):
            return self.measurement_states.key(robot, k)
        key = s.family.key(k)
        if key not in self.key_time:
            self._declare(key, s.family.vartype.zero(), float(s.t[k]))
        return key

    def state_keys(self, robot: str, ks) -> list[int]:
        """state_key for many states at once: the keys of the robot's states ks (in that order)."""
        s = self.states[robot]
        if len(ks) and np.max(ks) >= len(s.t):
            return [self.state_key(robot, int(k)) for k in ks]
        keys = s.family.keys(ks)
        new = list(dict.fromkeys(key for key in keys if key not in self.key_time))
        if new:  # declared as in state_key; one zero value serves them all (Values copies it)
            self.key_time.update(zip(new, s.t[np.asarray(new) - s.family.key(0)].tolist()))
            zero = s.family.vartype.zero()
            self._pending.update((key, zero) for key in new)
        return keys

    def pose_key(self, robot: str, k: int) -> int:
        """The pose of robot `robot` at state k: its state variable, for robots with pose states."""
        return self.state_key(robot, k)

    def parameter(self, robot: str, name: str, index: int | None = None, k: int | None = None) -> int:
        """Key of a calibration parameter from the robot description (element `index`).

        Static parameters are one variable; time-varying ones are one per state `k` (state_index(robot, k)),
        chained by a `parameter.random_walk` factor. The description's prior is added once (time-varying:
        on the first state only).
        """
        robot, name = self.config.robots[robot].shared.get(name, (robot, name))  # a shared one: the owner's
        param = self.robot(robot).parameters[name]
        i = 0 if index is None else index
        if param.time_varying:
            if k is None:
                raise ValueError(f"{robot}/{name} is time-varying: pass the state index k")
            k = self.state_index(robot, k)
            fam = self.keys.family(robot, name if not param.indexed else f"{name}[{i}]",
                                   param.vartype, TIME_VARYING, shown=param.element(index))
            key = fam.key(k)
            new = key not in self.key_time
            self._declare(key, param.values[i], self.state_time(robot, k))
            if new and k == 0:
                self._prior(param, i, key, f"prior:{robot}/{name}", self.state_time(robot, 0))
            return key
        fam = self.keys.family(robot, name, param.vartype, STATIC, indexed=param.indexed, elements=param.elements)
        key = fam.key(i)
        if key not in self.key_time:
            self._declare(key, param.values[i], STATIC_TIME)
            self._prior(param, i, key, f"prior:{robot}/{name}", STATIC_TIME)
        return key

    def static_variable(self, robot: str, name: str, vartype: VarType, initial: Any,
                        prior_sigma: Any = None) -> int:
        """A static unknown that no description names (e.g. a base-to-base transform)."""
        key = self.keys.family(robot, name, vartype, STATIC, indexed=False).key(0)
        if key not in self.key_time:
            self._declare(key, initial, STATIC_TIME)
            if prior_sigma is not None:
                self.add_record(vartype.prior(key, initial, gaussian(prior_sigma)),
                                f"prior:{robot}/{name}", STATIC_TIME)
        return key

    def _prior(self, param: Parameter, i: int, key: int, label: str, time: float) -> None:
        """The description's prior; a fixed parameter is held by a prior of FIXED_SIGMA (a hard
        constraint model would break the QR marginals); one without a value waits for an initializer."""
        if param.fixed:
            self.fixed_keys.add(key)
            noise = gaussian([FIXED_SIGMA] * param.vartype.dim)
            self.add_record(param.vartype.prior(key, param.values[i], noise), label.replace("prior:", "fixed:"), time)
        elif not param.known:
            self.awaiting_value[key] = label.removeprefix("prior:").split("/", 1)
        elif param.sigma is not None:
            self.add_record(param.vartype.prior(key, param.values[i], gaussian(param.sigma[i])), label, time)

    def set_initial(self, key: int, value: Any) -> None:
        """Initial value of a variable (an initializer's estimate); a fixed parameter keeps its value."""
        if key in self.fixed_keys:
            return
        waiting = self._pending.get(key)
        if waiting is not None and type(waiting) is type(value):  # not inserted yet: replace it
            self._pending[key] = value.copy() if isinstance(value, np.ndarray) else value
        elif key not in self.key_time:
            raise KeyError(f"{self.keys.name_of(key)} is not a variable of the graph")
        else:  # in the Values (or another Python type): gtsam converts and checks the type
            if key in self._pending:
                self._values.insert(key, self._pending.pop(key))
            self._values.update(key, value)
        if self.awaiting_value and self.awaiting_value.pop(key, None) is not None:
            self.value_source[self.keys.name_of(key)] = self.current_initializer

    # --- factors -----------------------------------------------------------------------------
    def noise(self, sigmas, spec: Spec | None = None) -> gtsam.noiseModel.Base:
        """Gaussian noise with the robust kernel of the entry (`robust:`), if any; the sigmas multiplied by the
        entry's `noise_scale:`."""
        scale = noise_scale(spec)
        model = gaussian(np.asarray(sigmas, dtype=float) * scale if scale != 1.0 else sigmas)
        if spec is not None and "noise_scale" in spec.data:
            self._scaled_sigmas.setdefault(spec.label, set()).add(_sigma_key(model))
        return with_kernel(model, spec.get("robust") if spec else None)

    def add(self, factor: gtsam.NonlinearFactor, spec: Spec, time: float = STATIC_TIME, part: str | None = None) -> None:
        """Add a factor made by entry `spec`; `time` is when an incremental solver may add it
        (the latest state it touches; static-only factors go first). An entry with `robust:` or a
        `noise_scale:` must have built the factor's noise with `noise(sigmas, spec)`: a kernel or scale silently
        dropped is refused. `part` names a factor whose noise is the plugin's own, not the entry's measurement
        noise (e.g. a prior holding an auxiliary variable near zero): neither the entry's kernel nor its
        scale applies, and an estimated scale does not count it (API 1.7)."""
        if part is None and spec.data.get("robust") and not isinstance(getattr(factor, "noiseModel", lambda: None)(),
                                                                       gtsam.noiseModel.Robust):
            raise PluginError(f"{spec.label}: factor type {spec.type} was given `robust:` but built a factor "
                              "without the kernel (plugin bug: build its noise with ctx.noise(sigmas, spec))")
        if part is None and "noise_scale" in spec.data and not self._noise_made_here(factor, spec):
            raise PluginError(f"{spec.label}: factor type {spec.type} was given `noise_scale:` but built a factor "
                              "whose noise ctx.noise did not make (plugin bug: build its noise with "
                              "ctx.noise(sigmas, spec), or name a prior of its own with ctx.add(..., part=...))")
        self.records.append(FactorRecord(factor, spec.label, time, part=part))

    def _noise_made_here(self, factor: gtsam.NonlinearFactor, spec: Spec) -> bool:
        model = getattr(factor, "noiseModel", lambda: None)()
        if isinstance(model, gtsam.noiseModel.Robust):
            model = model.noise()
        return model is not None and _sigma_key(model) in self._scaled_sigmas.get(spec.label, ())

    def add_vectorized(self, residual: VectorizedResidual, keys, data: dict[str, Any], sigmas, spec: Spec,
                       times=STATIC_TIME) -> None:
        """Add N factors of one vectorized residual (fusionkit.graph.vectorized): `keys` (N, k) variable
        keys per instance in the residual's variable order, `data` {name: (N, ...)} measurements, `sigmas`
        (dim,) shared or (N, dim) per instance (residual units; the entry's `robust:` kernel is applied),
        `times` () or (N,) as in `add`; the sigmas are multiplied by the entry's `noise_scale:`."""
        keys = np.asarray(keys, dtype=np.int64)
        n = len(keys)
        if keys.shape != (n, len(residual.variables)):
            raise PluginError(f"{spec.label}: {residual.name} takes {len(residual.variables)} keys per factor; "
                              f"got keys of shape {keys.shape}")
        data = {name: np.asarray(v) for name, v in data.items()}
        for name, v in data.items():
            if len(v) != n:
                raise PluginError(f"{spec.label}: {residual.name} data {name!r} has {len(v)} rows for {n} factors")
        per_instance = np.ndim(sigmas) == 2
        sigma_rows = np.broadcast_to(np.asarray(sigmas, dtype=float) * noise_scale(spec), (n, residual.dim)).copy()
        if not np.all(sigma_rows > 0):
            raise PluginError(f"{spec.label}: {residual.name} sigmas must be > 0")
        times = np.broadcast_to(np.asarray(times, dtype=float), (n,)).tolist()
        def noise(sigmas):  # the rows are scaled already: the entry's kernel only
            return with_kernel(gaussian(sigmas), spec.get("robust"))
        first = noise(sigma_rows[0] if n else np.ones(residual.dim))
        kernel = first.robust() if isinstance(first, gtsam.noiseModel.Robust) else None
        shared = None if per_instance else first
        group = VectorizedGroup(residual, keys, data, sigma_rows, kernel)
        instances = InstanceCache(residual, keys, data)
        for i in range(n):
            model = shared if shared is not None else noise(sigma_rows[i])
            self.records.append(FactorRecord(instances.factor(i, model), spec.label, times[i], group, i))

    def add_record(self, factor: gtsam.NonlinearFactor, label: str, time: float) -> None:
        self.records.append(FactorRecord(factor, label, time))

    def add_constraint(self, factor: gtsam.NonlinearFactor, label: str, time: float = STATIC_TIME) -> None:
        """A factor a plugin adds of its own, not from a measurement: a hold prior on an unidentifiable parameter,
        a gauge fixing a free frame. Its variables must be declared; `label` (e.g. "gauge:anchors/position")
        names it in the residual reports; no entry's kernel or noise scale applies to it."""
        undeclared = [k for k in factor.keys() if k not in self.key_time]
        if undeclared:
            raise PluginError(f"ctx.add_constraint({label!r}): variable {gtsam.DefaultKeyFormatter(undeclared[0])} "
                              "is declared by no factor (plugin bug: add the constraint after the factors)")
        self.records.append(FactorRecord(factor, label, time))

    def hold(self, key: int, axes, reason: str, labels=()) -> None:
        """Say that tangent `axes` of variable `key` are held by a factor of the plugin's (a tight prior at a
        nominal value: e.g. a parameter the data cannot identify), and why (`reason`, e.g. "not identifiable
        with base.rz"); `labels` name the axes (`tx`). The summary and report.html then print the element as
        `held (reason)` instead of its value and the hold's sigma. Holding more axes of the key adds them."""
        axes, labels = [int(a) for a in axes], [str(x) for x in labels]
        if labels and len(labels) != len(axes):
            raise PluginError(f"ctx.hold: {len(labels)} labels for {len(axes)} axes of {self.keys.name_of(key)}")
        before = self.held.get(key)
        if before is not None:
            named = dict(zip(before.axes, before.labels or [""] * len(before.axes)))
            named.update(zip(axes, labels or [""] * len(axes)))
            axes, labels = list(named), list(named.values()) if all(named.values()) else []
            reason = before.reason if reason == before.reason else f"{before.reason}; {reason}"
        order = sorted(range(len(axes)), key=axes.__getitem__)
        self.held[key] = Held(tuple(axes[i] for i in order), reason, tuple(labels[i] for i in order) if labels else ())

    def associate(self, stream: Stream, robot: str, tolerance: float | Spec, spec: Spec | None = None) -> Association:
        """Nearest-stamp association of `stream` rows with the robot's states; counts what is left.
        `associate(stream, robot, spec)`: within the entry's `tolerance` (s; its schema declares the key
        as TOLERANCE_SCHEMA); `associate(stream, robot, tolerance, spec)`: within the one given.
        An entry with a `time_offset:` gets every sample inside the states' span instead, each paired with a
        measurement-time state (index past the robot's states; see fusionkit/time_offset)."""
        offset = TimeOffset.of(spec if spec is not None else tolerance)
        if offset is not None:
            return self.measurement_states.associate(stream, robot, spec if spec is not None else tolerance, offset)
        if spec is None:
            spec = tolerance
            if "tolerance" not in spec.data:
                raise PluginError(f"{spec.label}: {spec.type} associates samples by nearest stamp but its schema "
                                  "declares no `tolerance` (plugin bug: add \"tolerance\": TOLERANCE_SCHEMA)")
            tolerance = spec["tolerance"]
        a = nearest(self.state_set(robot, spec).t, stream.t, tolerance)
        note = (f"{spec.label}: {a.unmatched} of {len(stream)} samples of stream {stream.name!r} had no state "
                f"within {tolerance} s and were not used")
        if a.unmatched and note not in self.notes:  # an entry may associate the same stream more than once
            self.notes.append(note)
        return a

    def problem(self) -> Problem:
        return Problem(self.records, self.initial, self.keys, self.states, self.key_time,
                       self.notes + self._unused_notes(), self.diagnostics, self.plots, self.fixed_keys,
                       self.value_source, self.measurement_states, self, self.held, list(self.analyses))

    def require_values(self) -> None:
        """After the initializers: every parameter the description gives no value must have one now."""
        for key, (robot, name) in self.awaiting_value.items():
            raise self.robot(robot).error(("parameters", name), f"robot {robot!r}: parameter {name} has no value "
                                          f"and no initializer set {self.keys.name_of(key)}; give `value:`/"
                                          "`values:` in the description, or add an initializer that estimates it")

    def _unused_notes(self) -> list[str]:
        """What the config declares but no factor uses: a robot's states, a description parameter."""
        notes = []
        for robot, states in self.states.items():
            if not any(states.key(k) in self.key_time for k in range(len(states))):
                notes.append(f"robot {robot!r} has {len(states)} states but no factor uses them: they are not "
                             "estimated (add a factor for the robot, or remove its `states:`)")
        declared = {(f.robot, f.name.split("[")[0]) for f in self.keys.families()}
        for robot, setup in self.config.robots.items():
            unused = [name for name in setup.description.parameters if (robot, name) not in declared]
            if unused:
                notes.append(f"robot {robot!r}: parameter(s) {', '.join(unused)} used by no factor: not estimated, "
                             "reported nowhere")
        return notes

    # --- diagnostics and figures -------------------------------------------------------------
    def add_diagnostic(self, label: str, report: dict, identifiability: bool = False) -> None:
        """A plugin's finding about the data (e.g. observability), for report.json and `validate`.
        `report["verdict"]` (a list of sentences), if present, is printed for the user. `identifiability`
        (API 1.10): a finding about what the data determine of the parameters (a cable's observability, an arm's
        identifiable axes): printed, and listed in report.json, with the identifiability report."""
        self.diagnostics[label] = report
        if identifiability and label not in self.analyses:
            self.analyses.append(label)

    def add_plot(self, name: str, draw: Callable[[Path], None]) -> None:
        """A figure written as plots/<name>.png with the outputs: `draw(path)` saves it."""
        self.plots[name] = draw
