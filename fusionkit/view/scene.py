"""The 3-D scene of a run, written as scene.json beside report.json and drawn by `fusionkit view`:

- trajectories: each robot's estimate and its truth (polylines, world frame, m);
- static shapes: point parameters (pulleys, anchors) at their estimates with their 3-sigma ellipsoids
  (axis-aligned, from the per-axis sigmas) and the true points when known;
- frames: at `FRAMES` times spread over the run, what each robot's model draws of itself at that time
  (`RobotModel.geometry`: cables, links, ...), its body frame's axes and the 3-sigma ellipsoid of its
  position.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..pipeline import RunResult, world_position_covariance
from ..plugins import registry
from .shapes import Lines, Points, polyline

SCENE_FILE = "scene.json"
SCENE_VERSION = 1
FRAMES = 40
AXIS_LENGTH = 0.08  # body axes drawn at this fraction of the trajectories' span
ESTIMATE, TRUTH, SIGMA = "#d62728", "#000000", "#1f77b4"
ROBOT_COLORS = ("#d62728", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf")  # estimates, robot by robot


def ellipsoid(label: str, center, covariance, k: float = 3.0) -> dict:
    """The k-sigma ellipsoid of a position covariance (3x3, or 2x2 for a planar point, m^2) about center:
    `axes` holds its semi-axes (m) as columns, along the covariance's principal directions."""
    c = np.zeros((3, 3))
    cov = np.asarray(covariance, float)
    c[:len(cov), :len(cov)] = cov
    w, v = np.linalg.eigh((c + c.T) / 2)
    return {"kind": "ellipsoid", "label": label, "color": SIGMA, "center": _xyz([center])[0].tolist(),
            "axes": (v * (k * np.sqrt(np.clip(w, 0.0, None)))).tolist()}


def _xyz(values) -> np.ndarray:
    a = np.asarray(values, float).reshape(len(values), -1)
    return np.column_stack([a[:, :3], np.zeros((len(a), max(0, 3 - a.shape[1])))])


def _point_parameters(result: RunResult) -> list[dict]:
    """Estimates of point parameters with their 3-sigma ellipsoids (full covariance where the solver gave
    it, else the per-axis sigmas), and their truth."""
    shapes = []
    covariances = result.solution.covariances or {}
    for robot, params in result.parameters.items():
        for name, est in params.items():
            if est.series_t is not None or est.family.vartype.name not in ("point3", "point2"):
                continue
            xyz = _xyz([est.family.vartype.to_list(v) for v in est.values])
            shapes.append(Points(f"{robot}/{name}", xyz, ESTIMATE).to_json())
            for i, p in enumerate(xyz):
                cov = covariances.get(est.family.key(i)) if est.family.indexed else covariances.get(est.family.key())
                if cov is None and est.sigma is not None:
                    cov = np.diag(np.asarray(est.sigma[i], float) ** 2)
                if cov is not None:
                    shapes.append(ellipsoid(f"{robot}/{name}[{i}] 3-sigma", p, cov))
            true = result.truth.calibration.get(robot, {}).get(name)
            if true is not None and true.get("values") is not None:
                shapes.append(Points(f"{robot}/{name} truth", _xyz(true["values"]), TRUTH, 4.0).to_json())
    return shapes


def _trajectories(result: RunResult) -> list[dict]:
    out = []
    for robot, traj in result.trajectories.items():
        out.append(Lines(f"{robot} estimate", polyline(traj.pose_array()[:, :3]), _color(result, robot)).to_json())
        truth = result.truth.trajectories.get(robot)
        if truth is not None:
            out.append(Lines(f"{robot} truth", polyline(truth.pose_array()[:, :3]), TRUTH, 1.0).to_json())
    return out


def _color(result: RunResult, robot: str) -> str:
    return ROBOT_COLORS[list(result.trajectories).index(robot) % len(ROBOT_COLORS)]


def _state_at(result: RunResult, robot: str, t: float) -> tuple[dict[str, Any], int | None]:
    """The robot's per-state values nearest to time t: {family: value} (`pose` as a Pose3), and the index of
    its trajectory's sample (None without a trajectory)."""
    state, index = {}, None
    traj = result.trajectories.get(robot)
    if traj is not None:
        index = int(np.argmin(np.abs(traj.t - t)))
        state["pose"] = traj.poses()[index]
    for (r, family), series in result.states.items():
        if r == robot and len(series.t) and family not in state:  # a trajectory's poses are Pose3 (planar: lifted)
            state[family] = series.values[int(np.argmin(np.abs(series.t - t)))]
    return state, index


