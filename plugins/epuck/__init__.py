"""`epuck` plugin: the e-puck's IR proximity sensors against a known wall map and the velocity motion
model (docs/models/epuck.md) -- the epuck and wall_map robot models, the `epuck.ir` and
`epuck.velocity_motion` factors, dead reckoning from the commands, the `epuck.sim` simulator and the
sensor- and motion-model fitting commands."""

from fusionkit.api import hookimpl, robot_description_files

from .commands import COMMANDS
from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .model import EpuckModel, WallMapModel
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
    return [EpuckModel, WallMapModel]


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "epuck")  # robots/epuck/ of the repository


@hookimpl
def register_commands():
    return COMMANDS
