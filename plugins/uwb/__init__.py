"""`uwb` plugin: UWB ranging (docs/models/uwb.md) -- tag-to-anchor ranges with constant or time-varying
bias per anchor and an optional scale error, tag-to-tag ranges between robots, differential-drive
odometry and a constant-velocity prior between ranging epochs, multilateration initialization of
poses and unknown anchors, and a simulator. The range math is the rigid-cable model's
(fusionkit.geometry): the anchor plays the pulley, the bias the encoder offset."""

from fusionkit.api import hookimpl, robot_description_files

from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .labyrinth import SOURCES
from .drone import UwbDroneSimulator
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
    return SIMULATORS + [UwbDroneSimulator]


@hookimpl
def register_sources():
    return SOURCES


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "uwb")  # robots/uwb/ of the repository
