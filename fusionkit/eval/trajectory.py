"""Trajectory error against ground truth with evo: ATE (optionally SE(3)/Sim(3) aligned) and RPE."""

from __future__ import annotations

import copy

import numpy as np

from ..data.stream import Stream


def _evo(stream: Stream):
    from evo.core.trajectory import PoseTrajectory3D
    a = stream.pose_array()
    return PoseTrajectory3D(positions_xyz=a[:, :3], orientations_quat_wxyz=a[:, [6, 3, 4, 5]],
                            timestamps=stream.t)


def trajectory_errors(estimate: Stream, truth: Stream, align: str = "none",
                      max_time_diff: float = 0.01) -> dict:
    """ATE (translation, m) and RPE per frame (translation m, rotation deg) after associating stamps."""
    from evo.core import metrics, sync
    ref, est = sync.associate_trajectories(_evo(truth), _evo(estimate), max_diff=max_time_diff)
    est = copy.deepcopy(est)
    scale = 1.0
    if align in ("se3", "sim3"):
        _, _, scale = est.align(ref, correct_scale=(align == "sim3"))
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    out = {"matched_poses": int(ref.num_poses), "align": align,
           "ate_rmse_m": float(ape.get_statistic(metrics.StatisticsType.rmse)),
           "ate_mean_m": float(ape.get_statistic(metrics.StatisticsType.mean)),
           "ate_max_m": float(ape.get_statistic(metrics.StatisticsType.max))}
    if align == "sim3":
        out["alignment_scale"] = float(scale)
    if ref.num_poses > 1:
        rpe_t = metrics.RPE(metrics.PoseRelation.translation_part, delta=1, delta_unit=metrics.Unit.frames)
        rpe_t.process_data((ref, est))
        rpe_r = metrics.RPE(metrics.PoseRelation.rotation_angle_deg, delta=1, delta_unit=metrics.Unit.frames)
        rpe_r.process_data((ref, est))
        out["rpe_translation_rmse_m"] = float(rpe_t.get_statistic(metrics.StatisticsType.rmse))
        out["rpe_rotation_rmse_deg"] = float(rpe_r.get_statistic(metrics.StatisticsType.rmse))
    return out


def position_consistency(est_pos: np.ndarray, true_pos: np.ndarray, sigma_pos: np.ndarray) -> dict:
    """Share of per-axis position errors inside 1/2/3 sigma (ideal: 68.3 / 95.4 / 99.7 %)."""
    z = np.abs(est_pos - true_pos) / sigma_pos
    return {axis: {f"{n}sigma": float(np.mean(z[:, i] <= n) * 100) for n in (1, 2, 3)}
            for i, axis in enumerate("xyz"[: z.shape[1]])}
