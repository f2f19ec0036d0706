"""Base classes of everything a plugin can provide.

A plugin returns these classes from its registration hooks (see `hookspecs.py`). Each class
declares a unique `name`, a one-line `summary`, and a JSON `schema` for the keys of its config
entry (besides `type`, `label` and, for factors, `robust`), with the `default` of each optional key
that has one: the loader fills them into the entry, so code reads `spec["key"]`. Keys named in
`robot_fields` must name a robot of the config and keys in `stream_fields` a stream: the core
checks them before any work starts. `check()` adds semantic checks; raise `spec.error(key, message)`.
"""

from __future__ import annotations

import argparse
from abc import ABC, abstractmethod
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, ClassVar

from .config.defaults import merged, with_default_keywords
from .config.yamlio import Document

if TYPE_CHECKING:
    import numpy as np

    from .data.stream import Stream
    from .graph.builder import BuildContext
    from .descriptions.description import RobotDescription


@dataclass
class Spec:
    """One entry of a config list (a factor, source, initializer) with its location for errors;
    `data` is the entry as written plus its schema's defaults for the keys it omits."""

    data: dict
    doc: Document
    path: tuple

    @property
    def type(self) -> str:
        return self.data["type"]

    @cached_property
    def label(self) -> str:
        """`label:`, else `factors[2]:pose.relative` (computed once: an entry does not change after loading)."""
        return self.data.get("label") or f"{self.path[0]}[{self.path[1]}]:{self.type}"

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def get(self, key: str, default: Any = None) -> Any:
        return self.data.get(key, default)

    def error(self, key: str | tuple | None, message: str):
        keys = () if key is None else (key if isinstance(key, tuple) else (key,))
        return self.doc.error(self.path + keys, message)


class Component(ABC):
    """Common declaration of every pluggable class."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    schema: ClassVar[dict] = {"type": "object", "properties": {}, "additionalProperties": False}
    robot_fields: ClassVar[tuple[str, ...]] = ()
    stream_fields: ClassVar[tuple[str, ...]] = ()

    def check(self, spec: Spec, scope: "CheckScope") -> None:
        """Semantic checks beyond the schema (e.g. a referenced robot parameter exists)."""


class CheckScope:
    """What `check()` may look at: robot descriptions and stream column names (not data)."""

    def __init__(self, robots: dict[str, "RobotDescription"], stream_columns: dict[str, tuple[str, ...]],
                 states: dict[str, dict | None] | None = None):
        self.robots = robots
        self.stream_columns = stream_columns
        self.states = states or {}
        self.stream_origins: dict[str, str] = {}  # stream -> where it comes from, for messages

    def require_states(self, spec: Spec, robot_key: str, state_type: str | None = None) -> None:
        """Error unless robot `spec[robot_key]` has states (of `state_type`, e.g. pose3, pose2, vector6)."""
        robot = spec[robot_key]
        states = self.states.get(robot)
        if not states:
            raise spec.error(robot_key, f"robot {robot!r} has no states; add `states: {{stream: ...}}` "
                             f"to robots.{robot}")
        have = states.get("type", "pose3")
        if state_type and have != state_type:
            raise spec.error(robot_key, f"robot {robot!r} has {have} states; this needs {state_type} "
                             f"(robots.{robot}.states.type)")

    def require_parameter(self, spec: Spec, robot_key: str, param_key: str, vartype: str | None = None) -> None:
        """Error unless `spec[param_key]` names a parameter of robot `spec[robot_key]`."""
        desc = self.robots[spec[robot_key]]
        name = spec[param_key]
        if name not in desc.parameters:
            raise spec.error(param_key, f"robot {spec[robot_key]!r} has no parameter {name!r}; it has: "
                             f"{', '.join(sorted(desc.parameters)) or '(none)'}")
        if vartype and desc.parameters[name].vartype.name != vartype:
            raise spec.error(param_key, f"parameter {name!r} is a {desc.parameters[name].vartype.name}; "
                             f"expected a {vartype}")

    def require_model(self, spec: Spec, robot_key: str, model: str) -> "RobotDescription":
        """The description of robot `spec[robot_key]`; error unless its `model:` is `model`."""
        desc = self.robots[spec[robot_key]]
        if desc.model != model:
            raise spec.error(robot_key, f"robot {spec[robot_key]!r} is a {desc.model!r} robot; {spec.type} needs "
                             f"a {model!r} robot (model: {model} in its description)")
        return desc

    def require_values(self, spec: Spec, robot_key: str, name: str, why: str) -> None:
        """Error unless robot `spec[robot_key]`'s description gives parameter `name` a value (not only
        `count:`), for a plugin that reads the nominal value, `why` (e.g. 'to guess the first lengths')."""
        param = self.robots[spec[robot_key]].parameters.get(name)
        if param is not None and not param.known:
            raise spec.error(robot_key, f"{spec.type} needs the nominal value of parameter {name!r} of robot "
                             f"{spec[robot_key]!r} {why}; give it `values:` in the robot description")

    def require_columns(self, spec: Spec, stream_key: str, columns: tuple[str, ...]) -> None:
        have = self.stream_columns[spec[stream_key]]
        missing = [c for c in columns if c not in have]
        if missing:
            origin = self.stream_origins.get(spec[stream_key])
            raise spec.error(stream_key, f"stream {spec[stream_key]!r}{f' ({origin})' if origin else ''} lacks "
                             f"column(s) {', '.join(missing)}; it has {', '.join(have) or '(none)'}")


@dataclass(frozen=True)
class ResidualPart:
    """A named part of a factor's residual: its rows and their unit (`FactorType.residual_parts`)."""

    name: str  # e.g. "position"
    unit: str  # e.g. "m"
    rows: tuple[int, ...]


