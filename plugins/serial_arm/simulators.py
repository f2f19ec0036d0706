"""`arm.sim`: a serial arm from its URDF measured by a tracker (docs/reference/factors.md#simulators).

Random static configurations (t = sample index) or a smooth joint trajectory; the true kinematic
parameters are the description's nominal ones plus Gaussian errors, drawn only for the parameters
the identifiability analysis keeps (an error on a held one would be absorbed by the others and could
not be compared with its truth); tracker (6-D pose or 3-D position) and encoder noise; optionally the
offset of one joint drifting smoothly during the run (a time-varying parameter).
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

import gtsam
import numpy as np

from fusionkit.api import (ConfigError, NON_NEGATIVE_SCHEMA as NONNEG, POSE3, POSE_COLUMNS, POSE_NOISE_SCHEMA,
                           Simulator, SourceOutput, Stream, noisy, pose_stream, robot_description_data)

from .factors import entry_layout
from .identifiability import analyze, kinematic_regressor
from .vectorized_kinematics import marker_poses
from .kinematics import parameters_of
from .model import Arm, chain_from, couplings_of, kinematic_groups, tool_frames
from .urdf import PREFIX, urdf_path

ROBOTS = Path(str(files("fusionkit_robots") / "serial_arm"))  # this family's shipped descriptions (robots/serial_arm/)
DRIFT_PARAMETER = "drifting_offset"


def _sigma_row(raw, index: int, dim: int) -> np.ndarray:
    """A description's prior sigma of element `index` per tangent axis (inf: no prior)."""
    if raw is None:
        return np.full(dim, np.inf)
    a = np.asarray(raw, float)
    if a.ndim == 2:
        return a[index]
    return np.broadcast_to(a if a.shape == (dim,) else a.reshape(-1)[:1], (dim,)).astype(float)


