"""Serial-arm experiments (docs/models/serial_arm.md#results), shared by benchmarks/bench_serial_arm.py and the
tests: marker-pose errors of a calibrated model, leave-one-out on FIGAROH's real UR10 recording, the scipy
baseline on the same problem, held-out errors on simulated arms.

Errors follow the dataset's README: position = Euclidean distance between predicted and measured marker
positions, orientation = angle of R_meas^T R_pred; leave-one-out errors are pooled over the folds (RMS).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from fusionkit.api import POSE3, pose_sigmas
from fusionkit.config.loader import RunConfig, load_config
from fusionkit.pipeline import RunResult, build_problem, estimate, read_sources
from fusionkit.simulate import simulated_config
from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses
from fusionkit_plugins.serial_arm.diagnosis import element_name
from fusionkit_plugins.serial_arm.factors import entry_layout, pose_matrices
from fusionkit_plugins.serial_arm.kinematics import parameters_of
from fusionkit_plugins.serial_arm.model import AXIS_NAMES, arm_of

from research import ur10_figaroh
from research.arm_scipy import ScipyCalibration, Variable

ROBOT = "arm"
# the models of the README's table, as changes of configs/arm_ur10_real.yaml (the shipped config is "full")
MODELS = {"base_marker": ["robots.arm.description.kinematics={base: base, tool: marker}"],
          "offsets": ["robots.arm.description.kinematics.placements=[]"],
          "full": [],
          # + a compliance per gravity-loaded joint (shoulder lift, elbow, wrist 1; the URDF's inertials), prior
          # 1e-4 rad/(N m), loose (industrial arms are reported at 1e-6 - 1e-5 rad/(N m))
          "elastic": ["robots.arm.description.kinematics.compliances=[{parameter: compliance, joints: "
                      "[shoulder_lift_joint, elbow_joint, wrist_1_joint]}]",
                      "robots.arm.description.parameters.compliance={type: scalar, values: [0.0, 0.0, 0.0], "
                      "sigma: 1.0e-4, unit: rad/(N m)}"]}


# --- a run's model and its predictions --------------------------------------------------------------
def arm_layout(config: RunConfig):
    """(arm, layout, variables) of the robot's full kinematic layout (the description's base and tool)."""
    desc = config.robots[ROBOT].description
    arm = arm_of(desc)
    return (arm, *entry_layout(arm, {}, desc.parameters[arm.tool].vartype.name if arm.tool else ""))


def typed(entry: dict, index: int | None):
    """A truth-calibration entry's value (element `index`) as the variable type stores it."""
    value = entry["values"][index] if index is not None else entry["value"]
    if entry["type"] == "pose3":
        return POSE3.from_list(value)
    return float(value) if entry["type"] == "scalar" else np.asarray(value, float)


def parameters(result: RunResult, which: str = "estimate"):
    """The kinematic Parameters of a run: its estimate, the simulator's truth, or the description's nominal values."""
    _, layout, variables = arm_layout(result.config)
    desc = result.config.robots[ROBOT].description
    pick = {"estimate": lambda n, i: result.parameters[ROBOT][n].values[i or 0],
            "truth": lambda n, i: typed(result.truth.calibration[ROBOT][n], i),
            "nominal": lambda n, i: desc.parameters[n].values[i or 0]}[which]
    return parameters_of(layout, [pick(name, index) for name, index in variables])


def predicted(config: RunConfig, params, q: np.ndarray) -> np.ndarray:
    """Marker poses (N, 4, 4) the model with `params` predicts at joint values q (N, n)."""
    arm, layout, _ = arm_layout(config)
    return marker_poses(arm.chain, layout, np.asarray(q, float).reshape(len(q), -1), params).T


def pose_errors(P: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position error m, orientation error rad) of predicted poses P against measured T, each (N, 4, 4)."""
    pos = np.linalg.norm(P[:, :3, 3] - T[:, :3, 3], axis=1)
    ang = np.linalg.norm(Rotation.from_matrix(np.swapaxes(T[:, :3, :3], 1, 2) @ P[:, :3, :3]).as_rotvec(), axis=1)
    return pos, ang


def rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


# --- the real UR10 recording ---------------------------------------------------------------------------
def real_config(folder: Path, model: str = "full", rows=None, extra: tuple[str, ...] = ()) -> RunConfig:
    """configs/arm_ur10_real.yaml for `model` on the recording's `rows` (all by default), converted into `folder`."""
    joints, tracker = ur10_figaroh.write_streams(folder, rows)
    return load_config(ur10_figaroh.CONFIG, ur10_figaroh.overrides(joints, tracker) + MODELS[model] + list(extra))


