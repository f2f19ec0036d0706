"""A robot description checked by its robot model: what each robot of a config gets, and what a
plugin command reads (`fusionkit.api.load_robot_description`)."""

from __future__ import annotations

from pathlib import Path

from ..config.schema import validate_against
from ..config.yamlio import load_yaml
from ..errors import ConfigError, PluginError
from .calibration_file import apply_calibration, calibration_entries
from .description import COMMON_KEYS, RobotDescription, description_from_document
from .registered import is_description_name, registered_document


def check_with_model(desc: RobotDescription, reg) -> RobotDescription:
    """`desc` after its robot model (registry `reg`) validated the model keys (its `schema`) and ran
    `check_description`; errors are located in the description's file. Each indexed parameter gets the
    names of its elements the model gives (`Parameter.elements`), a vector parameter those of its components
    (`Parameter.axes`)."""
    model = reg.get("robot_models", desc.model)
    if model is None:
        raise desc.error(("model",), reg.unknown("robot_models", desc.model))
    model_schema = dict(model.schema)
    # the common keys were validated already; listing them keeps "accepted keys" complete
    model_schema["properties"] = {**{k: {} for k in COMMON_KEYS}, **model.schema.get("properties", {})}
    validate_against(desc.doc, model_schema, desc.extra)
    instance = model()
    instance.check_description(desc)
    for name, param in desc.parameters.items():
        axes = instance.axis_names(desc, name)
        if axes is not None:
            axes = tuple(str(a) for a in axes)
            if len(axes) != param.vartype.dim or len(set(axes)) != len(axes):
                raise PluginError(f"robot model {model.name}: axis_names gave {list(axes)} for parameter {name!r} of "
                                  f"{desc.name!r}; expected {param.vartype.dim} distinct names (plugin bug)")
            param.axes = axes
        names = instance.element_names(desc, name) if param.indexed else None
        if names is None:
            continue
        names = tuple(str(n) for n in names)
        if len(names) != param.count or len(set(names)) != len(names):
            raise PluginError(f"robot model {model.name}: element_names gave {list(names)} for parameter {name!r} "
                              f"of {desc.name!r}; expected {param.count} distinct names, one per value (plugin bug)")
        param.elements = names
    return desc


def load_robot_description(source: str | Path, base: Path | None = None, calibration: str | Path | None = None,
                           robot: str | None = None) -> RobotDescription:
    """The robot description `source` names -- a shipped one by name (`ur10_tracker`) or a YAML file
    (relative to `base`, default the working folder) -- checked as a config's robots are; with `calibration`, a
    calibration file (`fusionkit run`'s calibration.yaml) applied over it: the entries of `robot` (needed when the
    file has several robots). One located ConfigError otherwise."""
    from ..plugins import registry
    reg = registry()
    if is_description_name(str(source)):
        desc = check_with_model(description_from_document(registered_document(str(source), reg, None, ())), reg)
    else:
        file = _existing(source, base, "robot description")
        desc = check_with_model(description_from_document(load_yaml(file)), reg)
    if calibration is not None:
        doc = load_yaml(_existing(calibration, base, "calibration"))
        entries = calibration_entries(doc)
        if robot is None and len(entries) != 1:
            raise ConfigError(f"{doc.file}: the calibration has robots {', '.join(sorted(entries)) or '(none)'}; "
                              "name the one to apply")
        name = robot if robot is not None else next(iter(entries))
        if name not in entries:
            raise ConfigError(f"{doc.file}: no robot {name!r} in the calibration; it has {', '.join(sorted(entries))}")
        apply_calibration(desc, entries[name], doc, name)
    return desc


def _existing(source: str | Path, base: Path | None, what: str) -> Path:
    file = Path(source) if Path(source).is_absolute() else Path(base or Path.cwd()) / source
    if not file.is_file():
        raise ConfigError(f"{what} file not found: {file}" + (" (a folder)" if file.is_dir() else ""))
    return file
