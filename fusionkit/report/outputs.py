"""report.json, calibration.yaml and trajectories/<robot>.tum from a RunResult."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .. import __version__
from ..data.files import write_tum
from ..pipeline import ParameterEstimate, RunResult
from ..robots.calibration_file import calibration_entry
from ..robots.description import Parameter


def _as_parameter(est: ParameterEstimate, result: RunResult) -> Parameter:
    base = est.name.split("[")[0]
    desc = result.config.robots[est.robot].description.parameters.get(base)
    if desc is not None and est.series_t is None:
        return desc
    return Parameter(est.name, est.family.vartype, est.values, None, indexed=len(est.values) > 1 or
                     (desc is not None and desc.indexed))


def parameter_entry(est: ParameterEstimate, result: RunResult) -> dict[str, Any]:
    """{type, value|values, sigma}; time-varying parameters give the last value plus their series."""
    param = _as_parameter(est, result)
    if est.series_t is None:
        return calibration_entry(param, est.values, est.sigma)
    entry = calibration_entry(Parameter(est.name, param.vartype, est.values[-1:], None, False), est.values[-1:],
                              None if est.sigma is None else est.sigma[-1:])
    entry["time_varying"] = True
    return entry


def calibration_document(result: RunResult) -> dict:
    robots: dict[str, dict] = {}
    for robot, params in result.parameters.items():
        for name, est in params.items():
            robots.setdefault(robot, {})[name] = parameter_entry(est, result)
    return {"fusionkit_calibration": 1, "robots": robots}


def report_document(result: RunResult) -> dict:
    problem = result.problem
    counts: dict[str, int] = {}
    for r in problem.records:
        counts[r.label] = counts.get(r.label, 0) + 1
    params: dict[str, dict] = {}
    for robot, group in result.parameters.items():
        for name, est in group.items():
            entry = parameter_entry(est, result)
            if est.series_t is not None:
                entry["series"] = {"t": est.series_t.tolist(),
                                   "values": [est.family.vartype.to_list(v) for v in est.values]}
                if est.sigma is not None:
                    entry["series"]["sigma"] = est.sigma.tolist()
            params.setdefault(robot, {})[name] = entry
    solver = result.solution.stats()
    return {
        "fusionkit_version": __version__,
        "name": result.config.name,
        "config": str(result.config.doc.file),
        "problem": {"factors": len(problem.records), "variables": int(problem.initial.size()),
                    "states": {r: len(s) for r, s in problem.states.items()}, "factors_by_entry": counts},
        "solver": solver,
        "final_cost": solver["final_cost"],
        "timings_s": result.timings,
        "parameters": params,
        "evaluation": result.evaluation,
        "notes": problem.notes,
    }


def _json_default(o: Any):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def write_outputs(result: RunResult, out: Path, plots: bool = True) -> None:
    """Write every output file into `out` (a fresh folder)."""
    (out / "trajectories").mkdir()
    (out / "report.json").write_text(json.dumps(report_document(result), indent=2, default=_json_default))
    (out / "calibration.yaml").write_text(yaml.safe_dump(calibration_document(result), sort_keys=False))
    for robot, traj in result.trajectories.items():
        write_tum(out / "trajectories" / f"{robot}.tum", traj)
    if plots:
        from .plots import write_plots
        (out / "plots").mkdir()
        write_plots(result, out / "plots")
