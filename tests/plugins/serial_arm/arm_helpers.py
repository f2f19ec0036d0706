"""Helpers for the serial-arm tests: a run's kinematic parameters in a factor layout, held-out samples."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import POSE3
from fusionkit_plugins.serial_arm.factors import entry_layout
from fusionkit_plugins.serial_arm.kinematics import marker_pose, parameters_of
from fusionkit_plugins.serial_arm.model import arm_of


def typed(entry: dict, index: int | None):
    """A truth-calibration entry's value (element `index`) as the variable type stores it."""
    value = entry["values"][index] if index is not None else entry["value"]
    if entry["type"] == "pose3":
        return POSE3.from_list(value)
    return float(value) if entry["type"] == "scalar" else np.asarray(value, float)


def layouts(config, robot: str = "arm"):
    """(chain, layout, variables) of the robot's full kinematic layout (the description's base and tool)."""
    desc = config.robots[robot].description
    arm = arm_of(desc)
    tool = desc.parameters[arm.tool].vartype.name if arm.tool else ""
    layout, variables = entry_layout(arm, {}, tool)
    return arm.chain, layout, variables


def estimated_parameters(result, robot: str = "arm"):
    chain, layout, variables = layouts(result.config, robot)
    est = result.parameters[robot]
    return parameters_of(layout, [est[name].values[index or 0] for name, index in variables])


def true_parameters(result, robot: str = "arm"):
    chain, layout, variables = layouts(result.config, robot)
    truth = result.truth.calibration[robot]
    return parameters_of(layout, [typed(truth[name], index) for name, index in variables])


def nominal_parameters(config, robot: str = "arm"):
    chain, layout, variables = layouts(config, robot)
    desc = config.robots[robot].description
    return parameters_of(layout, [desc.parameters[name].values[index or 0] for name, index in variables])


def held_out_errors(result, params, samples: int, tracker_sigma: float, encoder_sigma: float, seed: int):
    """Position (m, Euclidean) and orientation (rad) errors of the marker pose predicted with `params` at
    noisy readings of `samples` new random configurations, against the true pose measured with the
    tracker's noise: what a held-out check against the tracker shows."""
    chain, layout, _ = layouts(result.config)
    rng = np.random.default_rng(seed)
    truth = true_parameters(result)
    lo, hi = np.maximum(chain.lower, -np.pi), np.minimum(chain.upper, np.pi)
    pos, rot = [], []
    for q in rng.uniform(lo, hi, (samples, chain.n)):
        T = marker_pose(chain, layout, q, truth)[0]
        measured = gtsam.Pose3(T).compose(gtsam.Pose3.Expmap(rng.normal(0.0, tracker_sigma, 6)))
        predicted = gtsam.Pose3(marker_pose(chain, layout, q + rng.normal(0.0, encoder_sigma, chain.n), params)[0])
        pos.append(np.linalg.norm(predicted.translation() - measured.translation()))
        rot.append(np.linalg.norm(gtsam.Rot3.Logmap(measured.rotation().between(predicted.rotation()))))
    return np.array(pos), np.array(rot)
