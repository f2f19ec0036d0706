"""Designed against random static poses for a cable robot's calibration (docs/models/cable_rigid.md#pose-selection),
shared by benchmarks/bench_cable_design.py and the tests.

Per seed: ARAS-CAM (the shipped `arascam` description) whose true pulleys are the nominal ones moved by
N(0, PULLEY_ERROR) per axis and true encoder offsets the nominal ones moved likewise; CANDIDATES taut level
positions drawn in the workspace (the seed's own); N of them chosen D-optimally from the nominal description (as
before any data), against the first N, 2N, 3N of the candidates in random order. Each pose is measured as the
design assumes: motion capture with MOCAP sigmas (body-frame rotation and translation), the rigid cable lengths
plus offsets with ENCODER sigma. fusionkit calibrates from them (`pose.absolute` + `cable.length`, from the
description's nominal pulleys and offsets); the errors of the calibrated pulleys (RMS over their 3n axes) and
offsets against the truth, and the sigmas the calibration reports against those the design predicted.
"""

from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path

import gtsam
import numpy as np
import yaml

from fusionkit.api import robot_description_data
from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate
from fusionkit_plugins.cable_rigid.design import design_of, random_candidates, select
from fusionkit_plugins.cable_rigid.simulators import Geometry, cables

ROBOT = "arascam"
PULLEY_ERROR = 0.05   # m per axis: the true pulleys against the tape-measured nominal ones (cable.cdpr's default)
OFFSET_ERROR = 0.05   # m
ENCODER = 0.001       # m
MOCAP = {"rotation": 0.002, "translation": 0.001}
CANDIDATES = 500


def truth(desc: dict, rng: np.random.Generator) -> tuple[Geometry, np.ndarray]:
    """(the true geometry, the true offsets) of one robot: the nominal ones moved at random."""
    d = design_of(desc)
    geo = d.geometry
    pulleys = geo.pulleys + rng.normal(0.0, PULLEY_ERROR, geo.pulleys.shape)
    return replace(geo, pulleys=pulleys), d.offsets + rng.normal(0.0, OFFSET_ERROR, geo.n)


def measure(geo: Geometry, offsets: np.ndarray, positions: np.ndarray, rng: np.random.Generator):
    """(motion-capture rows t x y z qx qy qz qw, encoder rows t l0..), one per level pose, t = its index."""
    n, N = geo.n, len(positions)
    lengths = cables(positions, np.broadcast_to(np.eye(3), (N, 3, 3)), geo)[0] + offsets
    lengths += rng.normal(0.0, ENCODER, lengths.shape)
    sigma = np.array([MOCAP["rotation"]] * 3 + [MOCAP["translation"]] * 3)
    mocap = []
    for k, p in enumerate(positions):
        seen = gtsam.Pose3(gtsam.Rot3(), p).compose(gtsam.Pose3.Expmap(rng.normal(0.0, sigma)))
        q = seen.rotation().toQuaternion()
        mocap.append([k, *seen.translation(), q.x(), q.y(), q.z(), q.w()])
    return np.array(mocap), np.column_stack([np.arange(N), lengths]), n


def calibrate(desc_name: str, mocap: np.ndarray, lengths: np.ndarray, n: int, folder: Path):
    """fusionkit's calibration from the measured poses: the RunResult."""
    np.savetxt(folder / "mocap.tum", mocap, fmt="%.12g")
    np.savetxt(folder / "lengths.csv", lengths, delimiter=",", fmt="%.12g",
               header="t," + ",".join(f"l{i}" for i in range(n)), comments="")
    config = {"name": "cable_design", "robots": {"cdpr": {"description": desc_name, "states": {"stream": "mocap"}}},
              "sources": [{"type": "tum", "name": "mocap", "path": "mocap.tum"},
                          {"type": "csv", "name": "lengths", "path": "lengths.csv"}],
              "factors": [{"type": "pose.absolute", "robot": "cdpr", "stream": "mocap", "sigma": MOCAP},
                          {"type": "cable.length", "robot": "cdpr", "stream": "lengths", "sigma": ENCODER}],
              "initializers": [{"type": "pose.interpolate", "robot": "cdpr", "stream": "mocap"}],
              "solver": {"type": "batch", "method": "lm"}, "output": {"plots": False}}
    (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return estimate(load_config(folder / "config.yaml"), keep_rejected=True)


def case(seed: int, count: int, multiples=(1, 2, 3)) -> dict:
    """One seed: {"designed": ..., "random x<k>": ...}, each {pulley_rms_m, offset_rms_m, reported (sigmas),
    predicted (the design's sigmas for those poses)} for `count` designed poses and k x count random ones."""
    desc = robot_description_data(ROBOT)
    design = design_of(desc)
    rng = np.random.default_rng(seed)
    geo, offsets = truth(desc, rng)
    candidates = random_candidates(desc, design, CANDIDATES, rng)
    choice = select(design, candidates, count, ENCODER, MOCAP)
    order = rng.permutation(len(candidates))
    picks = {"designed": choice.indices, **{f"random x{k}": order[:k * count] for k in multiples}}
    out = {}
    for label, rows in picks.items():
        mocap, lengths, n = measure(geo, offsets, candidates[rows], rng)
        with tempfile.TemporaryDirectory() as tmp:
            result = calibrate(ROBOT, mocap, lengths, n, Path(tmp))
        est = result.parameters["cdpr"]
        pulleys = np.array([np.asarray(v, float) for v in est["pulley"].values])
        out[label] = {"pulley_rms_m": float(np.sqrt(np.mean((pulleys - geo.pulleys) ** 2))),
                      "offset_rms_m": float(np.sqrt(np.mean((np.ravel(est["offset"].values) - offsets) ** 2))),
                      "reported": np.concatenate([np.ravel(est["pulley"].sigma), np.ravel(est["offset"].sigma)]),
                      "predicted": choice.sigma_of(rows), "status": result.solution.rejection or "accepted"}
    return out
