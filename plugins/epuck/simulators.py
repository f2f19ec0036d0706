"""`epuck.sim`: an e-puck driving loops in a walled arena, its IR readings and commanded speeds
(docs/reference/factors.md#simulators).

The robot follows a rounded rectangle `clearance` m inside the arena's bounding box (corner radius
`corner_radius`) counter-clockwise at `speed` m/s, steered by pure pursuit on its true pose; each
command (v, omega), held for 1/`rate` s, is executed through the velocity motion model with the
description's alphas times `motion_noise_scale`. At every step each IR sensor reads
g_s F_mean(d) + o_s + sqrt(F_var(d)) * `ir_sigma_scale` * N(0, 1), clipped to [0, `max_reading`], d the
true distance along its axis to the nearest wall (the models continued beyond their range as in
irmodel.py); g_s = 1 + N(0, `gain_error`), o_s = N(0, `offset_error`) counts -- a sensor model other
than the estimator's when they are not zero (the written description then has `ir_gain` and
`ir_offset` parameters, which the config estimates). The start pose is drawn around the path's
start with `start_sigma`, the prior the config gives it.

Streams: `commands` (t, v, omega: m/s, rad/s; right, left: the wheels' commanded angular speeds,
rad/s), `ir` (t, one column per IR sensor, counts); truth: the `puck` trajectory (and the gains and
offsets).
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import (ConfigError, NON_NEGATIVE_SCHEMA as NONNEG, POSE_NOISE_SCHEMA, POSITIVE_SCHEMA as POSITIVE,
                           Simulator, SourceOutput, Stream, pose_stream, robot_description_data)

from .model import alphas, ir_layout_from_data, walls_from_data
from .velocity import sample_motion
from .walls import sensor_distances

ROBOT, ARENA = "puck", "arena"
LOOKAHEAD = 0.03   # m: pure pursuit
MAX_TURN = 4.0     # rad/s: the controller's limit on omega


def loop_path(walls: np.ndarray, clearance: float, radius: float, step: float = 0.001) -> np.ndarray:
    """(n, 2) points every `step` m along a counter-clockwise rounded rectangle `clearance` m inside the
    walls' bounding box, from the start of its bottom side."""
    lo, hi = walls.reshape(-1, 2).min(axis=0) + clearance, walls.reshape(-1, 2).max(axis=0) - clearance
    if np.any(hi - lo <= 2 * radius):
        raise ConfigError(f"epuck.sim: clearance {clearance} m and corner_radius {radius} m leave no loop inside "
                          f"the arena ({np.ptp(walls.reshape(-1, 2), axis=0).round(3).tolist()} m)")
    corners = [(hi[0] - radius, lo[1] + radius, -np.pi / 2), (hi[0] - radius, hi[1] - radius, 0.0),
               (lo[0] + radius, hi[1] - radius, np.pi / 2), (lo[0] + radius, lo[1] + radius, np.pi)]
    starts = [np.array([lo[0] + radius, lo[1]]), np.array([hi[0], lo[1] + radius]),
              np.array([hi[0] - radius, hi[1]]), np.array([lo[0], hi[1] - radius])]
    points = []
    for (cx, cy, a0), start in zip(corners, starts):
        end = np.array([cx + radius * np.cos(a0), cy + radius * np.sin(a0)])
        n = max(2, int(np.linalg.norm(end - start) / step))
        points.append(start + np.linspace(0.0, 1.0, n, endpoint=False)[:, None] * (end - start))
        arc = a0 + np.linspace(0.0, np.pi / 2, max(2, int(radius * np.pi / 2 / step)), endpoint=False)
        points.append(np.column_stack([cx + radius * np.cos(arc), cy + radius * np.sin(arc)]))
    return np.concatenate(points)


def pure_pursuit(pose: np.ndarray, path: np.ndarray, hint: int, speed: float) -> tuple[float, float, int]:
    """(v, omega) steering `pose` towards the path point LOOKAHEAD m ahead of its nearest one (the loop
    is closed); the nearest point's index is searched near `hint` and returned."""
    n = len(path)
    window = (hint + np.arange(-50, 200)) % n
    nearest = int(window[np.argmin(np.sum((path[window] - pose[:2]) ** 2, axis=1))])
    target = path[(nearest + int(LOOKAHEAD / 0.001)) % n] - pose[:2]
    c, s = np.cos(pose[2]), np.sin(pose[2])
    ahead = np.array([c * target[0] + s * target[1], -s * target[0] + c * target[1]])
    curvature = 2.0 * ahead[1] / max(ahead @ ahead, 1e-12)
    return speed, float(np.clip(speed * curvature, -MAX_TURN, MAX_TURN)), nearest