class ArmSimulator(Simulator):
    name = "arm.sim"
    summary = ("serial arm from its URDF (ur10_tracker, panda_tracker): random configurations or a joint trajectory, "
               "kinematic errors, tracker and encoder noise, optionally a drifting joint offset")
    schema = {"type": "object",
              "properties": {"description": {"type": "string"},
                             "configurations": {"type": "integer", "minimum": 2},
                             "motion": {"enum": ["static", "trajectory"]},
                             "duration": {"type": "number", "exclusiveMinimum": 0},
                             "rate": {"type": "number", "exclusiveMinimum": 0},
                             "measurement": {"enum": ["pose", "position"]},
                             "tracker_sigma": POSE_NOISE_SCHEMA, "encoder_sigma": NONNEG,
                             "errors": {"type": "object",
                                        "properties": {"base": POSE_NOISE_SCHEMA, "tool": POSE_NOISE_SCHEMA,
                                                       "joint_offsets": NONNEG, "placements": POSE_NOISE_SCHEMA,
                                                       "compliances": NONNEG, "mass_compliances": NONNEG},
                                        "additionalProperties": False},
                             "drift": {"type": "object",
                                       "properties": {"joint": {"type": "integer", "minimum": 0}, "change": NONNEG,
                                                      "random_walk": {"type": "number", "exclusiveMinimum": 0}},
                                       "additionalProperties": False}},
              "additionalProperties": False}
    defaults = {"description": "ur10_tracker", "configurations": 60, "motion": "static", "duration": 60.0,
                "rate": 10.0, "measurement": "pose", "tracker_sigma": {"rotation": 1e-4, "translation": 1e-4},
                "encoder_sigma": 1e-5,
                "errors": {"base": {"rotation": 0.02, "translation": 0.02},
                           "tool": {"rotation": 0.02, "translation": 0.005}, "joint_offsets": 0.005,
                           "placements": {"rotation": 0.001, "translation": 0.0005}, "compliances": 5e-5,
                           "mass_compliances": 2.5e-4},
                "drift": {"joint": 2, "change": 0.0, "random_walk": 0.001}}

    def stream_columns(self, params: dict):
        data = _shipped_arm(params)
        return {"joints": tuple(data["joints"]), "tracker": tracker_columns(params, tool_frames(data))}

    def robots(self, params: dict) -> dict[str, dict]:
        """The description; with a drift, the drifting joint's offset becomes its own time-varying parameter."""
        data = _shipped_arm(params)
        if not data["urdf"].startswith(PREFIX):  # a URDF shipped beside the description: where it is installed
            data["urdf"] = str(urdf_path(data["urdf"], ROBOTS))
        if params["drift"]["change"] > 0:
            kin, pars = data["kinematics"], data["parameters"]
            joint = data["joints"][params["drift"]["joint"]]
            for group in kin.get("joint_offsets", []):
                if joint in group["joints"]:
                    i = group["joints"].index(joint)
                    group["joints"].pop(i)
                    pars[group["parameter"]]["values"].pop(i)
            kin["joint_offsets"] = [g for g in kin.get("joint_offsets", []) if g["joints"]] + \
                [{"parameter": DRIFT_PARAMETER, "joints": [joint]}]
            pars[DRIFT_PARAMETER] = {"type": "scalar", "values": [0.0], "sigma": 0.01, "time_varying": True,
                                     "unit": "rad"}
        return {"arm": data}

    def config(self, params: dict) -> dict:
        """Encoders and the tracker; with several tool frames, one arm.tool_position entry per frame on its columns."""
        data = _shipped_arm(params)
        n, frames = len(data["joints"]), tool_frames(data)
        tracker = "arm.tool_pose" if params["measurement"] == "pose" else "arm.tool_position"
        sigma = {k: max(v, 1e-6) for k, v in params["tracker_sigma"].items()}
        factors = [{"type": "arm.joint_encoders", "robot": "arm", "stream": "joints",
                    "sigma": max(params["encoder_sigma"], 1e-7)}]
        if len(frames) == 1:
            factors.append({"type": tracker, "robot": "arm", "stream": "tracker",
                            "sigma": sigma if params["measurement"] == "pose" else sigma["translation"]})
        else:
            columns = tracker_columns(params, frames)
            factors += [{"type": tracker, "robot": "arm", "stream": "tracker", "tool_frame": frame,
                         "columns": list(columns[3 * i:3 * i + 3]), "sigma": sigma["translation"]}
                        for i, frame in enumerate(frames)]
        if params["drift"]["change"] > 0:
            factors.append({"type": "parameter.random_walk", "robot": "arm", "parameter": DRIFT_PARAMETER,
                            "sigma": params["drift"]["random_walk"]})
        return {"robots": {"arm": {"description": "robots/arm.yaml",
                                   "states": {"stream": "joints", "type": f"vector{n}", "family": "joints"}}},
                "factors": factors, "solver": {"type": "batch", "method": "lm"}}

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        data = self.robots(params)["arm"]
        frames = tool_frames(data)
        chain = chain_from(urdf_path(data["urdf"], ROBOTS), data["base_frame"], frames, data["joints"],
                           couplings_of(data), data.get("locked", {}))
        pars = data["parameters"]
        arms = [Arm(chain.for_tool(frame), *kinematic_groups(data, frame)) for frame in frames]
        layouts = [entry_layout(arm, {}, pars[arm.tool]["type"] if arm.tool else "") for arm in arms]
        variables = union_variables(layouts)
        t, q = self._motion(params, chain, rng)
        nominal = [_value(pars[name], index) for name, index in variables]
        truth = self._truth(params, arms, layouts, variables, pars, nominal, q, rng)
        poses = []
        for arm, (layout, names) in zip(arms, layouts):
            values = [truth[variables.index(v)] for v in names]
            p = parameters_of(layout, values)
            offsets = list(p.offsets)
            for i, change in self._drift(params, names, t).items():  # the drifting offset: one value per sample
                offsets[i - layout.base - bool(layout.tool)] = values[i] + change
            p.offsets = offsets
            poses.append([gtsam.Pose3(T) for T in marker_poses(arm.chain, layout, q, p).T])
        noise = params["tracker_sigma"]
        columns = tracker_columns(params, frames)
        if params["measurement"] == "pose":
            tracker = pose_stream("tracker", t, noisy(poses[0], noise, rng), "simulated:tracker")
        else:
            xyz = np.concatenate([[p.translation() for p in hand] for hand in poses], axis=1)
            tracker = Stream("tracker", t, columns, xyz + rng.normal(0.0, noise["translation"], xyz.shape),
                             "simulated:tracker")
        readings = q + rng.normal(0.0, params["encoder_sigma"], q.shape)
        names = tuple(f"c{i}" for i in range(chain.n))
        calibration = {}
        for (name, index), value in zip(variables, truth):  # the drifting offset: its value at the first sample
            entry = calibration.setdefault(name, {"type": pars[name]["type"]})
            listed = POSE3.to_list(value) if isinstance(value, gtsam.Pose3) else \
                float(value) if np.ndim(value) == 0 else [float(x) for x in value]
            if index is None:
                entry["value"] = listed
            else:
                entry.setdefault("values", []).append(listed)
        return SourceOutput(
            {"joints": Stream("joints", t, tuple(data["joints"]), readings, "simulated:encoders"), "tracker": tracker},
            truth_calibration={"arm": calibration},
            truth_states={"arm": {"joints": Stream("arm.joints", t, names, q, "simulated:joints")}})

    @staticmethod
    def _motion(params: dict, chain, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Sample times and true joint values: uniform within the limits (at most +-pi), or sinusoids
        of 0.02-0.08 Hz around the middle of the range."""
        if params["motion"] == "static":
            n = params["configurations"]
            return np.arange(n, dtype=float), random_configurations(chain, n, rng)
        lo, hi = joint_range(chain)
        t = np.arange(0.0, params["duration"], 1.0 / params["rate"])
        mid, amp = (lo + hi) / 2, np.minimum((hi - lo) / 2 * 0.8, 1.2)
        freq, phase = rng.uniform(0.02, 0.08, chain.n), rng.uniform(0, 2 * np.pi, chain.n)
        return t, mid + amp * np.sin(2 * np.pi * freq * t[:, None] + phase)

    @staticmethod
    def _truth(params: dict, arms: list[Arm], layouts: list, variables: list, pars: dict, nominal: list,
               q: np.ndarray, rng) -> list:
        """Nominal values plus errors, drawn for the tangent axes the tool frames' measurements identify together."""
        widths = {v: w for layout, names in layouts for v, w in zip(names, layout.widths)}
        start = np.cumsum([0] + [widths[v] for v in variables])
        sigma, scale = np.zeros(start[-1]), np.zeros(start[-1])
        kind = params["measurement"]
        blocks = []
        for arm, (layout, names) in zip(arms, layouts):
            columns = np.concatenate([np.arange(start[variables.index(v)], start[variables.index(v) + 1])
                                      for v in names]).astype(int)
            sigma[columns] = _error_sigmas(params["errors"], layout)
            scale[columns] = np.concatenate([_sigma_row(pars[name].get("sigma"), index or 0, width)
                                             for (name, index), width in zip(names, layout.widths)])
            values = parameters_of(layout, [nominal[variables.index(v)] for v in names])
            A = np.zeros(((6 if kind == "pose" else 3) * len(q[:: max(1, len(q) // 200)]), start[-1]))
            A[:, columns] = kinematic_regressor(arm.chain, layout, values, q[:: max(1, len(q) // 200)], kind,
                                                np.ones(6 if kind == "pose" else 3))
            blocks.append(A)
        xi = rng.normal(0.0, sigma)
        xi[analyze(np.concatenate(blocks), np.where(np.isfinite(scale), scale, 1.0)).held] = 0.0
        out = []
        for value, a, b in zip(nominal, start[:-1], start[1:]):
            d = xi[a:b]
            if isinstance(value, gtsam.Pose3):
                out.append(value.compose(gtsam.Pose3.Expmap(d)))
            else:
                out.append(value + (d if np.ndim(value) else float(d[0])))
        return out

    @staticmethod
    def _drift(params: dict, variables: list, t: np.ndarray) -> dict[int, np.ndarray]:
        """{variable: change over time} of the drifting offset."""
        if params["drift"]["change"] <= 0:
            return {}
        return {variables.index((DRIFT_PARAMETER, 0)): drift_truth(params, t, 0.0)}


def union_variables(layouts: list) -> list:
    """Every tool frame's layout variables once, ordered as the identifiability diagnostic orders its columns: base,
    markers, offsets, placements, compliances, mass compliances (within each, in order of first use)."""
    role = {}
    for layout, names in layouts:
        ends = np.cumsum([layout.base, bool(layout.tool), len(layout.offsets), len(layout.placements),
                          len(layout.compliances), len(layout.mass_compliances)])
        for i, v in enumerate(names):
            role.setdefault(v, int(np.searchsorted(ends, i, side="right")))
    return sorted(role, key=lambda v: role[v])  # stable: first use within a role


def tracker_columns(params: dict, frames: tuple[str, ...]) -> tuple[str, ...]:
    """The tracker stream's columns: a pose or x, y, z; with several tool frames `<frame>_x`, ... per frame."""
    if len(frames) == 1:
        return POSE_COLUMNS if params["measurement"] == "pose" else ("x", "y", "z")
    return tuple(f"{frame}_{axis}" for frame in frames for axis in "xyz")


def joint_range(chain) -> tuple[np.ndarray, np.ndarray]:
    """The joint values the simulator moves in: the URDF limits, at most +-pi (rad; m for a prismatic joint)."""
    return np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)


def random_configurations(chain, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, n) joint vectors drawn uniformly within `joint_range`: the simulator's static configurations."""
    lo, hi = joint_range(chain)
    return rng.uniform(lo, hi, (count, chain.n))


def drift_truth(params: dict, t: np.ndarray, start: float) -> np.ndarray:
    """The simulated drifting offset at times t (rad): from `start` at the first sample, a smooth S-curve
    that has changed by `drift.change` at the last."""
    span = max(t[-1] - t[0], 1e-9)
    return start + params["drift"]["change"] * (1 - np.cos(np.pi * (t - t[0]) / span)) / 2


def _error_sigmas(err: dict, layout) -> np.ndarray:
    """The simulated error's sigma on every tangent axis of the layout (`errors` of the parameters)."""
    out = []
    for role, width in (("base", 6 * layout.base), ("tool", {"pose3": 6, "point3": 3}.get(layout.tool, 0))):
        out += ([err[role]["rotation"]] * 3 if width == 6 else []) + [err[role]["translation"]] * 3 * (width > 0)
    out += [err["joint_offsets"]] * len(layout.offsets)
    out += [err["placements"]["rotation" if a < 3 else "translation"] for _, axes in layout.placements for a in axes]
    out += [err["compliances"]] * len(layout.compliances)
    out += [err["mass_compliances"]] * len(layout.lumped) * len(layout.mass_compliances)
    return np.array(out, float)


def _shipped_arm(params: dict) -> dict:
    """The registered serial_arm description `params` names (a fresh dict); ConfigError otherwise."""
    data = robot_description_data(params["description"])
    where = f"arm.sim: description {params['description']!r}"
    if data.get("model") != "serial_arm":
        raise ConfigError(f"{where} is a {data.get('model', 'generic')!r} robot; arm.sim needs a serial_arm one")
    n = len(data["joints"])
    if params["measurement"] == "pose" and len(tool_frames(data)) > 1:
        raise ConfigError(f"{where} has several tool frames: arm.sim measures their markers' positions "
                          "(measurement: position)")
    if params["drift"]["change"] > 0 and params["drift"]["joint"] >= n:
        raise ConfigError(f"arm.sim: drift.joint {params['drift']['joint']} is not a joint of "
                          f"{params['description']!r} (0 .. {n - 1})")
    return data


def _value(raw: dict, index: int | None):
    """A parameter's typed nominal value from a description dict."""
    value = raw["values"][index] if index is not None else raw["value"]
    if raw["type"] == "pose3":
        return POSE3.from_list(value)
    return float(value) if raw["type"] == "scalar" else np.asarray(value, float)


SIMULATORS = [ArmSimulator]
