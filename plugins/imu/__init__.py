"""Built-in `imu` plugin: GTSAM's preintegrated IMU factor between states, the initializers it needs
(velocities, a scaled odometry's scale, gaps of an odometry bridged), and the IMU + monocular VO simulator."""

from fusionkit.api import hookimpl

from .preintegrated import FACTOR_TYPES, INITIALIZERS
from .simulators import ImuVoSimulator

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_simulators():
    return [ImuVoSimulator]
