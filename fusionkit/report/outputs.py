"""report.json, report.html, calibration.yaml, trajectories/<robot>.tum, each robot model's own files
(`RobotModel.outputs`) and, when asked, covariances/<robot>.csv from a RunResult."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from .. import __version__
from ..data.files import write_tum
from ..eval.states import StateSeries
from ..pipeline import ParameterEstimate, RunResult
from ..descriptions.calibration_file import calibration_entry
from ..plugins import registry
from ..descriptions.description import Parameter, RobotDescription
from .writer import write_files


def estimate_entry(result: RunResult, est: ParameterEstimate) -> dict[str, Any]:
    """{type, value|values, sigma} of one estimate (a time-varying one: its last value)."""
    desc = result.config.robots[est.robot].description.parameters.get(est.name)
    if desc is not None and est.series_t is None:
        return calibration_entry(desc, est.values, est.sigma)
    values, sigma = est.values, est.sigma
    if est.series_t is not None:
        values, sigma = values[-1:], None if sigma is None else sigma[-1:]
    return calibration_entry(Parameter(est.name, est.family.vartype, values, None, indexed=len(values) > 1),
                             values, sigma)


def _estimated(param: Parameter, estimates: dict[str, ParameterEstimate]) -> tuple[list, np.ndarray | None] | None:
    """(values, sigma) of a description parameter's estimate, a time-varying one's last value per
    element; None when it was not estimated."""
    if not param.time_varying:
        est = estimates.get(param.name)
        return None if est is None else (est.values, est.sigma)
    names = [f"{param.name}[{i}]" for i in range(param.count)] if param.indexed else [param.name]
    series = [estimates.get(n) for n in names]
    if any(e is None for e in series):
        return None
    last = [e.values[-1] for e in series]
    sigma = None if any(e.sigma is None for e in series) else np.array([e.sigma[-1] for e in series])
    return last, sigma


def _description_entry(param: Parameter, estimates: dict[str, ParameterEstimate]) -> dict[str, Any] | None:
    """Entry of a description parameter; a time-varying one gives its last value per element."""
    found = _estimated(param, estimates)
    if found is None:
        return None
    entry = calibration_entry(param, *found)
    return {**entry, "time_varying": True} if param.time_varying else entry


def calibrated_description(result: RunResult, robot: str) -> RobotDescription:
    """The robot's description with each estimated parameter at its estimate (time-varying: the last
    value), what a robot model's `outputs` receives."""
    desc = result.config.robots[robot].description
    estimates = result.parameters.get(robot, {})
    parameters = {}
    for name, param in desc.parameters.items():
        found = _estimated(param, estimates)
        keep = found is None or len(found[0]) != param.count
        parameters[name] = param if keep else replace(param, values=list(found[0]))
    return replace(desc, parameters=parameters)


def calibration_document(result: RunResult) -> dict:
    """`robots:` holds description parameters (loadable as overrides); `other:` the rest."""
    robots: dict[str, dict] = {}
    other: dict[str, dict] = {}
    for robot, estimates in result.parameters.items():
        described = result.config.robots[robot].description.parameters
        for param in described.values():
            entry = _description_entry(param, estimates)
            if entry is not None:
                robots.setdefault(robot, {})[param.name] = entry
        for name, est in estimates.items():
            if name.split("[")[0] not in described:
                other.setdefault(robot, {})[name] = estimate_entry(result, est)
    doc: dict[str, Any] = {"fusionkit_calibration": 1, "robots": robots}
    if other:
        doc["other"] = other
    return doc


def identifiability_document(result: RunResult) -> dict | None:
    """report.json `identifiability`: the joint covariance's report and, under `analyses`, the labels of the
    families' own analyses of what the data determine (their reports under `diagnostics`) with their verdicts."""
    out = result.identifiability.to_json() if result.identifiability else None
    analyses = {label: result.problem.diagnostics[label].get("verdict", []) for label in result.problem.analyses}
    if analyses:
        out = {**(out or {}), "analyses": analyses}
    return out


