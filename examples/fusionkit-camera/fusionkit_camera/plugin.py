"""The module named by the entry point: fusionkit registers it with pluggy and calls its hooks.

    [project.entry-points.fusionkit]
    camera = "fusionkit_camera.plugin"
"""

from fusionkit.api import hookimpl

FUSIONKIT_API = "1.13"  # register_variable_types arrived in API 1.13: fusionkit refuses this plugin in an older one

from .factors import FACTOR_TYPES
from .intrinsics import CAL3_S2
from .simulator import SIMULATORS


@hookimpl
def register_variable_types():
    return [CAL3_S2]


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_simulators():
    return SIMULATORS
