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


POINT_TYPES = ("point3", "point2")


def aligned_point_errors(parameters: dict, truth: dict[str, dict[str, Any]], robots: list[str], alignment) -> dict:
    """robot -> parameter -> {aligned_abs_error (per point, m), aligned_mean_abs_error} of the point parameters
    (point3, point2) of `robots` (those without states: anchors, beacons, landmarks fixed in the world), after
    `alignment` (eval.trajectory.Alignment, estimate -> truth) -- the alignment the trajectories' ATE uses."""
    out: dict = {}
    for robot in robots:
        for name, entry in truth.get(robot, {}).items():
            est = parameters.get(robot, {}).get(name)
            if est is None or est.series_t is not None or est.family.vartype.name not in POINT_TYPES:
                continue
            raw = entry["values"] if "values" in entry else [entry["value"]]
            if len(raw) != len(est.values):
                continue
            estimated = np.array([np.asarray(v, float) for v in est.values])
            d = estimated.shape[1]
            lifted = np.column_stack([estimated, np.zeros((len(estimated), 3 - d))])
            errors = np.linalg.norm(alignment.apply(lifted)[:, :d] - np.asarray(raw, float), axis=1)
            out.setdefault(robot, {})[name] = {"aligned_abs_error": errors.tolist(),
                                               "aligned_mean_abs_error": float(errors.mean())}
    return out
