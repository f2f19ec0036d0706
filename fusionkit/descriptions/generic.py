"""The built-in `generic` robot model: frames, sensors and parameters, nothing model-specific."""

from __future__ import annotations

from ..hookspecs import hookimpl
from ..components import RobotModel


class GenericRobot(RobotModel):
    name = "generic"
    summary = "any robot: frames, sensors with mounts, calibration parameters with priors"


@hookimpl
def register_robot_models():
    return [GenericRobot]
