"""calibration.yaml: calibrated parameters per robot with 1-sigma; also the truth format.

    fusionkit_calibration: 1
    robots:
      cam:
        vo_scale: {type: scalar, value: 2.0, sigma: 0.01}
        pulley:   {type: point3, values: [[...], ...], sigma: [[...], ...]}
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..config.yamlio import Document
from .description import Parameter, RobotDescription, _sigma_array


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
        param.values = values
        if sigma is not None:
            param.sigma = sigma


def calibration_entry(param: Parameter, values: list[Any], sigmas: np.ndarray | None) -> dict[str, Any]:
    """One YAML entry: {type, value|values, sigma} with sigma per tangent axis."""
    out: dict[str, Any] = {"type": param.vartype.name}
    listed = [param.vartype.to_list(v) for v in values]
    sig = None if sigmas is None else [[float(x) for x in row] for row in np.atleast_2d(sigmas)]
    if param.indexed:
        out["values"] = listed
        if sig is not None:
            out["sigma"] = sig
    else:
        out["value"] = listed[0]
        if sig is not None:
            out["sigma"] = sig[0][0] if len(sig[0]) == 1 else sig[0]
    if param.unit:
        out["unit"] = param.unit
    return out
