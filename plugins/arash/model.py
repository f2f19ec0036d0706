"""The `rcm_arm` robot model: ARASH:ASiST's parallelogram remote-centre-of-motion arm.

Model keys of the description (besides frames, sensors, parameters):

    model: rcm_arm
    convention: thesis          # thesis (eq. 3.7, lengths in m) or authors_code (lengths in mm)
    joint_limits:               # the workspace the simulator draws configurations in
      phi: [-0.785, 0.785]      # rad
      psi: [-0.524, 1.047]      # rad
      d: [-0.027, 0.0]          # the convention's length unit

Calibration parameters it requires, scalars: `alpha` (rad), `theta` (rad), `l_1234` (the
convention's length unit). Joint states are the robot's vector3 states (phi, psi, d).
"""

from __future__ import annotations

from fusionkit.api import RobotDescription, RobotModel

from .kinematics import CONVENTIONS

PARAMETERS = ("alpha", "theta", "l_1234")
JOINTS = ("phi", "psi", "d")
RANGE = {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}


def convention_of(desc: RobotDescription) -> str:
    """The forward-kinematics convention of a validated rcm_arm description: thesis or authors_code."""
    return desc.extra["convention"]


class RcmArmModel(RobotModel):
    name = "rcm_arm"
    summary = ("ARASH:ASiST parallelogram remote-centre-of-motion arm: joints (phi, psi, d), parameters "
               "alpha, theta, l_1234; forward kinematics in the thesis (m) or the authors' code (mm) convention")
    schema = {"type": "object",
              "properties": {"convention": {"enum": list(CONVENTIONS)},
                             "joint_limits": {"type": "object",
                                              "properties": {j: RANGE for j in JOINTS},
                                              "required": list(JOINTS), "additionalProperties": False}},
              "required": ["convention", "joint_limits"], "additionalProperties": False}

    def check_description(self, desc: RobotDescription) -> None:
        """alpha, theta and l_1234 are single scalars; each joint range is [lo, hi] with lo < hi."""
        for name in PARAMETERS:
            param = desc.parameters.get(name)
            if param is None:
                raise desc.error(("parameters",), f"an rcm_arm needs the scalar parameter {name!r}")
            if param.vartype.name != "scalar" or param.indexed:
                raise desc.error(("parameters", name), f"expected one scalar (`type: scalar`, `value:`); got "
                                 f"{param.count} {param.vartype.name} value(s)")
        for joint in JOINTS:
            lo, hi = desc.extra["joint_limits"][joint]
            if not lo < hi:
                raise desc.error(("joint_limits", joint), f"expected [lo, hi] with lo < hi; got [{lo}, {hi}]")
