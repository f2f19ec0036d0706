"""Built-in `wheels` plugin: differential-drive robots with wheel encoders, an optional passive wheel and a
gyro -- the diff_drive robot model, per-wheel, gyro, no-sideways-motion, preintegrated and long-horizon odometry factors,
dead-reckoning initialization and the wheels.sim fault simulator (models: docs/models/wheels.md)."""

from fusionkit.api import hookimpl, robot_description_files

from .rule_odometry import RULE_ODOMETRY
from .factors import FACTOR_TYPES
from .horizon import FACTOR_TYPES as LONG_HORIZON
from .initializers import INITIALIZERS
from .model import DiffDriveModel
from .simulators import SIMULATORS

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES + LONG_HORIZON + RULE_ODOMETRY


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_robot_models():
    return [DiffDriveModel]


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "wheels")  # robots/wheels/ of the repository
