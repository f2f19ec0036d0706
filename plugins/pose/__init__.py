"""Built-in `pose` plugin: generic pose factors, initializers and simulators."""

from fusionkit import hookimpl

from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .simulators import SIMULATORS


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_simulators():
    return SIMULATORS
