"""`time_offset:` on a factor entry: the entry's samples were stamped by a clock offset from the states'.

    time_offset: {robot: cdpr, parameter: encoder_lag}             # a sample stamped t was taken at t + delta
    time_offset: {parameter: encoder_lag, rate: encoder_clock_rate}  # ... at t + delta + rho (t - t_ref)
    time_offset: {parameter: mocap_lag, velocities: false}          # Pose3 states: ignore their velocities

`parameter` (and `rate`) name scalar parameters (s, and s/s) of `robot` (default: the entry's `robot`),
declared in its description with a value and a prior sigma like any calibration parameter (or
`time_varying: true`, chained by a `parameter.random_walk` entry). Only factor types that pair their
samples with states by stamp (their schema has `tolerance`) can take one. Pose3 states whose robot has
per-state velocity3 variables (imu.preintegrated's) are interpolated with those velocities unless
`velocities: false`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..components import CheckScope, Spec
from ..plugins import variable_type
from .interpolation import interpolable

KEY = "time_offset"
SCHEMA = {"type": "object",
          "properties": {"robot": {"type": "string"}, "parameter": {"type": "string"}, "rate": {"type": "string"},
                         "velocities": {"type": "boolean"}},
          "required": ["parameter"], "additionalProperties": False}


@dataclass(frozen=True)
class TimeOffset:
    """The offset (and clock-rate) parameters of one entry's samples: robot/parameter, robot/rate."""

    robot: str
    parameter: str
    rate: str | None = None
    velocities: bool = True  # use the states' world-frame velocities where the robot has them

    @classmethod
    def of(cls, spec: Spec) -> "TimeOffset | None":
        raw = spec.get(KEY)
        if raw is None:
            return None
        return cls(raw.get("robot") or spec["robot"], raw["parameter"], raw.get("rate"), raw.get("velocities", True))

    @property
    def label(self) -> str:
        return f"{self.robot}/{self.parameter}"


def takes_time_offset(factor_type: type) -> bool:
    """Whether entries of a factor type may take `time_offset:`: those that pair samples with states by stamp (a
    `tolerance` key)."""
    return "tolerance" in factor_type.schema.get("properties", {})


def check_time_offset(spec: Spec, factor_type: type, scope: CheckScope) -> None:
    """The entry's `time_offset:` names scalar parameters of a robot, on an entry that pairs samples with
    states by stamp and whose robots' states can be interpolated; raises a located ConfigError."""
    if KEY not in spec.data:
        return
    raw, path = spec[KEY], (KEY,)
    if not takes_time_offset(factor_type):
        raise spec.error(path, f"factor type {spec.type} does not pair its samples with states by stamp, so a time "
                         "offset cannot apply to it (it applies to entries with a `tolerance:` key)")
    robot = raw.get("robot") or spec.get("robot")
    if robot is None:
        raise spec.error(path, "expected `robot:` (whose parameter the offset is): this entry names no robot")
    if robot not in scope.robots:
        raise spec.error(path + ("robot",) if "robot" in raw else path,
                         f"unknown robot {robot!r}; the config defines: {', '.join(scope.robots)}")
    params = scope.robots[robot].parameters
    for key in ("parameter", "rate"):
        name = raw.get(key)
        if name is None:
            continue
        if name not in params:
            raise spec.error(path + (key,), f"robot {robot!r} has no parameter {name!r}; it has: "
                             f"{', '.join(sorted(params)) or '(none)'} (declare it in the robot description: "
                             f"{{type: scalar, value: 0.0, sigma: ...}}, in {'s' if key == 'parameter' else 's/s'})")
        param = params[name]
        if param.vartype.name != "scalar" or param.count != 1:
            what = "offset" if key == "parameter" else "rate"
            raise spec.error(path + (key,), f"parameter {name!r} of robot {robot!r} is "
                             f"{param.count} x {param.vartype.name}; a time {what} is one scalar")
        if param.time_varying and not scope.states.get(robot):
            raise spec.error(path + (key,), f"parameter {name!r} is time-varying but robot {robot!r} has no states "
                             "to vary with")
    if "velocities" in raw and scope.states.get(spec.get("robot"), {}).get("type", "pose3") != "pose3":
        raise spec.error(path + ("velocities",), "only pose3 states are interpolated with velocities; robot "
                         f"{spec.get('robot')!r} has {scope.states.get(spec.get('robot'), {}).get('type')} states "
                         "(remove `velocities:`)")
    for key in factor_type.robot_fields:
        states = scope.states.get(spec.get(key)) if key in spec.data else None
        if states and not interpolable(variable_type(states.get("type", "pose3"))):
            raise spec.error(path, f"robot {spec[key]!r} has {states['type']} states, which cannot be interpolated "
                             "in time")
