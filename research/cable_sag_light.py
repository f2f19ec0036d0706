"""Light sagging cables at measured poses (issue: sagging cables on a real robot): the rigid model (`cable.length`)
against the catenary at the measured pose (`cable.catenary`) on `cable.sag_static` data of the small robot
(cdpr_small: 4.4 kg, 0.10 N/m cables of 5-13 m in the central workspace, where sag adds 0.5-9 mm to a cable), with motion
capture of the end-effector. Each run calibrates on the first half of the static poses and predicts the cable
lengths of the second half from their measured poses.

    python research/cable_sag_light.py [--seeds 5] [--com-error 0.02] [--moving]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import yaml

if __package__ in (None, ""):  # run as a script: the repository root on the path for `research.`
    import sys
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

MOCAP = {"rotation": 0.002, "translation": 0.001}  # rad, m
LENGTH_SIGMA = 0.0005                               # m
POSES = 40
STATICS_SIGMA = {"force": 0.05, "moment": 0.05}     # N, N m: the approximation's misfit at exact equilibria (0.01-0.04)
WORKSPACE = "{min: [-0.5, -3.0, -12.0], max: [1.0, 0.0, -3.0]}"  # every cable taut: sag 0.5-9 mm (median 2.4 mm)


def dataset(folder: Path, seed: int, poses: int = POSES, com_error: float = 0.0) -> Path:
    """The simulated recording; `com_error` (m, rms per axis): the true centre of mass off the description's."""
    from fusionkit.simulate import write_dataset
    write_dataset("cable.sag_static", folder, ["robot=cdpr_small", f"poses={poses}", f"length_sigma={LENGTH_SIGMA}",
                                               f"workspace={WORKSPACE}", f"com_error={com_error}",
                                               f"pose_sigma={{rotation: {MOCAP['rotation']}, translation: "
                                               f"{MOCAP['translation']}}}"], seed=seed)
    return folder


def config(folder: Path, model: str, poses: int, weight_sigma: float | None = None) -> dict:
    """The calibration on the first `poses` static poses: `rigid`, `catenary` (the description's weight per length)
    or `catenary_weight` (the weight estimated from a prior of `weight_sigma` N/m around half the true value)."""
    robot = yaml.safe_load((folder / "robots" / "cdpr.yaml").read_text())
    robot["parameters"]["pulley"]["sigma"] = 2.0  # the nominal pulleys are a guess, ~1 m off
    robot["parameters"]["offset"]["sigma"] = 2.0
    entry = {"type": "cable.length", "robot": "cdpr", "stream": "lengths", "sigma": LENGTH_SIGMA}
    if model != "rigid":
        entry = {"type": "cable.catenary", "robot": "cdpr", "stream": "lengths", "sigma": LENGTH_SIGMA}
    if model == "catenary_weight":
        robot["parameters"]["cable_weight"] = {"type": "scalar", "value": 0.5 * robot["cables"]["weight_per_length"],
                                               "sigma": weight_sigma, "unit": "N/m"}
        entry["weight"] = "cable_weight"
    factors = [{"type": "pose.absolute", "robot": "cdpr", "stream": "poses", "sigma": MOCAP}, entry]
    if model == "catenary_statics":  # the force and moment balance as a constraint, the centre of mass estimated
        robot["parameters"]["centre_of_mass"] = {"type": "point3", "value": robot["end_effector"]["com"],
                                                 "sigma": 0.05, "unit": "m"}
        entry["com"] = "centre_of_mass"
        factors.append({"type": "cable.statics", "robot": "cdpr", "stream": "lengths", "com": "centre_of_mass",
                        "sigma": STATICS_SIGMA})
    (folder / "robots" / f"{model}.yaml").write_text(yaml.safe_dump(robot, sort_keys=False))
    return {"name": f"light_{model}",
            "robots": {"cdpr": {"description": f"robots/{model}.yaml", "states": {"stream": "poses", "end": poses - 0.5}}},
            "sources": [{"type": "tum", "name": "poses", "path": "data/poses.tum"},
                        {"type": "csv", "name": "lengths", "path": "data/lengths.csv"}],
            "factors": factors,
            "initializers": [{"type": "pose.interpolate", "robot": "cdpr", "stream": "poses"}],
            "solver": {"type": "batch", "method": "lm"}}


