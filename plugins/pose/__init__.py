"""Built-in `pose` plugin: generic pose, IMU and motion-model factors, initializers and simulators."""

from fusionkit.api import hookimpl, robot_description_files

from . import imu, imu_vo, motion
from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .simulators import SIMULATORS

FUSIONKIT_API = "1.13"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES + imu.FACTOR_TYPES + motion.FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS + imu.INITIALIZERS


@hookimpl
def register_simulators():
    return SIMULATORS + [imu_vo.ImuVoSimulator]


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "pose")  # robots/pose/ of the repository
