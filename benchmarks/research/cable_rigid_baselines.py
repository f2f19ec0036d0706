"""The comparison of thesis Table 4.1: localization error of forward kinematics alone, visual
odometry alone and the fused graph, from one run of a cable-robot config with truth.

- forward kinematics: positions from the encoder readings with the calibrated pulleys and
  offsets, at the orientation the kinematics assumes (identity: the end-effector level);
- visual odometry: the VO increments composed from the first estimated pose at the calibrated
  scale (dead reckoning);
- fused: the graph's estimate.
Errors are position RMSE against the true trajectory at the state times (m).
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import interpolate_poses, nearest, poses_from_array
from fusionkit_plugins.cable_rigid.factors import length_columns
from fusionkit_plugins.cable_rigid.kinematics import forward_kinematics
from fusionkit_plugins.cable_rigid.model import cable_robot


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def dead_reckoned_positions(vo_t: np.ndarray, vo_poses: np.ndarray, t: np.ndarray, start: gtsam.Pose3,
                            scale: float) -> np.ndarray:
    """(K, 3) positions from composing the VO increments between times t (scaled) from `start`."""
    _, arr = interpolate_poses(vo_t, vo_poses, np.clip(t, vo_t[0], vo_t[-1]))
    poses = poses_from_array(arr)
    out, pose = [start.translation()], start
    for a, b in zip(poses[:-1], poses[1:]):
        d = a.between(b)
        pose = pose.compose(gtsam.Pose3(d.rotation(), scale * d.translation()))
        out.append(pose.translation())
    return np.array(out)


def localization_errors(result, robot: str, lengths: str = "lengths", vo: str = "vo",
                        scale: str = "vo_scale") -> dict[str, float]:
    """{"forward_kinematics", "visual_odometry", "fused"}: position RMSE (m) against the truth of
    `robot` in a `fusionkit.pipeline.RunResult` (its streams `lengths` and `vo`)."""
    truth = result.truth.trajectories[robot]
    fused = result.trajectories[robot]
    match = nearest(truth.t, fused.t, 1e-6)
    t, true_pos = fused.t[match.row], truth.pose_array()[match.state, :3]

    desc = result.config.robots[robot].description
    est = result.parameters[robot]
    cdpr = cable_robot(desc)
    stream = result.streams[lengths]
    rows = nearest(t, stream.t, 1e-6)
    z = np.column_stack([stream.column(c) for c in length_columns({}, cdpr.n)])[rows.row]
    fk, _ = forward_kinematics(np.array(est["pulley"].values), np.array(est["offset"].values), cdpr.attachments, z)

    vo_stream = result.streams[vo]
    start = poses_from_array(fused.pose_array()[match.row[:1]])[0]
    dr = dead_reckoned_positions(vo_stream.t, vo_stream.pose_array(), t, start, float(est[scale].values[0]))
    return {"forward_kinematics": _rmse(fk, true_pos[rows.state]),
            "visual_odometry": _rmse(dr, true_pos),
            "fused": _rmse(fused.pose_array()[match.row, :3], true_pos)}
