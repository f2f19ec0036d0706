"""The module named by the entry point: fusionkit registers it with pluggy and calls its hooks.

    [project.entry-points.fusionkit]
    altimeter = "fusionkit_altimeter.plugin"

Implement only the hooks you need (see `fusionkit.hookspecs`); each returns classes.
"""

from fusionkit.api import hookimpl

FUSIONKIT_API = "1.1"  # the plugin API this package is written for: fusionkit refuses to load it into an older one

from .factors import FACTOR_TYPES
from .simulator import SIMULATORS


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_simulators():
    return SIMULATORS
