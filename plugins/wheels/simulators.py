"""`wheels.sim`: a differential drive with a passive wheel and a low-cost gyro driving over a floor with the
fault classes of passive-wheel odometry (docs/models/wheels.md#simulator).

The motors follow a commanded forward speed and turn rate (one `path` shape, held over each sample
interval); the robot's true motion is the command except while it is stuck (it stands still) and in
fast turns with `slide` (it turns by (1 - slip) of the command). Encoder readings are the travel of each
wheel's rim: the driven wheels turn as commanded whatever the robot does, the passive wheel turns with
the floor; a wheel crossing an obstacle of height h turns 2 r (beta - sin beta) further than it advances
(beta = acos(1 - h/r): rolling up over the edge and down again); every wheel has random travel noise.
Fault classes (`faults`, all off by default):

- roughness: wires of height h across the floor every `spacing` m (lines x = const), for all wheels;
- bumps: `count` obstacles of height up to `height` (at most 0.9 r of the wheel), each under one wheel
  (left, right or passive, at random), climbed and left `length` m later;
- stuck: `count` episodes of `duration` s: the robot stands, the driven wheels spin, the passive wheel
  and the gyro see no motion;
- slide: while the commanded turn rate exceeds `turn_rate` (rad/s) the robot under-rotates by `slip`.

The gyro reads (true rate - bias) / scale + noise, its bias drifting as a random walk. A camera stream
gives the true pose with the noise of an overhead camera (2.8 mm). Optionally one wheel's radius drifts
linearly during the run (`drift`). Streams: `wheels` (t, left, right[, passive][, gyro]: cumulative
ticks or rad as the description says; gyro row i = mean rate over the interval ending at t_i),
`camera` (poses), `radius_truth` (t, left, right: the true radii, m) with a drift; truth: the path and
the intrinsics (time-varying ones at the first sample). The true intrinsics (nominal plus `errors`) are drawn
from the run's seed, or from `robot_seed` when given: the same robot in several runs (a calibration run and
a mission).
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import (NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS, POSE_NOISE_SCHEMA, POSITIVE_SCHEMA as POSITIVE,
                           Simulator, SourceOutput, Stream, arc_path, pose_stream, robot_description_data, sample_times)

from .model import AXLE, GYRO_BIAS, GYRO_SCALE, PASSIVE_OFFSET, PASSIVE_RADIUS, RADIUS, RADIUS_LEFT, RADIUS_RIGHT

COUNT = {"type": "integer", "minimum": 0}
SHAPES = ("loop", "figure_eight", "square", "slalom", "random")
LOOP_RADIUS = 0.5     # m: loop and figure-eight radius
SIDE = 0.75           # m: square side
CORNER_RATE = 1.5     # rad/s: turning on the spot at a square's corners
START = 0.5           # s at rest before moving (the gyro's bias shows)
OVER_READ = 3.0       # sigmas: encoder readings over-running the motion by more are down-weighted (config)


def _obj(properties: dict) -> dict:
    return {"type": "object", "properties": properties, "additionalProperties": False}


class WheelsSimulator(Simulator):
    name = "wheels.sim"
    summary = ("differential drive with a passive wheel and a low-cost gyro: roughness, bumps, stuck wheels, "
               "sliding in fast turns, camera ground truth, drifting radius (paths: loop, figure_eight, square, "
               "slalom, random)")
    schema = _obj({"description": {"type": "string"}, "path": {"enum": list(SHAPES)},
                   "duration": POSITIVE, "rate": POSITIVE, "speed": POSITIVE,
                   "errors": _obj({"radius": NONNEG, "axle": NONNEG}),
                   "wheel_noise": NONNEG,
                   "faults": _obj({"roughness": _obj({"height": NONNEG, "spacing": POSITIVE}),
                                   "bumps": _obj({"count": COUNT, "height": NONNEG, "length": POSITIVE}),
                                   "stuck": _obj({"count": COUNT, "duration": POSITIVE}),
                                   "slide": _obj({"turn_rate": POSITIVE,
                                                  "slip": {"type": "number", "minimum": 0, "maximum": 1}})}),
                   "gyro": _obj({"scale": POSITIVE, "bias": {"type": "number"}, "noise": NONNEG,
                                 "bias_drift": NONNEG}),
                   "camera": _obj({"rate": POSITIVE, "sigma": POSE_NOISE_SCHEMA}),
                   "drift": _obj({"wheel": {"enum": ["left", "right"]}, "change": {"type": "number"}}),
                   "robot_seed": {"type": ["integer", "null"], "minimum": 0}})
    defaults = {"description": "passive_wheel_robot", "path": "figure_eight", "duration": 60.0, "rate": 20.0,
                "speed": 0.15, "errors": {"radius": 0.0003, "axle": 0.002}, "wheel_noise": 2e-4,
                "faults": {"roughness": {"height": 0.0, "spacing": 0.1},
                           "bumps": {"count": 0, "height": 0.03, "length": 0.05},
                           "stuck": {"count": 0, "duration": 1.5},
                           "slide": {"turn_rate": 1.0, "slip": 0.0}},
                "gyro": {"scale": 1.25, "bias": 0.03, "noise": 0.002, "bias_drift": 0.0},
                "camera": {"rate": 10.0, "sigma": {"rotation": 0.02, "translation": 0.0028}},
                "drift": {"wheel": "left", "change": 0.0}, "robot_seed": None}

    def stream_columns(self, params: dict):
        data = _shipped(params)
        columns = ("left", "right") + ("passive",) * (PASSIVE_RADIUS in data["parameters"]) + \
            ("gyro",) * (GYRO_BIAS in data["parameters"])
        out = {"wheels": columns, "camera": POSE_COLUMNS}
        if params["drift"]["change"]:
            out["radius_truth"] = ("left", "right")
        return out

    def robots(self, params: dict) -> dict[str, dict]:
        """The description; the drifting wheel's radius and a drifting gyro bias become time-varying."""
        data = _shipped(params)
        pars = data["parameters"]
        if params["drift"]["change"]:
            pars[RADIUS[params["drift"]["wheel"]]]["time_varying"] = True
        if GYRO_BIAS in pars and params["gyro"]["bias_drift"] > 0:
            pars[GYRO_BIAS]["time_varying"] = True
        return {"robot": data}

    def config(self, params: dict) -> dict:
        """Encoders (sigma from the wheel noise and the tick quantization; readings that over-run the
        motion down-weighted), the passive wheel, the gyro, no sideways motion, dead reckoning to start;
        with a radius drift also the camera (the radius is observable only against a reference)."""
        data = self.robots(params)["robot"]
        pars = data["parameters"]
        dt = 1.0 / params["rate"]
        factors = [{"type": "pose.origin", "robot": "robot", "sigma": {"rotation": 1e-4, "translation": 1e-4}}]
        for wheels, ticks in ((["left", "right"], data.get("ticks_per_revolution")),
                              (["passive"], data.get("passive_ticks_per_revolution"))):
            if wheels == ["passive"] and PASSIVE_RADIUS not in pars:
                continue
            radius = pars[RADIUS[wheels[0]]]["value"]
            tick = 0.0 if ticks is None else 2 * np.pi / ticks  # rad per tick; quantization: tick^2/6 per step
            sigma = float(np.sqrt((params["wheel_noise"] / radius) ** 2 + tick ** 2 / (6 * dt)))
            factors.append({"type": "wheels.encoder", "robot": "robot", "stream": "wheels", "wheels": wheels,
                            "sigma": round(max(sigma, 1e-4), 5), "over_read": OVER_READ})
        if GYRO_BIAS in pars:
            gyro = params["gyro"]
            factors.append({"type": "wheels.gyro", "robot": "robot", "stream": "wheels",
                            "sigma": max(gyro["noise"], 1e-4)})
            if pars[GYRO_BIAS].get("time_varying"):
                factors.append({"type": "parameter.random_walk", "robot": "robot", "parameter": GYRO_BIAS,
                                "sigma": max(gyro["bias_drift"], 1e-5)})
        factors.append({"type": "wheels.nonholonomic", "robot": "robot", "sigma": 1e-3})
        if params["drift"]["change"]:
            name = RADIUS[params["drift"]["wheel"]]
            span = max(params["duration"], 1.0)
            factors += [{"type": "parameter.random_walk", "robot": "robot", "parameter": name,
                         "sigma": float(abs(params["drift"]["change"]) / np.sqrt(span))},
                        {"type": "pose.absolute", "robot": "robot", "stream": "camera", "sigma": params["camera"]["sigma"]}]
        return {"robots": {"robot": {"description": "robots/robot.yaml",
                                     "states": {"stream": "wheels", "type": "pose2"}}},
                "factors": factors,
                "initializers": [{"type": "wheels.dead_reckoning", "robot": "robot", "stream": "wheels",
                                  "forward": "passive" if PASSIVE_RADIUS in pars else "driven"}],
                "solver": {"type": "batch", "method": "lm"}}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        data = self.robots(params)["robot"]
        pars = data["parameters"]
        t = sample_times(params["duration"], params["rate"])
        dt = np.diff(t)
        robot_rng = rng if params["robot_seed"] is None else np.random.default_rng(params["robot_seed"])
        true = _true_intrinsics(pars, params["errors"], robot_rng)
        v_cmd, w_cmd = command(params, t[:-1], rng)
        stuck = _episodes(params["faults"]["stuck"], t[:-1], rng)
        slide = params["faults"]["slide"]
        w_true = np.where(np.abs(w_cmd) > slide["turn_rate"], (1 - slide["slip"]) * w_cmd, w_cmd)
        v_true, w_true = np.where(stuck, 0.0, v_cmd), np.where(stuck, 0.0, w_true)
        poses = arc_path(v_true, w_true, dt)
        radii = {w: np.full(len(t), true[RADIUS[w]]) for w in ("left", "right")}
        change = params["drift"]["change"]
        if change:
            radii[params["drift"]["wheel"]] += change * (t - t[0]) / (t[-1] - t[0])
        wheels = ["left", "right"] + ["passive"] * (PASSIVE_RADIUS in pars)
        lateral = {"left": 0.5 * true[AXLE], "right": -0.5 * true[AXLE], "passive": true.get(PASSIVE_OFFSET, 0.0)}
        columns, faults = {}, params["faults"]
        bumps, length = _bumps(faults["bumps"], wheels, v_true, rng), faults["bumps"]["length"]
        for w in wheels:
            driven = w != "passive"
            rim = ((v_cmd if driven else v_true) - (w_cmd if driven else w_true) * lateral[w]) * dt
            contact = _contact_points(poses, lateral[w])
            radius = radii[w][1:] if driven else true[PASSIVE_RADIUS]
            rim = rim + np.sign(rim) * (_roughness(faults["roughness"], contact, radius) +
                                        _bump_travel(bumps.get(w, []), length, contact, radius))
            rim = rim + rng.normal(0.0, params["wheel_noise"], len(dt)) * np.sqrt(dt)
            angle = np.concatenate([[0.0], np.cumsum(rim / radius)])
            ticks = data.get("ticks_per_revolution" if driven else "passive_ticks_per_revolution")
            columns[w] = angle if ticks is None else np.round(angle * ticks / (2 * np.pi))
        if GYRO_BIAS in pars:
            columns["gyro"] = _gyro(params["gyro"], np.concatenate([[0.0], w_true]), t, rng)
        streams = {"wheels": Stream("wheels", t, tuple(columns), np.column_stack(list(columns.values())),
                                    "simulated:wheels")}
        streams["camera"] = _camera(params["camera"], t, poses, rng)
        if change:
            streams["radius_truth"] = Stream("radius_truth", t, ("left", "right"),
                                             np.column_stack([radii["left"], radii["right"]]), "simulated:radii")
        if GYRO_BIAS in pars:
            true.update({GYRO_SCALE: params["gyro"]["scale"], GYRO_BIAS: params["gyro"]["bias"]})
        calibration = {name: {"type": "scalar", "value": float(v)} for name, v in true.items()}
        return SourceOutput(streams, {"robot": pose_stream("robot", t, _lifted(poses), "simulated:truth")},
                            {"robot": calibration})


