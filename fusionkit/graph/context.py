"""The build context a plugin programs against (public as `fusionkit.api.BuildContext`, API 1.12): what
`FactorType.build`, `FactorType.diagnose`/`review` and `Initializer.initialize` may ask of the `ctx` they receive.
The concrete class (graph/builder.py) has more, for the core; plugins are given a `PluginContext` (below) that has
these and nothing else, so a plugin stays working across minor versions (tests/core/test_public_api.py also
checks the source of every plugin in this repository)."""

from __future__ import annotations

from typing import Any, Callable, Protocol, runtime_checkable

import gtsam

from ..components import Spec
from ..data.association import Association
from ..data.stream import Stream
from ..descriptions.description import RobotDescription
from .builder import STATIC_TIME
from .variables import VarType


@runtime_checkable
class BuildContext(Protocol):
    # --- robots, streams, states
    def robot(self, name: str) -> RobotDescription:
        """The robot's (validated) description."""

    def stream(self, name: str) -> Stream:
        """A stream the sources read."""

    def state_set(self, robot: str, spec: Spec | None = None) -> Any:
        """The robot's states: `.t` (times, s), `.family` (its variable family, `.vartype`), `.key(k)`; an error at
        `spec`'s robot key when it has none."""

    def state_time(self, robot: str, k: int) -> float:
        """Time (s) of state k."""

    def state_index(self, robot: str, k: int) -> int:
        """The state k stands for (a measurement-time state: the nearest real one)."""

    def associate(self, stream: Stream, robot: str, tolerance: float | Spec, spec: Spec | None = None) -> Association:
        """The stream's samples matched to the robot's states (nearest within the tolerance, or the entry's)."""

    # --- variables: keys, typed values
    def state_key(self, robot: str, k: int) -> int:
        """The robot's state variable at state k."""

    def state_keys(self, robot: str, ks) -> list[int]:
        """state_key for each k."""

    def pose_key(self, robot: str, k: int) -> int:
        """The robot's pose state at k (robots with pose states)."""

    def state_variable(self, robot: str, family: str, vartype: VarType, k: int, initial: Any = None) -> int:
        """A per-state variable of another family (velocity, bias) at state k, declared on first use."""

    def parameter(self, robot: str, name: str, index: int | None = None, k: int | None = None) -> int:
        """A description parameter's variable (element `index`; at state k when time-varying)."""

    def static_variable(self, robot: str, name: str, vartype: VarType, initial: Any, prior_sigma: Any = None) -> int:
        """A plugin's own static variable (e.g. an unknown transform between two robots)."""

    def base_transform(self, other: str, robot: str, prior_sigma=None, declare: bool = True) -> int | None:
        """The key of `<other>/base_in_<robot>`, robot `other`'s base frame in robot `robot`'s (a static pose3 the
        families linking two robots share); declare=False: its key if declared, else None."""

    def family(self, robot: str, name: str) -> Any:
        """A declared variable family of the robot (`.key(k)`), or None."""

    def robot_of(self, key: int) -> str:
        """The robot a declared variable belongs to."""

    def has_variable(self, key: int) -> bool:
        """Whether variable `key` is declared."""

    def initial_value(self, key: int) -> Any:
        """Its current initial value, typed (gtsam.Pose3, numpy vector, float, ...)."""

    def sigma(self, key: int) -> Any:
        """After solving (FactorType.review): the variable's 1-sigma per tangent axis, or None (API 1.14)."""

    def initial_values(self) -> gtsam.Values:
        """A copy of every declared variable's initial value (for a plugin's own local solve)."""

    def set_initial(self, key: int, value: Any) -> None:
        """Set a declared variable's initial value."""

    # --- factors
    def noise(self, sigmas, spec: Spec | None = None) -> gtsam.noiseModel.Base:
        """The entry's noise model: sigmas with its `noise_scale:` and `robust:` applied."""

    def add(self, factor: gtsam.NonlinearFactor, spec: Spec, time: float = STATIC_TIME, part: str | None = None) -> None:
        """Add a factor of entry `spec` (guarded: its noise must come from `noise`, unless `part` names a prior of
        the plugin's own)."""

    def add_vectorized(self, residual, keys, data: dict, sigmas, spec: Spec, times=STATIC_TIME) -> None:
        """Add N instances of one vectorized residual (API 1.5)."""

    def add_constraint(self, factor: gtsam.NonlinearFactor, label: str, time: float = STATIC_TIME) -> None:
        """A factor of the plugin's own (a hold prior, a gauge) on declared variables."""

    def hold(self, key: int, axes, reason: str, labels=()) -> None:
        """Report tangent `axes` of `key` as held (by a constraint), and why."""

    def factors(self, label: str | None = None, robots: tuple[str, ...] | None = None) -> list:
        """Factors added so far: an entry's, or those whose variables all belong to `robots`."""

    def entries(self, type_name: str | None = None, robot: str | None = None) -> list[Spec]:
        """The config's factor entries (of a type, of a robot)."""

    # --- what the run reports
    def note(self, text: str) -> None:
        """A sentence for the run's notes (said once)."""

    def add_diagnostic(self, label: str, report: dict, identifiability: bool = False) -> None:
        """A finding about the data for report.json and `validate`."""

    def add_plot(self, name: str, draw: Callable) -> None:
        """A figure written as plots/<name>.png."""


MEMBERS = frozenset(name for name in vars(BuildContext) if not name.startswith("_"))


class PluginContext:
    """The `ctx` a plugin receives: the core's build context seen through the protocol above. Every operation of
    BuildContext is the core's own; anything else (its Values, key registry, factor records, config) is not
    there, so a plugin cannot come to depend on it: AttributeError naming the protocol."""

    def __init__(self, core: Any):
        for name in MEMBERS:  # the core's bound methods, looked up once: as fast to call as on the core
            object.__setattr__(self, name, getattr(core, name))

    def __getattr__(self, name: str) -> Any:  # only for names not set above
        raise AttributeError(f"ctx.{name} is not part of fusionkit.api.BuildContext, the context plugins are given "
                             f"(docs/plugin_guide.md#the-buildcontext)")

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"ctx.{name} cannot be set: a plugin changes the problem through ctx's operations")


def for_plugins(core: Any) -> PluginContext:
    """The plugin's view of a core build context (one per context)."""
    view = getattr(core, "_plugin_view", None)
    if view is None:
        view = PluginContext(core)
        core._plugin_view = view
    return view
