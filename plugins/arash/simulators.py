"""`arash.sim`: two ARASH:ASiST arms on one eye, the follower following the leader's tool tip.

Geometry (thesis convention, SI): the leader is the shipped `arash_asist` arm with its kinematic
parameters off by `leader_error`; the eye centre E is its tip at mid-range joints. The follower
is the same design, off by `follower_error`, mounted opposite: its base is the leader's turned half
a turn about the vertical through E, then by the rotation vector `base_tilt` about E, so its RCM
sits on the far side of the eye. For each of `configurations` static configurations (one per
second) the leader's tip goes to a point drawn uniformly within `workspace_radius` of E; the
follower, commanded through its nominal parameters, follows it and misses by the parameter errors.

Streams: `leader_joints`, `follower_joints` (t, phi, psi, d: encoder readings, noise
`encoder_sigma`), `leader_tip` (t, x, y, z: the tracker, in the leader's base frame, per-axis noise
`tracker_sigma`), `tip_offset` (t, dx, dy, dz: the follower's tip minus the leader's, in the leader's
base frame, `offset_sigma`) and, with `base_survey`, `follower_base` (the follower's base frame
in the leader's, one pose, noise `survey_sigma`; the other streams are the same with or without
it). Truth: both arms' parameters, the base-to-base transform `follower/base_in_leader` and the
true joints (state family `joints`).

Every parameter is in SI units (m, rad); with `convention: authors_code` the data, truth, robot
descriptions and config are written in that convention (mm, its axes), through the frame change
of kinematics.py.
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import (ConfigError, NON_NEGATIVE_SCHEMA as NONNEG, POSE_COLUMNS, POSE_NOISE_SCHEMA, Simulator,
                           SourceOutput, Stream, noisy, pose_array_from, pose_stream, robot_description_data)

from .kinematics import (CODE_R_THESIS, MM_PER_M, code_from_thesis, code_point_from_thesis, inverse_kinematics,
                         tip_position)
from .model import JOINTS, PARAMETERS

DESCRIPTIONS = {"thesis": "arash_asist", "authors_code": "arash_asist_mm"}
ROBOTS = ("leader", "follower")
ERRORS = {"type": "object", "properties": {p: {"type": "number"} for p in PARAMETERS},
          "required": list(PARAMETERS), "additionalProperties": False}
INSERTION_SIGN = -1.0  # ARASH:ASiST's insertion in the thesis convention: d <= 0 (the tip at the RCM minus |d| v)
MAX_DRAWS = 50  # batches of candidate targets before the workspace is declared out of reach
FLOOR = {"rad": 1e-5, "m": 1e-6}  # smallest noise a config states (noise-free data stay solvable)


class ArashPairSimulator(Simulator):
    name = "arash.sim"
    summary = ("ARASH:ASiST pair: a follower RCM arm follows a leader's tool tip; encoders, tracked leader tip, "
               "tip-to-tip offsets, a survey of the follower's base")
    schema = {"type": "object",
              "properties": {"convention": {"enum": list(DESCRIPTIONS)},
                             "configurations": {"type": "integer", "minimum": 3},
                             "workspace_radius": {"type": "number", "exclusiveMinimum": 0},
                             "leader_error": ERRORS, "follower_error": ERRORS,
                             "base_tilt": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
                             "encoder_sigma": {"type": "object", "properties": {j: NONNEG for j in JOINTS},
                                               "required": list(JOINTS), "additionalProperties": False},
                             "tracker_sigma": NONNEG, "offset_sigma": NONNEG,
                             "base_survey": {"type": "boolean"}, "survey_sigma": POSE_NOISE_SCHEMA},
              "additionalProperties": False}
    defaults = {"convention": "thesis", "configurations": 60, "workspace_radius": 0.006,
                "leader_error": {"alpha": 0.010, "theta": -0.008, "l_1234": 0.0015},
                "follower_error": {"alpha": -0.012, "theta": 0.010, "l_1234": -0.0010},
                "base_tilt": [0.15, -0.10, 0.30],
                "encoder_sigma": {"phi": 2e-4, "psi": 2e-4, "d": 1e-5},
                "tracker_sigma": 1e-4, "offset_sigma": 1e-4,
                "base_survey": True, "survey_sigma": {"rotation": 1e-3, "translation": 1e-4}}

    def stream_columns(self, params: dict):
        columns = {"leader_joints": JOINTS, "follower_joints": JOINTS, "leader_tip": ("x", "y", "z"),
                   "tip_offset": ("dx", "dy", "dz")}
        return {**columns, "follower_base": POSE_COLUMNS} if params["base_survey"] else columns

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        nominal, limits = _nominal_arm()
        truth = {"leader": nominal + _errors(params["leader_error"]),
                 "follower": nominal + _errors(params["follower_error"])}
        eye = tip_position(limits.mean(axis=1), nominal, "thesis")
        base = _base_transform(eye, params["base_tilt"])
        targets, q_leader, q_follower = _configurations(params, rng, eye, base, truth["leader"], nominal, limits)
        tip_follower = np.array([base.transformFrom(p) for p in tip_position(q_follower, truth["follower"], "thesis")])
        n, enc = len(targets), np.array([params["encoder_sigma"][j] for j in JOINTS])
        data = {"leader_joints": q_leader + rng.normal(size=(n, 3)) * enc,
                "follower_joints": q_follower + rng.normal(size=(n, 3)) * enc,
                "leader_tip": targets + rng.normal(scale=params["tracker_sigma"], size=(n, 3)),
                "tip_offset": tip_follower - targets + rng.normal(scale=params["offset_sigma"], size=(n, 3))}
        survey = noisy([base], params["survey_sigma"], rng)[0]  # drawn last: the other streams stay the same
        true_q = {"leader": q_leader, "follower": q_follower}
        if params["convention"] == "authors_code":
            data = {name: code_from_thesis(v, np.zeros(3))[0] if name.endswith("joints") else code_point_from_thesis(v)
                    for name, v in data.items()}
            true_q = {r: code_from_thesis(q, np.zeros(3))[0] for r, q in true_q.items()}
            truth = {r: code_from_thesis(np.zeros(3), k)[1] for r, k in truth.items()}
            base, survey = _code_pose(base), _code_pose(survey)
        t = np.arange(n, dtype=float)  # one static configuration per second
        columns = self.stream_columns(params)
        streams = {name: Stream(name, t, columns[name], values, f"simulated:{name}") for name, values in data.items()}
        if params["base_survey"]:
            streams["follower_base"] = pose_stream("follower_base", t[:1], [survey], "simulated:follower_base")
        calibration = {r: {p: {"type": "scalar", "value": float(v)} for p, v in zip(PARAMETERS, truth[r])}
                       for r in ROBOTS}
        calibration["follower"]["base_in_leader"] = {"type": "pose3", "value": pose_array_from([base])[0].tolist()}
        states = {r: {"joints": Stream(f"{r}.joints", t, ("c0", "c1", "c2"), true_q[r], f"simulated:{r}.joints")}
                  for r in ROBOTS}
        return SourceOutput(streams, None, calibration, states)

    def robots(self, params: dict) -> dict[str, dict]:
        return {r: robot_description_data(DESCRIPTIONS[params["convention"]]) for r in ROBOTS}

    def config(self, params: dict) -> dict:
        """Both arms' encoders, the leader's tracked tip, the tool-to-tool offsets and (with `base_survey`)
        the survey of the follower's base, solved in one batch (configs/arash_pair.yaml)."""
        length = 1.0 if params["convention"] == "thesis" else MM_PER_M  # config lengths in the convention's unit

        def sigma(value: float, unit: str) -> float:
            return max(value, FLOOR[unit]) * (length if unit == "m" else 1.0)
        enc = {j: sigma(params["encoder_sigma"][j], "m" if j == "d" else "rad") for j in JOINTS}
        factors = [*({"type": "rcm.joint_encoders", "robot": r, "stream": f"{r}_joints", "sigma": enc} for r in ROBOTS),
                   {"type": "rcm.tool_position", "robot": "leader", "stream": "leader_tip",
                    "sigma": sigma(params["tracker_sigma"], "m")},
                   {"type": "rcm.tool_to_tool", "robot": "leader", "other": "follower", "stream": "tip_offset",
                    "sigma": sigma(params["offset_sigma"], "m")}]
        if params["base_survey"]:
            survey = params["survey_sigma"]
            factors.append({"type": "rcm.base_pose", "robot": "leader", "other": "follower", "stream": "follower_base",
                            "sigma": {"rotation": sigma(survey["rotation"], "rad"),
                                      "translation": sigma(survey["translation"], "m")}})
        return {"robots": {r: {"description": f"robots/{r}.yaml",
                               "states": {"stream": f"{r}_joints", "type": "vector3", "family": "joints"}}
                           for r in ROBOTS},
                "factors": factors,
                "initializers": [{"type": "rcm.base_transform", "robot": "leader", "other": "follower",
                                  "stream": "tip_offset"}],
                "solver": {"type": "batch", "method": "lm"}}


