"""Built-in `serial_arm` plugin: serial arms from a URDF (Pinocchio forward kinematics), their kinematic
calibration factors, identifiability, and the arm simulator (models: docs/models/serial_arm.md)."""

from fusionkit.api import hookimpl, robot_description_files

from .factors import FACTOR_TYPES
from .model import SerialArmModel
from .simulator import SIMULATORS


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_robot_models():
    return [SerialArmModel]


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_robot_descriptions():
    return robot_description_files(__name__)