def command(params: dict, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Commanded forward speed (m/s) and turn rate (rad/s) held over the intervals starting at t: at rest
    for START s, then ramping up over 1 s into the path shape."""
    v0 = params["speed"]
    shape = params["path"]
    ramp = np.clip(t - START, 0.0, 1.0)
    ramp = ramp * ramp * (3 - 2 * ramp)
    s = t - START
    if shape == "loop":
        v, w = np.full(len(t), v0), np.full(len(t), v0 / LOOP_RADIUS)
    elif shape == "figure_eight":  # alternate left and right circles, switching smoothly
        lap = 2 * np.pi * LOOP_RADIUS / v0
        v, w = np.full(len(t), v0), v0 / LOOP_RADIUS * np.tanh(4 * np.sin(np.pi * s / lap))
    elif shape == "square":  # UMBmark-like: a side, then a 90 degree turn on the spot, counter-clockwise
        leg, corner = SIDE / v0, (np.pi / 2) / CORNER_RATE
        phase = np.mod(np.maximum(s, 0.0), leg + corner)
        on_leg = phase < leg
        v, w = np.where(on_leg, v0, 0.0), np.where(on_leg, 0.0, CORNER_RATE)
        return v * (s >= 0), w * (s >= 0)
    elif shape == "slalom":
        v, w = np.full(len(t), v0), 0.8 * np.sin(2 * np.pi * s / 6.0)
    else:  # random: three sinusoids of random frequency and phase in the turn rate, a slower one in the speed
        f, phase = rng.uniform(0.02, 0.2, 3), rng.uniform(0, 2 * np.pi, 4)
        w = sum(0.4 * np.sin(2 * np.pi * fi * s + p) for fi, p in zip(f, phase))
        v = v0 * (1 + 0.3 * np.sin(2 * np.pi * 0.05 * s + phase[3]))
    return v * ramp, w * ramp


def _true_intrinsics(pars: dict, errors: dict, rng: np.random.Generator) -> dict[str, float]:
    """The description's nominal wheel intrinsics plus Gaussian errors (radii, axle; none on a fixed one)."""
    out = {}
    for name in (RADIUS_LEFT, RADIUS_RIGHT, AXLE, PASSIVE_RADIUS, PASSIVE_OFFSET):
        if name in pars:
            value = float(pars[name]["value"])
            sigma = 0.0 if pars[name].get("fixed") else errors["axle" if name == AXLE else "radius"]
            out[name] = value + (rng.normal(0.0, sigma) if name != PASSIVE_OFFSET else 0.0)
    return out


def _episodes(stuck: dict, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Mask of the intervals in which the robot is stuck: `count` episodes of `duration` s, not overlapping,
    after the start and before the last 2 s."""
    mask = np.zeros(len(t), dtype=bool)
    lo, hi = START + 2.0, t[-1] - 2.0 - stuck["duration"]
    if stuck["count"] == 0 or hi <= lo:
        return mask
    slots = np.arange(lo, hi, stuck["duration"] + 1.0)
    for start in rng.choice(slots, size=min(stuck["count"], len(slots)), replace=False):
        mask |= (t >= start) & (t < start + stuck["duration"])
    return mask


def _contact_points(poses: np.ndarray, lateral: float) -> np.ndarray:
    """(N, 2) world positions of the axle point at lateral offset `lateral` (m)."""
    return poses[:, :2] + lateral * np.column_stack([-np.sin(poses[:, 2]), np.cos(poses[:, 2])])


def _over_edge(height: float, radius: float) -> float:
    """Extra rim travel (m) of a wheel rolling up over an edge of `height` (at most 0.9 radius): it pivots
    on the edge by beta = acos(1 - h/r), turning r beta while advancing r sin beta."""
    beta = np.arccos(1.0 - min(height, 0.9 * radius) / radius)
    return radius * (beta - np.sin(beta))


def _roughness(rough: dict, contact: np.ndarray, radius) -> np.ndarray:
    """Extra rim travel per interval from wires of height h across the floor every `spacing` m (lines
    x = const): up and over each one crossed."""
    if rough["height"] <= 0:
        return np.zeros(len(contact) - 1)
    crossed = np.abs(np.diff(np.floor(contact[:, 0] / rough["spacing"])))
    r = np.mean(radius)
    return crossed * 2 * _over_edge(rough["height"], r)


def _bumps(bumps: dict, wheels: list[str], v: np.ndarray, rng: np.random.Generator) -> dict[str, list]:
    """{wheel: [(interval at which it meets the obstacle, height)]}: `count` obstacles while moving."""
    moving = np.flatnonzero(np.abs(v) > 0.5 * np.max(np.abs(v), initial=0.0))
    out: dict[str, list] = {}
    if bumps["count"] == 0 or len(moving) == 0:
        return out
    for k in np.sort(rng.choice(moving[: max(1, int(0.9 * len(moving)))], size=bumps["count"], replace=False)):
        out.setdefault(str(rng.choice(wheels)), []).append((int(k), rng.uniform(0.5, 1.0) * bumps["height"]))
    return out


def _bump_travel(bumps: list, length: float, contact: np.ndarray, radius) -> np.ndarray:
    """Extra rim travel per interval of a wheel meeting obstacles: up over the front edge while advancing
    r sin(beta), and down over the back edge `length` m later, the extra spread along the wheel's path."""
    n = len(contact) - 1
    out = np.zeros(n)
    if not bumps:
        return out
    r = float(np.mean(radius))
    path = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(contact, axis=0), axis=1))])
    for k, height in bumps:
        extra = _over_edge(height, r)
        width = r * np.sin(np.arccos(1.0 - min(height, 0.9 * r) / r))
        start = path[k]
        cumulative = extra * (np.clip((path - start) / width, 0, 1) + np.clip((path - start - length) / width, 0, 1))
        out += np.diff(cumulative)
    return out