def pose_parts(planar: bool) -> list[ResidualPart]:
    """The parts of a pose residual in GTSAM's tangent order: Pose3 (rx ry rz, tx ty tz) orientation (rad) and
    position (m); Pose2 (x, y, theta) position (m) and heading (rad)."""
    if planar:
        return [ResidualPart("position", "m", (0, 1)), ResidualPart("heading", "rad", (2,))]
    return [ResidualPart("position", "m", (3, 4, 5)), ResidualPart("orientation", "rad", (0, 1, 2))]


class FactorType(Component):
    """Turns one config entry into factors: `build()` calls `ctx.add(...)` per factor.

    `example()` returns a `fusionkit.testing.FactorExample` (a factor at a consistent state)
    for the contract suite; every factor type must provide one.

    An entry's `robust:` kernel reaches the factors through `ctx.noise(sigmas, spec)`; the builder
    refuses a factor made without it. A type whose noise comes from its model (IMU preintegration)
    sets `accepts_robust = False`, and `robust:` on its entries is refused at load.
    """

    accepts_robust: ClassVar[bool] = True

    @abstractmethod
    def build(self, ctx: "BuildContext", spec: Spec) -> None:
        """Add this entry's factors to the graph through `ctx`."""

    def diagnose(self, ctx: "BuildContext", spec: Spec) -> None:
        """Optional: after initialization, examine the data (e.g. observability) and report it
        with `ctx.add_diagnostic(spec.label, {...})`."""

    def review(self, ctx: "BuildContext", spec: Spec, values: "Any") -> list[str]:
        """Optional (API 1.4): after solving, examine the estimate `values` (gtsam.Values) against this
        entry's factors (`ctx.records` with `spec.label`) and return notes for the report, e.g. residuals
        that say the model misses something. Default: none."""
        return []

    def baseline(self, ctx: "BuildContext", spec: Spec, values: "Any") -> dict[str, "Stream"]:
        """Optional (API 1.6): what this entry's sensor alone says of its robot's trajectory at the estimated
        calibration (`values`), as {name: stream with columns x, y, z (m, world frame)}; with a true
        trajectory, report.json compares each with the truth beside the fused estimate
        (`evaluation.baselines.<robot>.<name>`). Names are identifiers (no dots). Default: none."""
        return {}

    def separation_hint(self, spec: Spec, parameters: list[str]) -> str | None:
        """Optional (API 1.9): the data hardly tell apart `parameters` (full names, `robot/name`, sorted; the
        identifiability report's group). If this entry's model knows what motion or measurement separates
        them, one sentence saying so (it is printed after the group); else None. Default: None."""
        return None

    def residual_parts(self, ctx: "BuildContext", spec: Spec) -> list["ResidualPart"]:
        """Optional (API 1.10): named parts of this entry's residual (unwhitened, in the factor's units) whose
        norms `fusionkit crossval` reports as held-out prediction errors, e.g. a 6-D pose's orientation (rad,
        rows 0-2) and position (m, rows 3-5). Default: none, the whole residual as one part `residual`."""
        return []

    @classmethod
    @abstractmethod
    def example(cls, rng: "np.random.Generator"):
        """A factor of this type with values at which its residual is zero."""


@dataclass
class SourceOutput:
    """Streams a source produced, plus truth when it knows it (simulators)."""

    streams: dict[str, "Stream"]
    truth_trajectories: dict[str, "Stream"] | None = None
    truth_calibration: dict[str, dict[str, Any]] | None = None
    truth_states: dict[str, dict[str, "Stream"]] | None = None  # robot -> state family -> true values


class Source(Component):
    """Reads (or generates) named streams. `stream_names()` is known before reading data."""

    @abstractmethod
    def stream_names(self, spec: Spec, base_dir: "Any") -> dict[str, tuple[str, ...]]:
        """Stream name -> column names, reading no more than headers (for validation)."""

    @abstractmethod
    def read(self, spec: Spec, base_dir: "Any") -> SourceOutput:
        """Read (or generate) the streams."""


