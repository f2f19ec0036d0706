"""fusionkit: robot calibration and state estimation with factor graphs, declared in YAML.

Public API for users and plugin authors.
"""

from __future__ import annotations

import pluggy

__version__ = "0.1.0"

hookimpl = pluggy.HookimplMarker("fusionkit")

from .components import (  # noqa: E402  (hookimpl must exist before plugins import it)
    CheckScope, FactorType, Initializer, RobotModel, Simulator, Source, SourceOutput, Spec)
from .data.stream import POSE_COLUMNS, Stream, pose_stream  # noqa: E402
from .errors import ConfigError, DataError, FusionkitError, PluginError, SolverError  # noqa: E402
from .graph.noise import POSE_SIGMA_SCHEMA, gaussian, pose_sigmas  # noqa: E402
from .graph.variables import (  # noqa: E402
    IMU_BIAS, POINT2, POINT3, POSE2, POSE3, ROT3, SCALAR, VELOCITY3, VarType, vector_type)


def load_config(path, overrides=()):
    """Load and validate a run config (see `fusionkit.config.loader.load_config`)."""
    from .config.loader import load_config as _load
    return _load(path, overrides)


def run(path, overrides=()):
    """Load a config and estimate; returns a `fusionkit.pipeline.RunResult` (writes nothing)."""
    from .pipeline import estimate
    return estimate(load_config(path, overrides))


__all__ = ["CheckScope", "ConfigError", "DataError", "FactorType", "FusionkitError", "Initializer",
           "PluginError", "RobotModel", "Simulator", "SolverError", "Source", "SourceOutput", "Spec",
           "Stream", "POSE_COLUMNS", "pose_stream", "gaussian", "pose_sigmas", "POSE_SIGMA_SCHEMA", "VarType",
           "vector_type", "POSE3", "POSE2",
           "POINT3", "POINT2", "ROT3", "SCALAR", "VELOCITY3", "IMU_BIAS",
           "hookimpl", "load_config", "run", "__version__"]
