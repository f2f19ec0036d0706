"""Robot descriptions: frames, sensors with mounting transforms, parameters with prior sigmas.

A description is a YAML file (see docs/reference/robot_description.md). Keys other than the
common ones below belong to the robot model (`model:`), which validates them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gtsam
import numpy as np

from ..config.schema import validate_against
from ..config.yamlio import Document, load_yaml
from ..graph.variables import POSE3, VarType
from ..plugins import variable_type, variable_type_names
from .registered import is_description_name, registered_document

POSE_SCHEMA = {
    "type": "object",
    "properties": {
        "translation": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
        "rotation_rpy": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
        "quaternion_xyzw": {"type": "array", "items": {"type": "number"}, "minItems": 4, "maxItems": 4},
    },
    "additionalProperties": False,
}

COMMON_KEYS = {"name", "model", "frames", "sensors", "parameters", "summary"}

DESCRIPTION_SCHEMA = {
    "type": "object",
    "properties": {
        "name": {"type": "string"},
        "summary": {"type": "string"},
        "model": {"type": "string"},
        "frames": {"type": "array", "items": {"type": "string"}},
        "sensors": {
            "type": "object",
            "additionalProperties": {
                "type": "object",
                "properties": {
                    "type": {"type": "string"},
                    "frame": {"type": "string"},
                    "mount": POSE_SCHEMA,
                },
                "required": ["type"],
            },
        },
        "parameters": {
            "type": "object",
            "additionalProperties": {
                "type": "object",
                "properties": {
                    "type": {"type": "string"},
                    "value": {},
                    "values": {"type": "array", "minItems": 1},
                    "count": {"type": "integer", "minimum": 1},
                    "sigma": {"type": ["number", "array", "null"]},
                    "fixed": {"type": "boolean"},
                    "time_varying": {"type": "boolean"},
                    "unit": {"type": "string"},
                    "summary": {"type": "string"},
                },
                "required": ["type"],
                "additionalProperties": False,
            },
        },
    },
    "required": ["name"],
}


@dataclass
class Parameter:
    """A calibration parameter: nominal value(s) and the 1-sigma of its prior (None: no prior).

    `fixed`: held at its value (not estimated). `known` is False when the description gives no
    value: `values` then holds placeholders (zeros) until an initializer sets the variables.
    `elements`: the names of an indexed parameter's elements its robot model gives
    (`RobotModel.element_names`: a serial arm's joint offsets by joint), set when the model checks
    the description; None: they go by index."""

    name: str
    vartype: VarType
    values: list[Any]
    sigma: np.ndarray | None  # shape (count, dim)
    indexed: bool
    time_varying: bool = False
    unit: str = ""
    fixed: bool = False
    known: bool = True
    elements: tuple[str, ...] | None = None
    axes: tuple[str, ...] | None = None  # a vector parameter's component names (`RobotModel.axis_names`)

    @property
    def count(self) -> int:
        return len(self.values)

    def element(self, i: int | None) -> str:
        """How element i is named everywhere (summary, report, calibration.yaml, messages):
        `joint_offsets[elbow_joint]` with element names, else `pulley[2]`; `vo_scale` if not indexed."""
        if not self.indexed or i is None:
            return self.name
        return f"{self.name}[{self.elements[i] if self.elements else i}]"


@dataclass
class Sensor:
    name: str
    type: str
    frame: str
    mount: gtsam.Pose3  # body_T_sensor
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class RobotDescription:
    name: str
    model: str
    frames: list[str]
    sensors: dict[str, Sensor]
    parameters: dict[str, Parameter]
    extra: dict[str, Any]
    doc: Document

    def error(self, path: tuple, message: str):
        return self.doc.error(path, message)


FIXED_HINT = "to hold a parameter at its value, write `fixed: true` instead of a sigma"


def _sigma_array(raw: Any, count: int, dim: int) -> np.ndarray | None:
    if raw is None:
        return None
    a = np.asarray(raw, float)
    if a.ndim == 0:
        a = np.full((count, dim), float(a))
    elif a.shape == (dim,):
        a = np.tile(a, (count, 1))
    elif a.shape == (count,) and dim == 1:
        a = a.reshape(count, 1)
    if a.shape != (count, dim):
        raise ValueError(f"expected a number, {dim} numbers, or {count} lists of {dim} numbers")
    if np.any(~np.isfinite(a)) or np.any(a <= 0):
        raise ValueError(f"sigmas must be positive and finite ({FIXED_HINT})")
    return a


def _parameter(doc: Document, name: str, raw: dict) -> Parameter:
    path = ("parameters", name)
    try:
        vartype = variable_type(raw["type"])
    except ValueError:
        raise doc.error(path + ("type",), f"unknown variable type {raw['type']!r}; installed: "
                        f"{', '.join(variable_type_names())}") from None
    given = [k for k in ("value", "values", "count") if k in raw]
    if len(given) > 1:
        raise doc.error(path + (given[1],), f"give one of value, values or count (not {' and '.join(given)})")
    known = "count" not in raw and given != []
    if not known:  # no value: an initializer must supply it; no prior, nothing to hold fixed
        for key in ("sigma", "fixed", "time_varying"):
            if raw.get(key) not in (None, False):
                raise doc.error(path + (key,), f"`{key}` needs the parameter's value: give `value:` (or "
                                "`values:`), or drop it and let an initializer estimate the parameter")
    indexed = "values" in raw or "count" in raw
    raw_values = raw["values"] if "values" in raw else [raw["value"]] if "value" in raw else None
    values = []
    for i, v in enumerate(raw_values or []):
        try:
            values.append(vartype.from_list(v))
        except (ValueError, TypeError) as exc:
            where = path + (("values", i) if indexed else ("value",))
            raise doc.error(where, f"{exc} for a {vartype.name}") from None
    if raw_values is None:
        values = [vartype.zero() for _ in range(raw.get("count", 1))]
    fixed = bool(raw.get("fixed", False))
    if fixed and (raw.get("sigma") is not None or raw.get("time_varying")):
        key = "sigma" if raw.get("sigma") is not None else "time_varying"
        raise doc.error(path + (key,), f"a fixed parameter is held at its value: it has no {key}")
    try:
        sigma = _sigma_array(raw.get("sigma"), len(values), vartype.dim)
    except ValueError as exc:
        raise doc.error(path + ("sigma",), str(exc)) from None
    return Parameter(name, vartype, values, sigma, indexed, bool(raw.get("time_varying", False)),
                     raw.get("unit", ""), fixed, known)


def description_from_document(doc: Document) -> RobotDescription:
    """Validate the common part of a description and build it (model keys stay in `extra`)."""
    validate_against(doc, DESCRIPTION_SCHEMA, doc.data)
    data = doc.data
    sensors = {}
    for name, raw in (data.get("sensors") or {}).items():
        mount = POSE3.from_list(raw["mount"]) if "mount" in raw else gtsam.Pose3()
        extra = {k: v for k, v in raw.items() if k not in ("type", "frame", "mount")}
        sensors[name] = Sensor(name, raw["type"], raw.get("frame", "body"), mount, extra)
    parameters = {name: _parameter(doc, name, raw) for name, raw in (data.get("parameters") or {}).items()}
    extra = {k: v for k, v in data.items() if k not in COMMON_KEYS}
    return RobotDescription(data["name"], data.get("model", "generic"), list(data.get("frames", [])),
                            sensors, parameters, extra, doc)


def load_description(source: str | Path | dict, base: Path, where: Document, path: tuple, reg) -> RobotDescription:
    """Load a description from a file (relative to `base`), an inline mapping in the config, or by
    the name a plugin registered it under (a string without path separator or .yaml/.yml suffix,
    looked up in the registry `reg`)."""
    if isinstance(source, dict):
        sub = Document(source, where.file, {k[len(path):]: v for k, v in where.lines.items()
                                            if k[:len(path)] == path})
        return description_from_document(sub)
    if is_description_name(str(source)):
        return description_from_document(registered_document(str(source), reg, where, path))
    file = (base / source) if not Path(source).is_absolute() else Path(source)
    if not file.exists():
        raise where.error(path, f"robot description file not found: {file}")
    return description_from_document(load_yaml(file))