class RobotModel(Component):
    """Validates the model-specific keys of a robot description (`schema` covers them); optionally
    writes model-specific files after a run (`outputs`)."""

    def check_description(self, desc: "RobotDescription") -> None:
        """Semantic checks of a description after its schema passed (raise `desc.error(...)`)."""

    def axis_names(self, desc: "RobotDescription", parameter: str) -> list[str] | None:
        """Optional (API 1.9): names of the components of the vector parameter `parameter`, one per dimension
        (a serial arm's placement errors: the axes its description lists, `tx` ...), for the reports; None:
        `c0`, `c1`, ... Default: None."""
        return None

    def element_names(self, desc: "RobotDescription", parameter: str) -> list[str] | None:
        """Names of the elements of the indexed parameter `parameter` (one per value, distinct), when the
        model has them: a serial arm names its joint offsets by joint, so the summary, report.json,
        calibration.yaml and every message say `joint_offsets[elbow_joint]`, not `joint_offsets[2]`.
        Called after `check_description`. Default: None (elements go by index)."""
        return None

    def outputs(self, robot: str, calibrated: "RobotDescription") -> dict[str, str | bytes]:
        """Files `fusionkit run` writes for robot `robot` into its output folder: {path relative to the
        folder, `/`-separated (e.g. `robots/arm.urdf`): text or bytes}. `calibrated` is the robot's
        description with every estimated parameter at its estimate (a time-varying one at its last
        value; `Parameter.time_varying` says which); the others keep their description values.
        Default: none."""
        return {}

    def geometry(self, robot: str, calibrated: "RobotDescription", state: dict) -> list:
        """What `fusionkit view` and report.html draw of robot `robot` at one time: a list of
        `fusionkit.api.Points` / `Lines` in the world frame (m). `state` holds the robot's per-state values
        then, by family (`pose`: a gtsam.Pose3, planar poses lifted to z = 0; `joints`: ...), and is empty
        for a robot without states (drawn once); `calibrated` as for `outputs`. Default: nothing (the
        trajectory, point parameters and sigma ellipsoids are drawn for every robot)."""
        return []


class Initializer(Component):
    """Fills initial values (`ctx.set_initial`) after all factors are built."""

    @abstractmethod
    def initialize(self, ctx: "BuildContext", spec: Spec) -> None:
        """Set initial values of the variables this initializer is responsible for."""


class Simulator(Component):
    """Generates a synthetic dataset with its truth. `schema` covers its parameters and
    `defaults` gives the value of every optional one: the one place they are declared; the class's
    `schema` then shows each as its `default` keyword too (`fusionkit plugins --json`)."""

    defaults: ClassVar[dict] = {}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.schema = with_default_keywords(cls.schema, cls.defaults)

    @classmethod
    def resolve(cls, params: dict, doc: Document, path: tuple = ()) -> dict:
        """`params` over the defaults (nested mappings merged key by key, so `--set noise.rotation=...`
        keeps the default translation), validated as a whole against `schema`; errors are located
        at `path` in `doc`."""
        from .config.schema import validate_against
        full = merged(cls.defaults, params)
        validate_against(doc, cls.schema, full, path)
        return full

    @abstractmethod
    def stream_columns(self, params: dict) -> dict[str, tuple[str, ...]]:
        """Stream name -> column names that `simulate()` will produce."""

    @abstractmethod
    def simulate(self, params: dict, rng: "np.random.Generator") -> SourceOutput:
        """Streams and truth for `params` (already validated and defaulted)."""

    def robots(self, params: dict) -> dict[str, dict]:
        """Robot descriptions (as YAML-able dicts) the dataset belongs to, by robot name."""
        return {}

    def config(self, params: dict) -> dict:
        """A runnable config (without sources) that estimates this dataset."""
        return {}


BUILTIN_COMMANDS = ("run", "validate", "plugins", "simulate", "view")  # fusionkit's own; a plugin may not take them


class Command(ABC):
    """A `fusionkit <name>` subcommand a plugin adds (hook `register_commands`). The CLI runs it as
    its own commands: `--debug` and `-q` are accepted, a `FusionkitError` becomes one line on stderr
    with exit code 2, any other exception an internal error (exit 3). `summary` is the one-line help
    shown by `fusionkit --help` and `fusionkit plugins`. A command that writes files writes them with
    `fusionkit.api.write_output_folder` (the rules of `run --out`)."""

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""

    def add_arguments(self, parser: argparse.ArgumentParser) -> None:
        """Declare the command's arguments on its (sub)parser."""

    @abstractmethod
    def run(self, args: argparse.Namespace) -> int:
        """Do the work; return the exit code (0: success)."""
