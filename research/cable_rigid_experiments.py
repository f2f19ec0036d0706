"""The experiments of the thesis's ARAS-CAM chapter (docs/models/cable_rigid.md) on simulated
ARAS-CAM sequences: what the benchmark
(benchmarks/bench_cable_rigid.py) prints and the tests assert.

- `run_sequence`: one simulated sequence (`smooth` = sequence 12, `dynamic` = sequence 01) through
  the config the simulator writes (Monte-Carlo initialization, scaled VO + rigid cables, batch LM),
  optionally with pulley pseudo-measurements or another solver;
- `table_4_1`: localization error of forward kinematics, VO and the fused graph, the cable-length
  residual before and after refinement, and the consistency of the position sigmas, pooled over
  seeds;
- `pseudo_measurements`: coplanarity of the four pulleys and tape-measured distances between
  neighbouring pulleys, drawn from the truth with the tape's noise.
"""

from __future__ import annotations

import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np
import yaml

from fusionkit import load_config
from fusionkit.api import nearest
from fusionkit.config.loader import RunConfig
from fusionkit_plugins.cable_rigid.simulators import ROBOT_NAME, CdprSimulator


SEQUENCES = ("dynamic", "smooth")  # the thesis's sequences 01 and 12
CABLE_ENTRY = "factors[2]:cable.length"
TAPE_SIGMA = 0.003       # m: a tape measure between two pulleys
COPLANAR_SIGMA = 0.002   # m: pulleys mounted on one frame


def pseudo_measurements(pulleys: np.ndarray, rng: np.random.Generator, tape_sigma: float = TAPE_SIGMA) -> list[dict]:
    """Factor entries: the pulleys are coplanar, and the distances around the rectangle 0-1-2-3
    were taped (true distance + N(0, tape_sigma))."""
    n = len(pulleys)
    entries = [{"type": "cable.pulleys_coplanar", "robot": ROBOT_NAME, "pulleys": list(range(n)),
                "sigma": COPLANAR_SIGMA}]
    for i in range(n):
        j = (i + 1) % n
        d = float(np.linalg.norm(pulleys[i] - pulleys[j]) + rng.normal(0.0, tape_sigma))
        entries.append({"type": "cable.pulley_distance", "robot": ROBOT_NAME, "pulleys": [i, j],
                        "distance": round(d, 4), "sigma": tape_sigma})
    return entries


def sequence_config(motion: str, seed: int, params: dict | None = None, solver: dict | None = None,
                    pseudo: bool = False) -> dict:
    """The simulator's config with its data generated in-process (`simulate` source)."""
    sim = CdprSimulator()
    params = {"motion": motion, **(params or {})}
    config = {"name": f"arascam_{motion}_{seed}", **sim.config(params),
              "sources": [{"type": "simulate", "scenario": sim.name, "seed": seed, "params": params}]}
    if solver:
        config["solver"] = solver
    if pseudo:
        truth = sim.simulate(sim._params(params), np.random.default_rng(seed)).truth_calibration
        pulleys = np.array(truth[ROBOT_NAME]["pulley"]["values"])
        config["factors"] += pseudo_measurements(pulleys, np.random.default_rng(seed + 10_000))
    return config