def in_sample(model: str = "full", extra: tuple[str, ...] = ()) -> tuple[RunResult, np.ndarray, np.ndarray]:
    """(run, position errors, orientation errors) of one fit on all 23 samples, evaluated on them."""
    q, T = ur10_figaroh.read_recording()
    with tempfile.TemporaryDirectory() as tmp:
        result = estimate(real_config(Path(tmp), model, extra=extra))
    return (result, *pose_errors(predicted(result.config, parameters(result), q), T))


def leave_one_out(model: str = "full", fit=None) -> dict:
    """Pooled leave-one-out errors (23 fits on 22 samples, each predicting the one left out) and the
    seconds of all fits (config loading, fusionkit's whole estimate, or `fit`'s own time). `fit(config)`:
    the held-out sample's predicted pose from a fold's config and its seconds (default: fusionkit)."""
    q, T = ur10_figaroh.read_recording()
    pos, ang, seconds = [], [], 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(len(q)):
            rows = np.delete(np.arange(len(q)), i)
            tic = time.perf_counter()
            config = real_config(Path(tmp), model, rows)
            seconds += time.perf_counter() - tic
            P, s = (fit or fusionkit_fit)(config, q[i:i + 1])
            seconds += s
            p, a = pose_errors(P, T[i:i + 1])
            pos.append(p[0])
            ang.append(a[0])
    return {"pos": np.array(pos), "ang": np.array(ang), "seconds": seconds}


def fusionkit_fit(config: RunConfig, q: np.ndarray) -> tuple[np.ndarray, float]:
    tic = time.perf_counter()
    result = estimate(config)
    seconds = time.perf_counter() - tic
    return predicted(config, parameters(result), q), seconds


def scipy_fit(config: RunConfig, q: np.ndarray) -> tuple[np.ndarray, float]:
    """The scipy baseline from fusionkit's start values and held axes (their computation not timed)."""
    _, scipy = scipy_problem(config)
    out = scipy.solve()
    return scipy.marker_poses(out.values, q), out.seconds


# --- the scipy baseline on a fusionkit problem ----------------------------------------------------------
def built_problem(config: RunConfig):
    """The built fusionkit problem (factors, initializers, identifiability), not solved."""
    streams, _ = read_sources(config)
    return build_problem(config, streams), streams


def held_axes(problem) -> set[str]:
    report = problem.diagnostics.get(f"{ROBOT}: kinematic identifiability", {})
    return set(report.get("held", []))


def scipy_problem(config: RunConfig, problem=None, streams=None):
    """(fusionkit problem, ScipyCalibration) of the config's arm.tool_pose entry: the same parameters,
    start values (after the initializers), priors, held axes, tracker sigmas and data, the joints at their
    readings."""
    if problem is None:
        problem, streams = built_problem(config)
    arm, layout, variables = arm_layout(config)
    desc = config.robots[ROBOT].description
    held = held_axes(problem)
    roles = ["base"] * layout.base + ["tool"] * bool(layout.tool) + ["offset"] * len(layout.offsets) + \
        ["placement"] * len(layout.placements)
    out = []
    for p, (role, (name, index)) in enumerate(zip(roles, variables)):
        param = desc.parameters[name]
        key = problem.keys.get(ROBOT, name).key(index or 0)
        start, prior = param.vartype.read(problem.initial, key), param.values[index or 0]
        v = Variable(role, start, prior, None if param.sigma is None else param.sigma[index or 0])
        if role in ("base", "tool"):
            v.start, v.prior = start.matrix(), prior.matrix()
            labels = [f".{a}" for a in AXIS_NAMES]
        elif role == "offset":
            v.joint = layout.offsets[p - layout.base - bool(layout.tool)]
            labels = [""]
        else:
            v.joint, v.axes = layout.placements[p - layout.base - bool(layout.tool) - len(layout.offsets)]
            labels = [f".{AXIS_NAMES[a]}" for a in v.axes]
        v.free = np.array([element_name(desc, name, index) + label not in held for label in labels])
        out.append(v)
    tool = next(s for s in config.factors if s.type == "arm.tool_pose")
    joint_stream = next(s for s in config.factors if s.type == "arm.joint_encoders")["stream"]
    tracker, joints = streams[tool["stream"]], streams[joint_stream]
    if not np.array_equal(tracker.t, joints.t):
        raise ValueError("the scipy baseline pairs tracker and joint samples row by row: same stamps expected")
    chain = arm.chain
    scipy = ScipyCalibration(chain.model, chain.jids, chain.tool_id, chain.base_T_universe, out,
                             np.column_stack([joints.column(c) for c in desc.extra["joints"]]),
                             pose_matrices(tracker.pose_array()), np.asarray(pose_sigmas(tool["sigma"], False), float))
    return problem, scipy


