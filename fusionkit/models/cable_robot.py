"""The `cdpr` robot model, shared by every cable family (the rigid and the sagging cables): a cable-driven
parallel robot with n cables, and its typed reading (`CableRobot`, public as fusionkit.api.cable_robot).

Model keys of the description (besides frames, sensors, parameters):

    model: cdpr
    cables:
      attachments: [[x, y, z], ...]   # b_i: attachment points in the end-effector frame (m)
      stiffness_EA: 2.0e4             # axial stiffness E*A (N); absent: rigid cables
      weight_per_length: 0.10         # cable weight per metre g_c (N/m); or mass_per_length (kg/m); absent: massless
      pulley_radius: 0.04             # m: swivelling pulleys of this radius (absent or 0: a fixed exit point)
      swivel_axis: [0, 0, 1]          # the direction the cable travels as it reaches each pulley (default up)
    end_effector:
      mass: 2.5                       # kg; or weight (N)
      com: [0, 0, -0.05]              # centre of mass in the end-effector frame (m)
    gravity: 9.81                     # m/s^2 (default), converts a mass to a weight and back

Masses and weights are both published; whichever the description gives is stored as `mass` (kg) and
`weight_per_length` (N/m) once the description is checked, converted with its `gravity`.

Calibration parameters it requires: `pulley` (point3, one per cable: a_i, the point where cable
i leaves its pulley, base frame; with a `pulley_radius`, the swivel point where it reaches the pulley) and `offset` (scalar, one per cable: l0_i, encoder reading minus
cable length, m).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..components import RobotModel
from ..config.fragments import GRAVITY
from ..hookspecs import hookimpl
from ..descriptions.description import RobotDescription
from ..view.shapes import Lines, Points

VEC3 = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}


@dataclass(frozen=True)
class CableRobot:
    """Geometry and physics of a CDPR read from a validated description: attachments (m), EA (N), cable weight per
    metre (N/m), end-effector mass (kg) and centre of mass (m), pulley radius (m), swivel axis, gravity (m/s^2)."""

    attachments: np.ndarray  # (n, 3) b_i in the end-effector frame
    stiffness_EA: float | None
    weight_per_length: float | None
    mass: float | None
    com: np.ndarray
    pulley_radius: float = 0.0
    swivel_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    gravity: float = GRAVITY

    @property
    def n(self) -> int:
        return len(self.attachments)


def cable_robot(desc: RobotDescription | dict) -> CableRobot:
    """The CableRobot of a checked `cdpr` description (or of its model keys, a dict with `cables`, ...)."""
    extra = desc if isinstance(desc, dict) else desc.extra
    cables, ee = extra["cables"], extra.get("end_effector", {})
    return CableRobot(np.asarray(cables["attachments"], float), cables.get("stiffness_EA"),
                      cables.get("weight_per_length"), ee.get("mass"), np.asarray(ee.get("com", [0, 0, 0]), float),
                      float(cables.get("pulley_radius", 0.0)), np.asarray(cables.get("swivel_axis", [0, 0, 1]), float),
                      float(extra.get("gravity", GRAVITY)))


def store_as_mass_and_weight(desc: RobotDescription) -> None:
    """end_effector.weight (N) becomes mass (kg), cables.mass_per_length (kg/m) becomes weight_per_length
    (N/m), with the description's gravity; ConfigError at the key when both forms are given."""
    g = float(desc.extra.get("gravity", GRAVITY))
    for path, given, stored, to_stored in (("end_effector", "weight", "mass", 1.0 / g),
                                          ("cables", "mass_per_length", "weight_per_length", g)):
        group = desc.extra.get(path, {})
        if given in group and stored in group:
            raise desc.error((path, given), f"give {path}.{stored} or {path}.{given}, not both")
        if given in group:
            group[stored] = float(group.pop(given)) * to_stored


class CdprModel(RobotModel):
    name = "cdpr"
    summary = "cable-driven parallel robot: pulleys a_i, attachments b_i, encoder offsets l0_i, EA, mass"
    schema = {"type": "object",
              "properties": {
                  "cables": {"type": "object",
                             "properties": {"attachments": {"type": "array", "items": VEC3, "minItems": 1},
                                            "stiffness_EA": {"type": "number", "exclusiveMinimum": 0},
                                            "weight_per_length": {"type": "number", "exclusiveMinimum": 0},
                                            "mass_per_length": {"type": "number", "exclusiveMinimum": 0},
                                            "pulley_radius": {"type": "number", "minimum": 0},
                                            "swivel_axis": VEC3},
                             "required": ["attachments"], "additionalProperties": False},
                  "end_effector": {"type": "object",
                                   "properties": {"mass": {"type": "number", "exclusiveMinimum": 0},
                                                  "weight": {"type": "number", "exclusiveMinimum": 0},
                                                  "com": VEC3},
                                   "additionalProperties": False},
                  "gravity": {"type": "number", "exclusiveMinimum": 0}},
              "required": ["cables"], "additionalProperties": False}

    def geometry(self, robot: str, calibrated: RobotDescription, state: dict) -> list:
        """The cables as straight segments from each pulley a_i to its attachment p + R b_i, and the
        end effector as the polygon of its attachments (at the pose of `state`)."""
        pose = state.get("pose")
        if pose is None:
            return []
        attached = pose.transformFrom(cable_robot(calibrated).attachments.T).T   # (n, 3) world
        pulleys = np.asarray(calibrated.parameters["pulley"].values, float).reshape(-1, 3)
        ring = np.vstack([attached, attached[:1]])
        return [Lines(f"{robot} cables", np.stack([pulleys, attached], axis=1), "#2ca02c", 1.2),
                Lines(f"{robot} end effector", np.stack([ring[:-1], ring[1:]], axis=1), "#9467bd", 2.0),
                Points(f"{robot} attachments", attached, "#9467bd", 4.0)]

    def check_description(self, desc: RobotDescription) -> None:
        """`pulley` and `offset` must exist with one value per cable; a weight or a mass, not both
        (stored as `mass` and `weight_per_length`)."""
        store_as_mass_and_weight(desc)
        axis = desc.extra["cables"].get("swivel_axis")
        if axis is not None and np.linalg.norm(axis) == 0:
            raise desc.error(("cables", "swivel_axis"), "expected a direction (a non-zero vector)")
        n = len(desc.extra["cables"]["attachments"])
        for name, vartype in (("pulley", "point3"), ("offset", "scalar")):
            param = desc.parameters.get(name)
            if param is None:
                raise desc.error(("parameters",), f"a cdpr needs parameter {name!r} ({vartype}, {n} values)")
            if param.vartype.name != vartype or param.count != n or not param.indexed:
                raise desc.error(("parameters", name), f"expected a {vartype} with `values:` for each of the "
                                 f"{n} cables; got {param.count} {param.vartype.name} value(s)")


@hookimpl
def register_robot_models():
    return [CdprModel]