def _frame(result: RunResult, models: dict, calibrated: dict, covariance_keys: dict, axis_length: float,
           t: float) -> list[dict]:
    shapes = []
    for robot, model in models.items():
        state, index = _state_at(result, robot, t)
        if not state:
            continue
        shapes += [s.to_json() for s in model.geometry(robot, calibrated[robot], state)]
        if index is None:
            continue
        pose = state["pose"]
        keys = covariance_keys.get(robot)
        if keys is not None:
            planar = result.problem.states[robot].family.vartype.name == "pose2"
            cov = world_position_covariance(pose.rotation().matrix(), result.solution.covariances[keys[index]], planar)
            shapes.append(ellipsoid(f"{robot} position 3-sigma", pose.translation(), cov))
        shapes.append(Points(f"{robot} now", pose.translation()[None], _color(result, robot), 8.0).to_json())
        shapes += body_axes(robot, pose.matrix(), axis_length)
    return shapes


def _covariance_keys(result: RunResult, robot: str) -> list[int] | None:
    """The state keys of the robot's trajectory samples, when each has a marginal covariance."""
    states = result.problem.states.get(robot)
    if states is None or robot not in result.trajectories:
        return None
    keys = [k for k in states.family.keys(range(len(states))) if k in result.solution.covariances]
    return keys if len(keys) == len(result.trajectories[robot].t) else None


def body_axes(robot: str, T: np.ndarray, length: float) -> list[dict]:
    """The body frame at pose T (4x4): x, y, z axes of `length` m in red, green, blue."""
    return [Lines(f"{robot} body {name}", np.stack([T[:3, 3], T[:3, 3] + length * T[:3, i]])[None], color, 2.5).to_json()
            for i, (name, color) in enumerate(zip("xyz", ("#ff0000", "#00aa00", "#0000ff")))]


def _extent(result: RunResult) -> float:
    """The largest span of the trajectories (m), at least 0.1 m."""
    spans = [np.ptp(t.pose_array()[:, :3], axis=0).max() for t in result.trajectories.values() if len(t.t)]
    return max(spans + [0.1])


def build_scene(result: RunResult) -> dict:
    from ..report.outputs import calibrated_description
    reg = registry()
    models = {robot: reg.get("robot_models", setup.description.model)()
              for robot, setup in result.config.robots.items()}
    calibrated = {robot: calibrated_description(result, robot) for robot in models}
    spans = [(s.t[0], s.t[-1]) for s in result.trajectories.values() if len(s.t)] + \
        [(s.t[0], s.t[-1]) for s in result.states.values() if len(s.t)]
    times = np.linspace(min(a for a, _ in spans), max(b for _, b in spans), FRAMES).tolist() if spans else []
    static = _point_parameters(result)
    for robot, model in models.items():  # geometry that does not move (a robot without states)
        if not _state_at(result, robot, 0.0)[0]:
            static += [s.to_json() for s in model.geometry(robot, calibrated[robot], {})]
    covariance_keys = {robot: _covariance_keys(result, robot) for robot in models}
    axis_length = AXIS_LENGTH * _extent(result)
    return {"fusionkit_scene": SCENE_VERSION, "name": result.config.name, "trajectories": _trajectories(result),
            "static": static, "times": times,
            "frames": [_frame(result, models, calibrated, covariance_keys, axis_length, t) for t in times]}


def is_empty(scene: dict) -> bool:
    """Nothing to draw: no trajectory, no point parameter, no robot geometry at any time."""
    return not (scene["trajectories"] or scene["static"] or any(scene["frames"]))


def load_scene(folder: Path) -> dict:
    """scene.json of an output folder; FileNotFoundError / ValueError with the reason."""
    file = Path(folder) / SCENE_FILE
    if not file.is_file():
        raise FileNotFoundError(f"{folder}: no {SCENE_FILE} (expected the output folder of `fusionkit run`)")
    scene = json.loads(file.read_text())
    if scene.get("fusionkit_scene") != SCENE_VERSION:
        raise ValueError(f"{file}: not a fusionkit scene of version {SCENE_VERSION}")
    return scene