class EpuckSimulator(Simulator):
    name = "epuck.sim"
    summary = ("e-puck looping in a walled arena (epuck_arena): commanded (v, omega) executed through the velocity "
               "model, IR readings from the sensor models (optionally with other gains, offsets, noise), truth")
    schema = {"type": "object",
              "properties": {"description": {"type": "string"}, "arena": {"type": "string"},
                             "duration": POSITIVE, "rate": POSITIVE, "speed": POSITIVE,
                             "clearance": POSITIVE, "corner_radius": POSITIVE,
                             "motion_noise_scale": NONNEG, "ir_sigma_scale": NONNEG,
                             "gain_error": NONNEG, "offset_error": NONNEG, "max_reading": POSITIVE,
                             "start_sigma": POSE_NOISE_SCHEMA},
              "additionalProperties": False}
    defaults = {"description": "epuck", "arena": "epuck_arena", "duration": 60.0, "rate": 10.0, "speed": 0.05,
                "clearance": 0.06, "corner_radius": 0.04, "motion_noise_scale": 1.0, "ir_sigma_scale": 1.0,
                "gain_error": 0.0, "offset_error": 0.0, "max_reading": 4095.0,
                "start_sigma": {"rotation": 0.03, "translation": 0.003}}

    def stream_columns(self, params: dict):
        names = ir_layout_from_data(_description(params)).names
        return {"commands": ("v", "omega", "right", "left"), "ir": tuple(names)}

    def robots(self, params: dict) -> dict[str, dict]:
        puck = {**_description(params), "name": ROBOT}
        if params["gain_error"] > 0 or params["offset_error"] > 0:
            n = len(ir_layout_from_data(puck).names)
            puck.setdefault("parameters", {})
            puck["parameters"]["ir_gain"] = {"type": "scalar", "values": [1.0] * n,
                                             "sigma": max(params["gain_error"], 1e-3)}
            puck["parameters"]["ir_offset"] = {"type": "scalar", "values": [0.0] * n,
                                               "sigma": max(params["offset_error"], 1.0), "unit": "counts"}
        return {ARENA: {**_arena(params), "name": ARENA}, ROBOT: puck}

    def config(self, params: dict) -> dict:
        start, sigma = self._start(params), params["start_sigma"]
        ir = {"type": "epuck.ir", "robot": ROBOT, "map": ARENA, "stream": "ir",
              "robust": {"kernel": "cauchy", "k": 5.0}}  # a ray grazing a wall's end: see docs/models/epuck.md
        if params["gain_error"] > 0 or params["offset_error"] > 0:
            ir.update(gain="ir_gain", offset="ir_offset")
        return {"robots": {ARENA: {"description": f"robots/{ARENA}.yaml"},
                           ROBOT: {"description": f"robots/{ROBOT}.yaml", "states": {"stream": "ir", "type": "pose2"}}},
                "factors": [{"type": "pose.origin", "robot": ROBOT, "pose": [round(float(x), 6) for x in start],
                             "sigma": {k: max(v, 1e-6) for k, v in sigma.items()}},
                            {"type": "epuck.velocity_motion", "robot": ROBOT, "stream": "commands"}, ir],
                "initializers": [{"type": "epuck.dead_reckoning", "robot": ROBOT, "stream": "commands", "ir": "ir",
                                  "map": ARENA}],
                "solver": {"type": "batch", "method": "lm"}}

    def _start(self, params: dict) -> np.ndarray:
        path = loop_path(walls_from_data(_arena(params)), params["clearance"], params["corner_radius"])
        heading = np.arctan2(*(path[1] - path[0])[::-1])
        return np.array([path[0, 0], path[0, 1], heading])

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        desc, walls = _description(params), walls_from_data(_arena(params))
        layout = ir_layout_from_data(desc)
        path = loop_path(walls, params["clearance"], params["corner_radius"])
        dt = 1.0 / params["rate"]
        t = np.arange(int(round(params["duration"] * params["rate"])) + 1) * dt
        alpha = alphas(desc) * params["motion_noise_scale"]
        start = self._start(params)
        sig = params["start_sigma"]
        pose = start + rng.normal(0.0, [sig["translation"], sig["translation"], sig["rotation"]])
        poses, cmd, hint = np.zeros((len(t), 3)), np.zeros((len(t), 2)), 0
        for k in range(len(t)):
            poses[k] = pose
            v, omega, hint = pure_pursuit(pose, path, hint, params["speed"])
            cmd[k] = v, omega
            pose = sample_motion(pose, v, omega, dt, alpha, rng)
        d = sensor_distances(walls, poses, layout.mounts, layout.angles)
        ev = layout.bank.evaluate(d)
        n = layout.bank.size
        gain, offset = 1.0 + rng.normal(0.0, params["gain_error"], n), rng.normal(0.0, params["offset_error"], n)
        z = gain * ev.mean + offset + np.sqrt(ev.var) * params["ir_sigma_scale"] * rng.standard_normal(d.shape)
        z = np.clip(z, 0.0, params["max_reading"])
        r, axle = float(desc["wheel_radius"]), float(desc["axle_length"])
        wheels = np.column_stack([cmd[:, 0] + 0.5 * axle * cmd[:, 1], cmd[:, 0] - 0.5 * axle * cmd[:, 1]]) / r
        streams = {"commands": Stream("commands", t, ("v", "omega", "right", "left"), np.column_stack([cmd, wheels]),
                                      "simulated:commands"),
                   "ir": Stream("ir", t, tuple(layout.names), z, "simulated:ir")}
        quat = np.column_stack([np.zeros((len(t), 2)), np.sin(poses[:, 2] / 2), np.cos(poses[:, 2] / 2)])
        truth = {ROBOT: pose_stream(ROBOT, t, np.column_stack([poses[:, :2], np.zeros(len(t)), quat]),
                                    "simulated:truth")}
        calibration = {}
        if params["gain_error"] > 0 or params["offset_error"] > 0:
            calibration[ROBOT] = {"ir_gain": {"type": "scalar", "values": gain.tolist()},
                                  "ir_offset": {"type": "scalar", "values": offset.tolist()}}
        return SourceOutput(streams, truth, calibration)


def _description(params: dict) -> dict:
    return robot_description_data(params["description"], "epuck", "epuck.sim")


def _arena(params: dict) -> dict:
    return robot_description_data(params["arena"], "wall_map", "epuck.sim")


SIMULATORS = [EpuckSimulator]
