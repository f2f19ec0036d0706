"""calibration.yaml: calibrated parameters per robot with 1-sigma; also the truth format.

    fusionkit_calibration: 1
    robots:
      cam:
        vo_scale: {type: scalar, value: 2.0, sigma: 0.01}
        pulley:   {type: point3, values: [[...], ...], sigma: [[...], ...], components: [x, y, z], ...}
        marker:   {type: pose3, value: [x, y, z, qx, qy, qz, qw], sigma: [rx, ry, rz, tx, ty, tz],
                   components: [x, y, z, qx, qy, qz, qw], sigma_components: [rx, ry, rz, tx, ty, tz]}

Sigmas are per tangent axis in GTSAM's order: for poses and rotations rx ry rz is the rotation about
the body axes (rad) and tx ty tz the translation along them (m). `components` and `sigma_components`
name the entries of the value and sigma lists; when present on reading they must be these names.
`elements` names the values of a parameter whose robot model names its elements (a serial arm's
`joint_offsets: {values: [...], elements: [shoulder_pan_joint, ...]}`, one per joint); when present on
reading they must be the description's names, in its order.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..config.yamlio import Document
from ..plugins import variable_type
from .description import Parameter, RobotDescription, _sigma_array


def _check_components(doc: Document, path: tuple, entry: dict) -> None:
    """A located error when `components` / `sigma_components` name other entries than fusionkit's order."""
    kind = entry.get("type")
    try:
        vartype = variable_type(kind) if isinstance(kind, str) else None
    except ValueError:
        vartype = None  # its values are read as the description's parameter's type when applied
    if vartype is None or not vartype.components:
        return
    for key, what, expected in zip(("components", "sigma_components"), ("value", "sigma"), vartype.names()):
        got = entry.get(key, list(expected))
        if got != list(expected):
            shown = f"[{', '.join(map(str, got))}]" if isinstance(got, list) else repr(got)
            raise doc.error(path + (key,), f"got {shown}; expected [{', '.join(expected)}], the order of a "
                            f"{kind} {what}: reorder the numbers and their names together")


def calibration_entries(doc: Document) -> dict[str, dict[str, Any]]:
    """robot -> parameter -> entry, with a located error if the file is not in this format."""
    data = doc.data
    if not isinstance(data, dict) or not isinstance(data.get("robots"), dict):
        raise doc.error((), "not a calibration file: expected a top-level 'robots:' mapping "
                        "(as written by `fusionkit run` to calibration.yaml)")
    for robot, params in data["robots"].items():
        if not isinstance(params, dict):
            raise doc.error(("robots", robot), "expected a mapping of parameter name -> {value, sigma}")
        for name, entry in params.items():
            if not isinstance(entry, dict) or not ({"value", "values"} & set(entry)):
                raise doc.error(("robots", robot, name), "expected {value: ..., sigma: ...} or {values: [...]}")
            _check_components(doc, ("robots", robot, name), entry)
    return data["robots"]


def parameter_values(param: Parameter, entry: dict) -> list[Any]:
    raw = entry["values"] if "values" in entry else [entry["value"]]
    return [param.vartype.from_list(v) for v in raw]


def apply_calibration(desc: RobotDescription, entries: dict[str, Any], doc: Document, robot: str) -> None:
    """Override nominal values (and prior sigmas, when given) of `desc` from a calibration file."""
    for name, entry in entries.items():
        path = ("robots", robot, name)
        param = desc.parameters.get(name)
        if param is None:
            raise doc.error(path, f"robot {desc.name!r} has no parameter {name!r}; it has: "
                            f"{', '.join(sorted(desc.parameters))}")
        try:
            values = parameter_values(param, entry)
            if len(values) != param.count:
                raise ValueError(f"{len(values)} values given; the description has {param.count}")
            sigma = _sigma_array(entry.get("sigma"), param.count, param.vartype.dim)
        except (ValueError, TypeError) as exc:
            raise doc.error(path, str(exc)) from None
        _check_elements(doc, path + ("elements",), param, entry)
        param.values, param.known = values, True
        if sigma is not None:
            param.sigma, param.fixed = sigma, False
        if entry.get("fixed"):
            param.sigma, param.fixed = None, True


def _check_elements(doc: Document, path: tuple, param: Parameter, entry: dict) -> None:
    """A located error when `elements` names other elements than the description, or in another order."""
    if "elements" not in entry:
        return
    got, expected = entry["elements"], list(param.elements or ())
    if got == expected and expected:
        return
    shown = f"[{', '.join(map(str, got))}]" if isinstance(got, list) else repr(got)
    if not expected:
        raise doc.error(path, f"got {shown}; the description names no elements of {param.name!r} (they go by index): "
                        "remove `elements`")
    raise doc.error(path, f"got {shown}; expected [{', '.join(expected)}], the description's elements of "
                    f"{param.name!r} in its order: reorder the values and their names together")


def calibration_entry(param: Parameter, values: list[Any], sigmas: np.ndarray | None) -> dict[str, Any]:
    """One YAML entry: {type, value|values, sigma} with sigma per tangent axis; types with named
    components (VarType.components) name them in `components` after the value and `sigma_components` after the sigma;
    a parameter with named elements (`Parameter.elements`) names them in `elements` after the values."""
    names = param.vartype.names() if param.vartype.components else None
    out: dict[str, Any] = {"type": param.vartype.name}
    listed = [param.vartype.to_list(v) for v in values]
    sig = None if sigmas is None or param.fixed else [[float(x) for x in row] for row in np.atleast_2d(sigmas)]
    out["values" if param.indexed else "value"] = listed if param.indexed else listed[0]
    if param.indexed and param.elements and len(param.elements) == len(listed):
        out["elements"] = list(param.elements)
    if names:
        out["components"] = list(names[0])
    if sig is not None:
        out["sigma"] = sig if param.indexed else (sig[0][0] if len(sig[0]) == 1 else sig[0])
        if names:
            out["sigma_components"] = list(names[1])
    if param.fixed:
        out["fixed"] = True
    if param.unit:
        out["unit"] = param.unit
    return out
