"""`cable.sag_static`: static poses of a suspended 4-cable robot with heavy sagging cables, as the
calibration of docs/models/cable_sag.md needs them (the setting of thesis Table 5.2).

The robot is a shipped description (`cdpr_large` or `cdpr_small`). Its TRUE pulleys are the
description's perturbed uniformly by +-initial_error/sqrt(3) per axis, and its true encoder
offsets are drawn the same way around the description's 0: the description is then the rough
guess the source starts from ("up to 10 m" for the large robot, 1 m for the small one). Each
static pose: a position drawn uniformly in `workspace` and a yaw ~ N(0, yaw_sigma); the static
simulator (static_solver.inverse_pose) settles roll and pitch and gives every cable's forces and
arc length; positions where a cable would go slack are redrawn.

Parameters left null take the robot's values in PER_ROBOT. Streams (one sample per pose, 1 s
apart): `poses` (the vision system: true pose times Exp(xi), xi ~ N(0, pose_sigma), by default 1 cm / 5 mrad on either robot), `lengths` (l0..l3 = arc length + offset + N(0, length_sigma)), `force`
(f: tension of the reference cable 0 at the end-effector + N(0, force_sigma)). Truth: the
equilibrium poses, pulleys and offsets.

`swing: {dwell: s, rate: Hz, amplitude: m, period: s, decay: s}`: the robot is held at each pose for
`dwell` s (the poses `dwell` + 1 s apart) and every stream is sampled at `rate` during the dwell, the
lengths and force constant (up to their noise) while the end-effector swings horizontally about its
equilibrium, amplitude * exp(-tau / decay) * sin(2 pi tau / period), in a random direction: the
recording a static model meets on a real robot. The truth is then one pose per sample (swing
included); the static poses are what `static_segments` recovers.

`path: {duration: s, rate: Hz, lag: s}`: instead of static poses, the robot moves slowly (quasi-statically: in
equilibrium at every instant) along a smooth path through the workspace (a Lissajous curve over 80 % of each
axis, the yaw a slow sinusoid of amplitude yaw_sigma), sampled at `rate`; the encoders' clock is `lag` s early:
the lengths stamped t are those at t + lag (a time offset to estimate). Truth: the path's poses.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from fusionkit.api import (ConfigError, NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS, POSE_NOISE_SCHEMA as SIGMA,
                           POSITIVE_SCHEMA as POSITIVE, Simulator, SourceOutput, Stream, noisy, pose_stream,
                           poses_from_array, robot_description_data)

from .model import ROBOT_NAME, shipped_robot
from .static_solver import StaticsError, inverse_pose

BOX = {"type": "object", "properties": {"min": {"type": "array", "items": {"type": "number"}, "minItems": 3,
                                                "maxItems": 3},
                                        "max": {"type": "array", "items": {"type": "number"}, "minItems": 3,
                                                "maxItems": 3}},
       "required": ["min", "max"], "additionalProperties": False}
# the vision system's pose noise, the same for both robots: the thesis states only "centimetre-level
# translation, small rotation" (the source's public simulation code uses 0.19 mm / 0.019 deg per
# axis: research/cable_sag_experiments.py SOURCE_CODE_POSE_SIGMA, set it with pose_sigma)
POSE_SIGMA = {"rotation": 0.005, "translation": 0.01}
# per robot: where the end-effector goes (the external finite-element poses span about this), the
# initial error of the source's protocol, the force sensor's noise (about 1 % of the tension)
PER_ROBOT = {
    "cdpr_large": {"workspace": {"min": [-28.0, -28.0, -4.0], "max": [28.0, 28.0, 28.0]},
                   "initial_error": 10.0, "force_sigma": 5.0},
    "cdpr_small": {"workspace": {"min": [-1.0, -4.0, -16.5], "max": [1.5, 0.5, -0.8]},
                   "initial_error": 1.0, "force_sigma": 0.2},
}
MAX_DRAWS = 100  # redraws per pose before giving up on a workspace
# the attachment-height equation (5.13) is the model itself. Solved in two stages (solver.refine):
# 1 cm of model tolerance lets the first solve travel from pulleys metres off (0.1 mm from there
# stalls it); the second, from that estimate, holds the equation to 0.1 mm, as exact as this
# simulator's data. It helps only where the data match the model exactly: on the finite-element
# poses, which the catenary matches to about 1 cm, it makes the small robot worse and the large one
# barely better (benchmarks/bench_cable_sag.py measures both)
HEIGHT_SIGMA = 0.01
REFINED_HEIGHT_SIGMA = 1e-4




def _dwell_and_swing(swing: dict, poses: np.ndarray, lengths: np.ndarray, force: np.ndarray,
                     rng: np.random.Generator):
    """Each static pose held `dwell` s, sampled at `rate`: (t, true poses with the swing, lengths, force)."""
    tau = np.arange(0.0, swing["dwell"], 1.0 / swing["rate"])
    out_t, out_poses, out_lengths, out_force = [], [], [], []
    for k, (pose, length, f) in enumerate(zip(poses, lengths, force)):
        heading = rng.uniform(0.0, 2 * np.pi)
        phase = swing["amplitude"] * np.exp(-tau / swing["decay"]) * np.sin(2 * np.pi * tau / swing["period"])
        moved = np.tile(pose, (len(tau), 1))
        moved[:, 0] += phase * np.cos(heading)
        moved[:, 1] += phase * np.sin(heading)
        out_t.append(k * (swing["dwell"] + 1.0) + tau)
        out_poses.append(moved)
        out_lengths.append(np.tile(length, (len(tau), 1)))
        out_force.append(np.full(len(tau), f))
    return np.concatenate(out_t), np.vstack(out_poses), np.vstack(out_lengths), np.concatenate(out_force)


class SagStaticSimulator(Simulator):
    name = "cable.sag_static"
    summary = ("static poses of a suspended 4-cable robot with heavy sagging cables (catenary statics): "
               "vision poses, cable lengths, reference-cable force, truth")
    schema = {"type": "object",
              "properties": {"robot": {"enum": sorted(PER_ROBOT)}, "poses": {"type": "integer", "minimum": 4},
                             "workspace": {"anyOf": [BOX, {"type": "null"}]},
                             "initial_error": {"anyOf": [NONNEG, {"type": "null"}]},
                             "force_sigma": {"anyOf": [NONNEG, {"type": "null"}]},
                             "yaw_sigma_deg": NONNEG, "length_sigma": NONNEG,
                             "pose_sigma": SIGMA, "com_error": NONNEG,
                             "path": {"anyOf": [{"type": "null"}, {
                                 "type": "object",
                                 "properties": {"duration": POSITIVE, "rate": POSITIVE, "lag": {"type": "number"}},
                                 "required": ["duration", "rate"], "additionalProperties": False}]},
                             "swing": {"anyOf": [{"type": "null"}, {
                                 "type": "object",
                                 "properties": {"dwell": POSITIVE, "rate": POSITIVE, "amplitude": NONNEG,
                                                "period": POSITIVE, "decay": POSITIVE},
                                 "required": ["dwell", "rate", "amplitude", "period", "decay"],
                                 "additionalProperties": False}]}},
              "additionalProperties": False}
    defaults = {"robot": "cdpr_large", "poses": 35, "workspace": None, "initial_error": None,
                "force_sigma": None, "yaw_sigma_deg": 1.0, "length_sigma": 0.001, "pose_sigma": POSE_SIGMA,
                "com_error": 0.0, "swing": None, "path": None}

    def _params(self, params: dict) -> dict:
        p = {**self.defaults, **params}
        for key, value in PER_ROBOT[p["robot"]].items():
            if p[key] is None:
                p[key] = value
        return p

    def stream_columns(self, params: dict):
        return {"poses": POSE_COLUMNS, "lengths": tuple(f"l{i}" for i in range(4)), "force": ("f",)}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        from scipy.spatial.transform import Rotation
        p = self._params(params)
        robot, nominal = shipped_robot(p["robot"])
        if p["com_error"] > 0:  # the true centre of mass is not the description's: statics tilt the robot otherwise
            robot = replace(robot, com=robot.com + rng.normal(0.0, p["com_error"], 3))
        half = p["initial_error"] / np.sqrt(3.0)
        pulleys = nominal + rng.uniform(-half, half, nominal.shape)
        offsets = rng.uniform(-half, half, robot.n)
        lo, hi = np.asarray(p["workspace"]["min"], float), np.asarray(p["workspace"]["max"], float)
        if np.any(lo >= hi):
            raise ConfigError(f"<simulate {self.name}>: workspace min must be below max on every axis")
        if p["path"]:
            t = np.arange(int(round(p["path"]["duration"] * p["path"]["rate"]))) / p["path"]["rate"]
            states = self._path(t, p["path"]["duration"], lo, hi, pulleys, robot, np.radians(p["yaw_sigma_deg"]))
            lag = p["path"].get("lag", 0.0)
            lagged = self._path(t + lag, p["path"]["duration"], lo, hi, pulleys, robot,
                                np.radians(p["yaw_sigma_deg"])) if lag else states  # equilibria solved once
        else:
            states = [self._static_pose(rng, lo, hi, pulleys, robot, np.radians(p["yaw_sigma_deg"]))
                      for _ in range(p["poses"])]
            lagged = states
            t = np.arange(p["poses"], dtype=float)
        truth = np.array([np.concatenate([s.t, Rotation.from_matrix(s.R).as_quat()]) for s in states])
        lengths = np.array([s.state.length for s in lagged]) + offsets
        force = np.array([s.forces[robot.reference] for s in lagged])
        if p["swing"]:
            t, truth, lengths, force = _dwell_and_swing(p["swing"], truth, lengths, force, rng)
        lengths = lengths + rng.normal(0.0, p["length_sigma"], lengths.shape)
        force = force + rng.normal(0.0, p["force_sigma"], len(t))
        seen = noisy(poses_from_array(truth), p["pose_sigma"], rng)
        streams = {"poses": pose_stream("poses", t, seen, "simulated:poses"),
                   "lengths": Stream("lengths", t, tuple(f"l{i}" for i in range(robot.n)), lengths,
                                     "simulated:lengths"),
                   "force": Stream("force", t, ("f",), force[:, None], "simulated:force")}
        calibration = {ROBOT_NAME: {"pulley": {"type": "point3", "values": pulleys.tolist()},
                                    "offset": {"type": "scalar", "values": offsets.tolist()}}}
        return SourceOutput(streams, {ROBOT_NAME: pose_stream(ROBOT_NAME, t, truth, "simulated:truth")},
                            calibration)

    @staticmethod
    def _path(t: np.ndarray, duration: float, lo, hi, pulleys, robot, yaw_sigma: float) -> list:
        """The robot in equilibrium at each time t on a smooth path through the box lo..hi."""
        phase = 2 * np.pi * t / duration
        centre, half = 0.5 * (lo + hi), 0.4 * (hi - lo)
        positions = centre + half * np.column_stack([np.sin(phase), np.sin(2 * phase + 0.7), np.sin(3 * phase + 1.3)])
        out = []
        for tk, position, yaw in zip(t, positions, yaw_sigma * np.sin(4 * phase)):
            try:
                out.append(inverse_pose(position, pulleys, robot, yaw=float(yaw)))
            except StaticsError:
                raise ConfigError(f"<simulate cable.sag_static>: at t = {tk:g} s the path leaves the statics' "
                                  "workspace (a cable would go slack); shrink `workspace`") from None
        return out

    @staticmethod
    def _static_pose(rng, lo, hi, pulleys, robot, yaw_sigma):
        for _ in range(MAX_DRAWS):
            try:
                return inverse_pose(rng.uniform(lo, hi), pulleys, robot, yaw=rng.normal(0.0, yaw_sigma))
            except StaticsError:
                continue  # a slack cable or no equilibrium there: draw again
        raise ConfigError(f"<simulate cable.sag_static>: no static equilibrium in {MAX_DRAWS} draws from the "
                          f"workspace {lo.tolist()} .. {hi.tolist()}; shrink it towards the pulleys' centre")

    def robots(self, params: dict) -> dict[str, dict]:
        """The shipped description, without priors on pulleys and offsets: its values are only the
        starting guess (off by up to initial_error)."""
        desc = robot_description_data(self._params(params)["robot"])
        for name in ("pulley", "offset"):
            desc["parameters"][name].pop("sigma", None)
        return {ROBOT_NAME: desc}

    def config(self, params: dict) -> dict:
        """Vision poses, sagging cables, the reference force; poses from the vision system, forces
        and orientations in equilibrium with the guessed pulleys. Batch Dogleg with QR: the graph is
        too ill-conditioned for Cholesky (fusionkit/solve/factorization.py), and from pulleys metres
        off Levenberg-Marquardt crawls along the curved valley the statics make (50-90 iterations
        measured) where Dogleg's trust region crosses it in 10-26."""
        p = self._params(params)
        return {
            "robots": {ROBOT_NAME: {"description": f"robots/{ROBOT_NAME}.yaml", "states": {"stream": "poses"}}},
            "factors": [
                {"type": "pose.absolute", "robot": ROBOT_NAME, "stream": "poses",
                 "sigma": {k: max(v, 1e-4) for k, v in p["pose_sigma"].items()}},
                {"type": "cable.sag", "label": "sag", "robot": ROBOT_NAME, "stream": "lengths",
                 "sigma": max(p["length_sigma"], 1e-4), "height_sigma": HEIGHT_SIGMA},
                {"type": "cable.reference_force", "robot": ROBOT_NAME, "stream": "force",
                 "sigma": max(p["force_sigma"], 1e-3)}],
            "initializers": [{"type": "pose.interpolate", "robot": ROBOT_NAME, "stream": "poses"},
                             {"type": "cable.sag_forces", "robot": ROBOT_NAME}],
            "solver": {"type": "batch", "method": "dogleg", "factorization": "qr",
                       "refine": {"sag": {"height_sigma": REFINED_HEIGHT_SIGMA}}}}


SIMULATORS = [SagStaticSimulator]
