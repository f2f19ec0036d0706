"""`arash` plugin: ARASH:ASiST's parallelogram remote-centre-of-motion arm (docs/models/arash.md) --
the `rcm_arm` robot model with the forward kinematics of thesis eq. 3.7 and of the authors' code,
joint-encoder and tracked-tool factors, two arms co-registered through a base-to-base transform, and
the leader/follower simulator."""

from fusionkit.api import hookimpl, robot_description_files

from .factors import FACTOR_TYPES
from .initializers import INITIALIZERS
from .model import RcmArmModel
from .simulators import SIMULATORS

FUSIONKIT_API = "1.14"  # the fusionkit plugin API this family is written for (fusionkit.api.API_VERSION)


@hookimpl
def register_factor_types():
    return FACTOR_TYPES


@hookimpl
def register_robot_models():
    return [RcmArmModel]


@hookimpl
def register_initializers():
    return INITIALIZERS


@hookimpl
def register_simulators():
    return SIMULATORS


@hookimpl
def register_robot_descriptions():
    return robot_description_files("fusionkit_robots", "arash")  # robots/arash/ of the repository
