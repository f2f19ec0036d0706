"""Built-in `pose` plugin: pose measurements of any robot (absolute, relative, scaled relative, the origin,
co-registration of two robots), the random walk of a time-varying parameter, their initializers and
simulators. The IMU and the motion models are families of their own (`imu`, `motion`)."""

from fusionkit.api import hookimpl, robot_description_files

from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .simulators import SIMULATORS

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "pose")  # robots/pose/ of the repository
