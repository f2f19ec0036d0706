"""Every hook a fusionkit plugin can implement. All are registration hooks, called once.

A plugin is a module (or object) with functions decorated by `fusionkit.api.hookimpl`; third-party
packages expose it through the `fusionkit` entry-point group in their pyproject.toml:

    [project.entry-points.fusionkit]
    myplugin = "my_package.plugin"
"""

from __future__ import annotations

import pluggy

hookspec = pluggy.HookspecMarker("fusionkit")
hookimpl = pluggy.HookimplMarker("fusionkit")  # public as fusionkit.api.hookimpl


@hookspec
def register_factor_types() -> list[type]:
    """Return `fusionkit.api.FactorType` subclasses (sensor models and constraints)."""


@hookspec
def register_sources() -> list[type]:
    """Return `fusionkit.api.Source` subclasses (file formats, bag readers, in-process generators)."""


@hookspec
def register_robot_models() -> list[type]:
    """Return `fusionkit.api.RobotModel` subclasses (robot types described in YAML)."""


@hookspec
def register_initializers() -> list[type]:
    """Return `fusionkit.api.Initializer` subclasses (initial values for the solver)."""


@hookspec
def register_simulators() -> list[type]:
    """Return `fusionkit.api.Simulator` subclasses (synthetic datasets with truth)."""


@hookspec
def register_robot_descriptions() -> dict:
    """Return {name: file} of robot descriptions shipped as package data (`importlib.resources`
    files, e.g. `fusionkit.api.robot_description_files(__name__)`): a config names one by name
    (`description: arascam`), a simulator reads one with `fusionkit.api.robot_description_data`."""


@hookspec
def register_commands() -> list[type]:
    """Return `fusionkit.api.Command` subclasses: subcommands `fusionkit <name>` (e.g. a planning tool
    that needs no config), listed by `fusionkit plugins` and `fusionkit --help`."""


@hookspec
def register_variable_types() -> list:
    """Return `fusionkit.api.VarType` values: kinds of unknowns the core does not know (e.g. camera
    intrinsics), each with its GTSAM storage and prior, its array form and retraction for vectorized
    residuals, how states of it are interpolated in time, and the names its values are printed with.
    Descriptions and `states: {type: ...}` then name it like a built-in type."""
