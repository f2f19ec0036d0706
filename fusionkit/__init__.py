"""fusionkit: robot calibration and state estimation with factor graphs, declared in YAML.

For users: `load_config` and `run` (or the `fusionkit` command). For plugin authors: `fusionkit.api`, the one
public plugin API (versioned: `fusionkit.api.API_VERSION`); every other module is internal.
"""

from __future__ import annotations

__version__ = "0.1.0"


def load_config(path, overrides=()):
    """Load and validate a run config (see `fusionkit.config.loader.load_config`)."""
    from .config.loader import load_config as _load
    return _load(path, overrides)


def run(path, overrides=()):
    """Load a config and estimate; returns a `fusionkit.pipeline.RunResult` (writes nothing)."""
    from .pipeline import estimate
    return estimate(load_config(path, overrides))


__all__ = ["load_config", "run", "__version__"]