def _gyro(gyro: dict, rate: np.ndarray, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Readings (true rate - bias) / scale + white noise (`noise` rad/sqrt(s)); the bias drifts as a random
    walk of `bias_drift` rad/s/sqrt(s) from `bias`."""
    dt = np.diff(t)
    bias = gyro["bias"] + np.concatenate([[0.0], np.cumsum(rng.normal(0.0, gyro["bias_drift"], len(dt)) * np.sqrt(dt))])
    return (rate - bias) / gyro["scale"] + rng.normal(0.0, gyro["noise"], len(t)) / np.sqrt(np.r_[dt[0], dt])


def _lifted(poses: np.ndarray) -> np.ndarray:
    """(N, 7) x y z qx qy qz qw of planar poses (x, y, theta) on the plane z = 0."""
    half = 0.5 * poses[:, 2]
    n = len(poses)
    return np.column_stack([poses[:, :2], np.zeros((n, 3)), np.sin(half), np.cos(half)])


def _camera(camera: dict, t: np.ndarray, poses: np.ndarray, rng: np.random.Generator) -> Stream:
    """Overhead-camera poses at `rate` Hz: the true pose with Gaussian position and heading noise."""
    every = max(1, int(round((1.0 / camera["rate"]) / (t[1] - t[0]))))
    rows = np.arange(0, len(t), every)
    sigma = camera["sigma"]
    noisy = poses[rows] + rng.normal(size=(len(rows), 3)) * [sigma["translation"], sigma["translation"], sigma["rotation"]]
    return pose_stream("camera", t[rows], _lifted(noisy), "simulated:camera")


def _shipped(params: dict) -> dict:
    """The registered diff_drive description `params` names (a fresh dict); ConfigError otherwise."""
    return robot_description_data(params["description"], "diff_drive", "wheels.sim")


SIMULATORS = [WheelsSimulator]
