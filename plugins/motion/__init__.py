"""Built-in `motion` plugin: motion models between consecutive states of any robot -- wheel odometry
(differential drive), dead reckoning logged as increments, and a constant-velocity prior."""

from fusionkit.api import hookimpl

from .factors import FACTOR_TYPES

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES
