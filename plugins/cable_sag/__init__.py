"""`cable_sag` plugin: suspended cable robots with heavy, sagging cables (docs/models/cable_sag.md) --
the catenary statics through one reference cable, the kinematic-static calibration factors, cable lengths
with sag at measured poses (cable.catenary), the fast static simulator. Installed through the `fusionkit` entry-point group like any third-party
plugin; it builds on the rigid-cable plugin's `cdpr` robot model and `cdpr_small` description by name
(through the registry), without importing or changing it."""

from fusionkit.api import hookimpl, robot_description_files

from . import catenary_factor
from .commands import COMMANDS
from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .simulators import SIMULATORS

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES + catenary_factor.FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_commands():
    return COMMANDS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "cable_sag")  # robots/cable_sag/ of the repository
