"""Built-in `pose` plugin: generic pose and IMU factors, initializers and simulators."""

from fusionkit import hookimpl

from . import imu
from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .simulators import SIMULATORS


@hookimpl
def register_factor_types():
    return FACTOR_TYPES + imu.FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS + imu.INITIALIZERS


@hookimpl
def register_simulators():
    return SIMULATORS
