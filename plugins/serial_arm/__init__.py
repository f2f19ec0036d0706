"""Built-in `serial_arm` plugin: serial arms from a URDF (Pinocchio forward kinematics), their kinematic
calibration factors, identifiability, the base/marker initializer and the arm simulator (models:
docs/models/serial_arm.md)."""

from fusionkit.api import hookimpl, robot_description_files

from .commands import COMMANDS
from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .model import SerialArmModel
from .simulators import SIMULATORS

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_robot_models():
    return [SerialArmModel]


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "serial_arm")  # robots/serial_arm/ of the repository


@hookimpl
def register_commands():
    return COMMANDS
