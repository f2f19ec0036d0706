"""Built-in `cable_rigid` plugin: rigid/elastic cable factors on the core's `cdpr` robot model (fusionkit.api's
cable_robot), pulley pseudo-measurements (models: docs/models/cable_rigid.md)."""

from fusionkit.api import hookimpl, robot_description_files

from .commands import COMMANDS
from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .simulators import SIMULATORS

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "cable_rigid")  # robots/cable_rigid/ of the repository


@hookimpl
def register_commands():
    return COMMANDS
