"""Errors of estimated parameters against truth (same schema as calibration.yaml)."""

from __future__ import annotations

from typing import Any

import numpy as np


def parameter_errors(parameters: dict, truth: dict[str, dict[str, Any]]) -> dict:
    """robot -> parameter -> {abs_error (per element, tangent-space norm), mean_abs_error, z (error/sigma)}."""
    out: dict = {}
    for robot, entries in truth.items():
        for name, entry in entries.items():
            est = parameters.get(robot, {}).get(name)
            if est is None or est.series_t is not None:
                continue
            vt = est.family.vartype
            raw = entry["values"] if "values" in entry else [entry["value"]]
            true = [vt.from_list(v) for v in raw]
            if len(true) != len(est.values):
                continue
            diffs = np.array([vt.local(t, e) for t, e in zip(true, est.values)])
            norms = np.linalg.norm(diffs, axis=1)
            item = {"abs_error": norms.tolist(), "mean_abs_error": float(norms.mean())}
            if est.sigma is not None:
                item["z_per_axis"] = (diffs / est.sigma).tolist()
            out.setdefault(robot, {})[name] = item
    return out