def compare_with_scipy(config: RunConfig) -> dict:
    """fusionkit's estimate and scipy's on the same problem: both solutions' cost in scipy's cost function
    (0.5 * sum of squared whitened residuals, joints at their readings), the largest parameter difference
    in units of fusionkit's sigma, and the solve times."""
    tic = time.perf_counter()
    result = estimate(config)
    fk_seconds = time.perf_counter() - tic
    _, scipy = scipy_problem(config, result.problem, result.streams)
    sp = scipy.solve()
    variables = arm_layout(config)[2]
    fk_values, z = [], []
    for v, (name, index), mine in zip(scipy.variables, variables, sp.values):
        est = result.parameters[ROBOT][name]
        value, sigma = est.values[index or 0], np.ravel(est.sigma[index or 0])
        if v.role in ("base", "tool"):
            fk_values.append(value.matrix())
            d = gtsam.Pose3.Logmap(value.between(gtsam.Pose3(mine)))
        else:
            fk_values.append(value)
            d = np.atleast_1d(np.asarray(mine, float) - value)
        free = v.free if v.free is not None else np.ones(len(d), bool)
        z += list(np.abs(d[free]) / sigma[free])
    fk_cost = 0.5 * float(np.sum(scipy.residuals_at(fk_values) ** 2))
    return {"result": result, "fusionkit_s": fk_seconds, "fusionkit_solve_s": result.timings["solve_s"],
            "scipy": sp, "fusionkit_cost": fk_cost, "scipy_cost": sp.cost, "max_z": max(z),
            "free": int(scipy.free.sum())}


# --- simulated arms ---------------------------------------------------------------------------------------
def held_out(result: RunResult, params, samples: int, tracker_sigma: float, encoder_sigma: float,
             seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(position m, orientation rad) errors of the marker poses predicted with `params` at noisy readings of
    `samples` new random configurations, against the true poses measured with the tracker's noise."""
    arm, layout, _ = arm_layout(result.config)
    chain = arm.chain
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)
    q = rng.uniform(lo, hi, (samples, chain.n))
    true = marker_poses(chain, layout, q, parameters(result, "truth")).T
    measured = np.array([(gtsam.Pose3(T) * gtsam.Pose3.Expmap(rng.normal(0.0, tracker_sigma, 6))).matrix()
                         for T in true])
    readings = q + rng.normal(0.0, encoder_sigma, q.shape)
    return pose_errors(marker_poses(chain, layout, readings, params).T, measured)


def estimated_axes(result: RunResult) -> tuple[np.ndarray, np.ndarray]:
    """(errors against the truth, z-scores) of every estimated tangent axis (held axes, sigma 1e-9, left out)."""
    errors, zs = [], []
    for name, ev in result.evaluation["parameters"][ROBOT].items():
        sigma = np.ravel(result.parameters[ROBOT][name].sigma)
        z = np.ravel(ev["z_per_axis"])
        keep = sigma > 1e-8  # held axes: HOLD_SIGMA 1e-9 (a compliance sigma is ~1e-7 rad/(N m))
        errors += list((z * sigma)[keep])
        zs += list(z[keep])
    return np.array(errors), np.array(zs)


def simulated_calibration(description: str, configurations: int, data_sigma: float, told_sigma: float,
                          seed: int, held_out_samples: int = 300) -> dict:
    """arm.sim with a tracker of `data_sigma` (m and rad per axis) and 1e-5 rad encoders, calibrated with the
    tracker's sigma stated as `told_sigma`: errors and z-scores of the estimated axes, chi2/dof, and the rms
    held-out position and orientation errors of the nominal and the calibrated model on new configurations
    measured like the calibration data (floor: sqrt(3) data_sigma in position)."""
    encoder = 1e-5
    params = {"description": description, "configurations": configurations,
              "tracker_sigma": {"rotation": data_sigma, "translation": data_sigma}, "encoder_sigma": encoder}

    def told(config: dict) -> None:
        config["factors"][1]["sigma"] = {"rotation": told_sigma, "translation": told_sigma}
    with simulated_config("arm.sim", params, seed=seed, edit=told) as config:
        result = estimate(config, keep_rejected=True)
    errors, z = estimated_axes(result)
    before = held_out(result, parameters(result, "nominal"), held_out_samples, data_sigma, encoder, seed + 100)
    after = held_out(result, parameters(result, "estimate"), held_out_samples, data_sigma, encoder, seed + 100)
    return {"estimated": len(z), "max_error": float(np.max(np.abs(errors))), "rms_z": rms(z),
            "max_z": float(np.max(np.abs(z))), "chi2_per_dof": result.solution.chi2_per_dof,
            "rejected": result.solution.rejection is not None,
            "before_pos": rms(before[0]), "before_ang": rms(before[1]), "after_pos": rms(after[0]),
            "after_ang": rms(after[1]), "floor": float(np.sqrt(3) * data_sigma)}