def report_document(result: RunResult) -> dict:
    problem = result.problem
    counts: dict[str, int] = {}
    for r in problem.records:
        counts[r.label] = counts.get(r.label, 0) + 1
    params: dict[str, dict] = {}
    for robot, group in result.parameters.items():
        for name, est in group.items():
            entry = estimate_entry(result, est)
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
        "states": states_entry(result),
        "status": solver["status"],  # "rejected": a check refused the solution (solver.rejection says why)
        "warnings": solver["warnings"],  # what the checks that need no ground truth found (also in solver)
        "solver": solver,
        "final_cost": solver["final_cost"],
        "timings_s": result.timings,
        "parameters": params,
        "identifiability": identifiability_document(result),
        "evaluation": result.evaluation,
        "diagnostics": problem.diagnostics,
        "notes": result.notes,
    }


class _Dumper(yaml.SafeDumper):
    """Lists of numbers or names on one line (`value: [x, y, z]`), everything else in block style."""


_Dumper.add_representer(list, lambda dumper, data: dumper.represent_sequence(
    "tag:yaml.org,2002:seq", data, flow_style=all(isinstance(x, (int, float, str)) for x in data)))


def calibration_text(doc: dict) -> str:
    """calibration.yaml's text: each list of numbers (a value, a sigma) or names on one line."""
    return yaml.dump(doc, Dumper=_Dumper, sort_keys=False, width=4096)


def series_files(result: RunResult) -> dict[str, StateSeries]:
    """states/<robot>.<family>.csv for every per-state family that is not a robot's trajectory (those
    are trajectories/<robot>.tum): velocities, biases, joint vectors, non-pose states."""
    return {f"states/{robot}.{family}.csv": series for (robot, family), series in result.states.items()
            if not (robot in result.trajectories and series.vartype.name in ("pose3", "pose2"))}


def states_entry(result: RunResult) -> dict:
    """report.json `states`: robot -> family -> type, number of states, components, file."""
    files = {id(series): file for file, series in series_files(result).items()}
    out: dict[str, dict] = {}
    for (robot, family), series in result.states.items():
        out.setdefault(robot, {})[family] = {
            "type": series.vartype.name, "count": len(series.t), "components": list(series.vartype.names()[0]),
            "file": files.get(id(series), f"trajectories/{robot}.tum")}
    return out


def _json_default(o: Any):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def write_outputs(result: RunResult, out: Path, plots: bool = True) -> None:
    """Write every output file into `out` (a fresh folder)."""
    (out / "report.json").write_text(json.dumps(report_document(result), indent=2, default=_json_default))
    (out / "calibration.yaml").write_text(calibration_text(calibration_document(result)))
    for robot, traj in result.trajectories.items():
        (out / "trajectories").mkdir(exist_ok=True)
        write_tum(out / "trajectories" / f"{robot}.tum", traj)
    for file, series in series_files(result).items():
        (out / "states").mkdir(exist_ok=True)
        columns, rows = series.table()
        np.savetxt(out / file, rows, delimiter=",", header=",".join(columns), comments="",
                   fmt=["%.9f"] + ["%.12g"] * (rows.shape[1] - 1))
    if result.config.output["state_covariances"]:
        from .covariances import write_state_covariances
        write_state_covariances(result, out / "covariances")
    from ..view.scene import SCENE_FILE, build_scene, is_empty
    scene = build_scene(result)
    (out / SCENE_FILE).write_text(json.dumps(scene, default=_json_default))
    if plots:
        from ..view.render_matplotlib import render_png
        from .plots import write_plots
        (out / "plots").mkdir()
        write_plots(result, out / "plots")
        if not is_empty(scene):
            render_png(scene, out / "plots" / "scene_3d.png")
    from .html import report_html
    (out / "report.html").write_text(report_html(result, out / "plots" if plots else None), encoding="utf-8")
    for robot, setup in result.config.robots.items():  # model-specific files (RobotModel.outputs)
        model = registry().get("robot_models", setup.description.model)
        write_files(out, model().outputs(robot, calibrated_description(result, robot)), f"robot model {model.name}")