def _nominal_arm() -> tuple[np.ndarray, np.ndarray]:
    """(alpha, theta, l_1234) and the joint limits (3, 2) of the shipped thesis-convention arm (SI)."""
    desc = robot_description_data(DESCRIPTIONS["thesis"])
    return (np.array([desc["parameters"][p]["value"] for p in PARAMETERS], float),
            np.array([desc["joint_limits"][j] for j in JOINTS], float))


def _errors(errors: dict) -> np.ndarray:
    return np.array([errors[p] for p in PARAMETERS], float)


def _base_transform(eye: np.ndarray, tilt) -> gtsam.Pose3:
    """The follower's base in the leader's: half a turn about the vertical through the eye, then `tilt`."""
    rotation = gtsam.Rot3.Expmap(np.asarray(tilt, float)).compose(gtsam.Rot3.Rz(np.pi))
    return gtsam.Pose3(rotation, eye - rotation.rotate(eye))


def _configurations(params, rng, eye, base, leader, follower_nominal, limits):
    """Targets within `workspace_radius` of the eye that both arms reach inside their joint limits:
    (targets (n, 3), the leader's true joints, the follower's joints commanded through its nominal model)."""
    n, radius = params["configurations"], params["workspace_radius"]
    targets, q_leader, q_follower = [], [], []
    for _ in range(MAX_DRAWS):
        if len(targets) >= n:
            break
        direction = rng.normal(size=(4 * n, 3))
        points = eye + radius * rng.uniform(size=(4 * n, 1)) ** (1 / 3) * direction / np.linalg.norm(
            direction, axis=1, keepdims=True)
        ql = inverse_kinematics(points, leader, INSERTION_SIGN)
        local = np.array([base.transformTo(p) for p in points])
        qf = inverse_kinematics(local, follower_nominal, INSERTION_SIGN)
        ok = _inside(ql, limits) & _inside(qf, limits)
        targets.extend(points[ok]), q_leader.extend(ql[ok]), q_follower.extend(qf[ok])
    if len(targets) < n:
        raise ConfigError(f"arash.sim: workspace_radius {radius} m: both arms reach too few points within it "
                          f"({len(targets)} of {n} configurations); give a smaller radius")
    return np.array(targets[:n]), np.array(q_leader[:n]), np.array(q_follower[:n])


def _inside(q: np.ndarray, limits: np.ndarray) -> np.ndarray:
    return np.all((q >= limits[:, 0]) & (q <= limits[:, 1]), axis=1)


def _code_pose(pose: gtsam.Pose3) -> gtsam.Pose3:
    """A base-to-base transform of the thesis convention (m) in the authors' frames (mm)."""
    rotation = gtsam.Rot3(CODE_R_THESIS @ pose.rotation().matrix() @ CODE_R_THESIS.T)
    return gtsam.Pose3(rotation, code_point_from_thesis(pose.translation()))


SIMULATORS = [ArashPairSimulator]