@contextmanager
def loaded_sequence(motion: str, seed: int, **kw) -> Iterator[RunConfig]:
    """The validated config of one simulated sequence (see `sequence_config`), its robot
    description in a temporary folder that lives as long as the context."""
    config = sequence_config(motion, seed, **kw)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "robots").mkdir()
        for name, desc in CdprSimulator().robots(config["sources"][0]["params"]).items():
            (folder / "robots" / f"{name}.yaml").write_text(yaml.safe_dump(desc, sort_keys=False))
        (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
        yield load_config(folder / "config.yaml")


def run_sequence(motion: str, seed: int, **kw):
    """`fusionkit.pipeline.RunResult` of one simulated sequence."""
    from fusionkit.pipeline import estimate
    with loaded_sequence(motion, seed, **kw) as config:
        return estimate(config)


def normalized_position_errors(result) -> np.ndarray:
    """(K, 3) per-axis position error / 1-sigma of the fused trajectory at the truth's times."""
    truth, est = result.truth.trajectories[ROBOT_NAME], result.trajectories[ROBOT_NAME]
    m = nearest(truth.t, est.t, 1e-6)
    error = est.pose_array()[m.row, :3] - truth.pose_array()[m.state, :3]
    return error / result.position_sigma[ROBOT_NAME][m.row]


def consistency_table(z: np.ndarray) -> dict[str, list[float]]:
    """Share (%) of |z| inside 1, 2, 3 per axis."""
    return {axis: [float(100 * np.mean(np.abs(z[:, i]) <= k)) for k in (1, 2, 3)] for i, axis in enumerate("xyz")}


def localization_errors(result, robot: str) -> dict[str, float]:
    """Thesis Table 4.1's comparison from one run: position RMSE (m) against the truth of forward kinematics
    alone, visual odometry alone (report.json evaluation.baselines: cable.length and pose.scaled_relative)
    and the fused graph, at the state times."""
    b = result.evaluation["baselines"][robot]
    return {"forward_kinematics": b["forward_kinematics"]["position_rmse_m"],
            "visual_odometry": b["visual_odometry"]["position_rmse_m"],
            "fused": b["visual_odometry"]["fused_position_rmse_m"]}


def table_4_1(motion: str, seeds: range) -> dict:
    """Mean localization errors (FK, VO, fused; m), how often fused beats both, the cable-length
    residual rms before/after refinement (m), pooled consistency, pulley and scale errors."""
    errors, residuals, z, pulley, scale_z, iterations = [], [], [], [], [], []
    for seed in seeds:
        result = run_sequence(motion, seed)
        errors.append(localization_errors(result, ROBOT_NAME))
        entry = result.evaluation["residuals_by_entry"][CABLE_ENTRY]
        residuals.append((entry["initial_rms"], entry["final_rms"]))
        z.append(normalized_position_errors(result))
        params = result.evaluation["parameters"][ROBOT_NAME]
        pulley.append(params["pulley"]["mean_abs_error"])
        scale_z.append(params["vo_scale"]["z_per_axis"][0][0])
        iterations.append(result.solution.iterations)
    mean = {k: float(np.mean([e[k] for e in errors])) for k in errors[0]}
    return {"runs": len(errors), "errors_m": mean,
            "fused_beats_both": sum(e["fused"] < min(e["forward_kinematics"], e["visual_odometry"]) for e in errors),
            "improvement_over_fk": 1 - mean["fused"] / mean["forward_kinematics"],
            "improvement_over_vo": 1 - mean["fused"] / mean["visual_odometry"],
            "cable_residual_m": np.mean(residuals, axis=0).tolist(),
            "consistency_percent": consistency_table(np.concatenate(z)),
            "pulley_error_m": float(np.mean(pulley)), "scale_z_rms": float(np.sqrt(np.mean(np.square(scale_z)))),
            "iterations": iterations}


def shape_error(estimate: np.ndarray, truth: np.ndarray) -> float:
    """Mean pulley error (m) after the rigid motion that best aligns the estimate with the truth
    (Kabsch): the error of the pulley geometry itself, not of its placement in the base frame."""
    ce, ct = estimate.mean(axis=0), truth.mean(axis=0)
    u, _, vt = np.linalg.svd((estimate - ce).T @ (truth - ct))
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt))])
    aligned = (estimate - ce) @ (u @ flip @ vt) + ct
    return float(np.linalg.norm(aligned - truth, axis=1).mean())


def pseudo_measurement_gain(motion: str, seeds: range) -> dict:
    """Mean pulley error (m) without and with the pseudo-measurements on the same data: in the
    base frame, and of the geometry alone (`shape_error`)."""
    out: dict = {}
    for pseudo in (False, True):
        frame, shape = [], []
        for seed in seeds:
            result = run_sequence(motion, seed, pseudo=pseudo)
            frame.append(result.evaluation["parameters"][ROBOT_NAME]["pulley"]["mean_abs_error"])
            shape.append(shape_error(np.array(result.parameters[ROBOT_NAME]["pulley"].values),
                                     np.array(result.truth.calibration[ROBOT_NAME]["pulley"]["values"])))
        out["with" if pseudo else "without"] = {"base_frame_m": float(np.mean(frame)), "shape_m": float(np.mean(shape))}
    for kind in ("base_frame_m", "shape_m"):
        out[f"reduction_{kind[:-2]}"] = 1 - out["with"][kind] / out["without"][kind]
    return out