def predicted_lengths(result, model: str, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The encoder readings (N, n) the calibration `result` of `model` predicts at poses R (N, 3, 3), t (N, 3): its
    pulleys, offsets and, where estimated, weight per length and centre of mass (else the description's; rigid:
    weightless cables, the straight chord)."""
    from fusionkit_plugins.cable_sag.measured_geometry import catenary_lengths
    from fusionkit_plugins.cable_sag.model import shipped_robot
    robot, _ = shipped_robot("cdpr_small")
    params = result.parameters["cdpr"]
    pulleys = np.array([np.asarray(v, float) for v in params["pulley"].values])
    offsets = np.array([float(v) for v in params["offset"].values])
    w = 0.0 if model == "rigid" else float(params["cable_weight"].values[0]) if "cable_weight" in params \
        else robot.cable_weight
    com = np.asarray(params["centre_of_mass"].values[0], float) if "centre_of_mass" in params else robot.com
    return catenary_lengths(R, t, np.broadcast_to(pulleys, (len(t),) + pulleys.shape), robot.attachments, com,
                            robot.weight, w) + offsets


def held_out_rms(folder: Path, model: str, result, first: int) -> float:
    """RMS (m) of the held-out lengths predicted at their measured poses with the calibration."""
    from scipy.spatial.transform import Rotation
    from fusionkit.data.files import read_csv_stream
    rows = np.loadtxt(folder / "data" / "poses.tum")[first:]
    R, t = Rotation.from_quat(rows[:, 4:8]).as_matrix(), rows[:, 1:4]
    z = read_csv_stream(folder / "data" / "lengths.csv", "lengths").values[first:]
    return float(np.sqrt(np.mean((predicted_lengths(result, model, R, t) - z) ** 2)))


def score(folder: Path, model: str, data: dict, held_out) -> dict:
    """Calibrate with config `data` (written to <model>.yaml) and score it: {pulley_mm (mean error against the
    truth), held_out_mm (held_out(result), m), chi2_dof, and what it estimated: weight (value, sigma) N/m, com (m),
    lag_ms (value, sigma)}; {rejected: why} when the chi-square gate refuses it."""
    from fusionkit.config.loader import load_config
    from fusionkit.errors import SolverError
    from fusionkit.pipeline import estimate
    file = folder / f"{model}.yaml"
    file.write_text(yaml.safe_dump(data, sort_keys=False))
    try:
        result = estimate(load_config(file))
    except SolverError as exc:  # refused by the chi-square gate: recorded, not a table row
        return {"rejected": str(exc)[:120]}
    truth = yaml.safe_load((folder / "truth" / "calibration.yaml").read_text())["robots"]["cdpr"]
    params = result.parameters["cdpr"]
    pulleys = np.array([np.asarray(v, float) for v in params["pulley"].values])
    row = {"pulley_mm": 1e3 * float(np.mean(np.linalg.norm(pulleys - np.asarray(truth["pulley"]["values"], float),
                                                           axis=1))),
           "held_out_mm": 1e3 * held_out(result), "chi2_dof": float(result.solution.chi2_per_dof)}
    if "lag" in params:
        row["lag_ms"] = (1e3 * float(params["lag"].values[0]), 1e3 * float(params["lag"].sigma[0, 0]))
    if "cable_weight" in params:
        row["weight"] = (float(params["cable_weight"].values[0]), float(params["cable_weight"].sigma[0, 0]))
    if "centre_of_mass" in params:
        row["com"] = [round(float(c), 4) for c in params["centre_of_mass"].values[0]]
    return row


def run(seed: int, models=("rigid", "catenary", "catenary_weight"), poses: int = POSES, com_error: float = 0.0) -> dict:
    """{model: score(...)} on static poses, the first half calibrating, the second predicted."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = dataset(Path(tmp) / "ds", seed, poses, com_error)
        return {model: score(folder, model, config(folder, model, poses // 2, weight_sigma=0.2),
                             lambda result, model=model: held_out_rms(folder, model, result, poses // 2))
                for model in models}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--com-error", type=float, default=0.0, help="m: the true centre of mass off the description's")
    parser.add_argument("--moving", action="store_true", help="the robot on a slow path, the encoders 30 ms early "
                        "(a time offset estimated), instead of static poses")
    parser.add_argument("--models", nargs="+", default=["rigid", "catenary", "catenary_weight"],
                        help="rigid, catenary, catenary_weight, catenary_statics (with cable.statics, the centre of "
                             "mass estimated)")
    args = parser.parse_args()
    for seed in range(args.seeds):
        rows = run_moving(seed, tuple(args.models)) if args.moving else run(seed, tuple(args.models),
                                                                               com_error=args.com_error)
        for model, row in rows.items():
            print(seed, model, {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()})



# --- a moving robot: the same light cables on a slow path, the encoders' clock early by LAG --------------------------
PATH = {"duration": 60.0, "rate": 10.0, "lag": 0.03}  # s, Hz, s


def moving_dataset(folder: Path, seed: int, path: dict = PATH) -> Path:
    from fusionkit.simulate import write_dataset
    write_dataset("cable.sag_static", folder, ["robot=cdpr_small", f"length_sigma={LENGTH_SIGMA}", f"workspace={WORKSPACE}",
                                               f"path={{duration: {path['duration']}, rate: {path['rate']}, lag: "
                                               f"{path['lag']}}}",
                                               f"pose_sigma={{rotation: {MOCAP['rotation']}, translation: "
                                               f"{MOCAP['translation']}}}"], seed=seed)
    return folder


def moving_config(folder: Path, model: str, path: dict = PATH) -> dict:
    """Calibration on the path's first half with a time offset `lag` (s) on the lengths."""
    data = config(folder, model, 0, weight_sigma=0.2)
    robot_file = folder / "robots" / f"{model}.yaml"
    robot = yaml.safe_load(robot_file.read_text())
    robot["parameters"]["lag"] = {"type": "scalar", "value": 0.0, "sigma": 0.1, "unit": "s"}
    robot_file.write_text(yaml.safe_dump(robot, sort_keys=False))
    data["robots"]["cdpr"]["states"] = {"stream": "poses", "end": path["duration"] / 2 - 0.5 / path["rate"]}
    data["factors"][1]["time_offset"] = {"parameter": "lag"}
    return data


def held_out_moving(folder: Path, model: str, result, path: dict = PATH) -> float:
    """RMS (m) of the second half's lengths predicted at the measured poses interpolated at t + lag (the estimate)."""
    from scipy.spatial.transform import Rotation, Slerp
    from fusionkit.data.files import read_csv_stream
    lag = float(result.parameters["cdpr"]["lag"].values[0])
    poses = np.loadtxt(folder / "data" / "poses.tum")
    stream = read_csv_stream(folder / "data" / "lengths.csv", "lengths")
    keep = (stream.t >= path["duration"] / 2) & (stream.t + lag <= poses[-1, 0])
    tau = stream.t[keep] + lag
    R = Slerp(poses[:, 0], Rotation.from_quat(poses[:, 4:8]))(tau).as_matrix()
    t = np.column_stack([np.interp(tau, poses[:, 0], poses[:, c]) for c in (1, 2, 3)])
    return float(np.sqrt(np.mean((predicted_lengths(result, model, R, t) - stream.values[keep]) ** 2)))


def run_moving(seed: int, models=("rigid", "catenary", "catenary_weight"), path: dict = PATH) -> dict:
    """{model: score(...)} on the moving robot, with the time offset lag_ms estimated."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = moving_dataset(Path(tmp) / "ds", seed, path)
        return {model: score(folder, model, moving_config(folder, model, path),
                             lambda result, model=model: held_out_moving(folder, model, result, path))
                for model in models}


if __name__ == "__main__":
    main()
