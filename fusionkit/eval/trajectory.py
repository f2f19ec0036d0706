"""Trajectory error against ground truth with evo: ATE (optionally SE(2)/SE(3)/Sim(3) aligned) and RPE."""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from ..data.association import nearest
from ..data.stream import Stream

MATCH_TOLERANCE = 0.01  # s: a truth pose is compared with the state nearest in time, when at most this far


@dataclass
class MatchedPositions:
    """Estimated and true positions (m, world axes) at the states that have a truth pose, in time order."""

    t: np.ndarray  # (n,) state times (s)
    estimate: np.ndarray  # (n, d): d = 3, or 2 (x, y) for planar robots
    truth: np.ndarray  # (n, d)
    sigma: np.ndarray | None  # (n, d) 1-sigma of the estimate, when computed

    @property
    def error(self) -> np.ndarray:
        return self.estimate - self.truth


def matched_positions(estimate: Stream, truth: Stream, sigma: np.ndarray | None = None) -> MatchedPositions:
    """Pair each truth pose with the nearest state within MATCH_TOLERANCE; `sigma` (one row per state
    of `estimate`) sets the axes compared: its columns (x, y for planar robots), else x, y, z. `estimate`:
    poses, or positions (columns x, y, z)."""
    a = nearest(truth.t, estimate.t, MATCH_TOLERANCE)
    d = 3 if sigma is None else sigma.shape[1]
    position = np.column_stack([estimate.column(c) for c in "xyz"[:d]])
    return MatchedPositions(estimate.t[a.row], position[a.row], truth.pose_array()[a.state, :d],
                            None if sigma is None else sigma[a.row])


@dataclass(frozen=True)
class Alignment:
    """x_truth = scale R x_estimate + t (world frames; R about z only for se2)."""

    R: np.ndarray
    t: np.ndarray
    scale: float = 1.0

    def apply(self, points: np.ndarray) -> np.ndarray:
        return self.scale * np.asarray(points, float) @ self.R.T + self.t

    def matrix(self) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = self.scale * self.R, self.t
        return out


def fit_alignment(estimate: np.ndarray, truth: np.ndarray, kind: str) -> Alignment:
    """The least-squares alignment (Umeyama) of estimated onto true positions (n, 3): `se2` a rotation about
    z and a translation in x, y (planar robots: no tilt fitted to noise), `se3`, or `sim3` (with scale)."""
    from evo.core.geometry import umeyama_alignment
    if kind == "se2":
        r, t, _ = umeyama_alignment(estimate[:, :2].T, truth[:, :2].T)
        R = np.eye(3)
        R[:2, :2] = r
        return Alignment(R, np.r_[t, 0.0])
    r, t, c = umeyama_alignment(estimate.T, truth.T, with_scale=(kind == "sim3"))
    return Alignment(r, t, float(c))


def _evo(stream: Stream):
    from evo.core.trajectory import PoseTrajectory3D
    a = stream.pose_array()
    return PoseTrajectory3D(positions_xyz=a[:, :3], orientations_quat_wxyz=a[:, [6, 3, 4, 5]],
                            timestamps=stream.t)


def trajectory_errors(estimate: Stream, truth: Stream, align: str = "none",
                      max_time_diff: float = MATCH_TOLERANCE) -> dict:
    """ATE (translation, m) and RPE per frame (translation m, rotation deg) after associating stamps."""
    from evo.core import metrics, sync
    ref, est = sync.associate_trajectories(_evo(truth), _evo(estimate), max_diff=max_time_diff)
    est = copy.deepcopy(est)
    scale = 1.0
    if align == "se2":
        est.transform(fit_alignment(est.positions_xyz, ref.positions_xyz, "se2").matrix())
    elif align in ("se3", "sim3"):
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
        translation, angle = relative_pose_errors(np.asarray(ref.poses_se3), np.asarray(est.poses_se3))
        out["rpe_translation_rmse_m"] = float(np.sqrt(np.mean(translation ** 2)))
        out["rpe_rotation_rmse_deg"] = float(np.degrees(np.sqrt(np.mean(angle ** 2))))
    return out


def relative_pose_errors(truth: np.ndarray, estimate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame RPE (evo's RPE with delta = 1 frame, as in the TUM RGB-D benchmark) of (n, 4, 4) pose
    matrices: E_i = (Q_i^-1 Q_i+1)^-1 (P_i^-1 P_i+1); its translation norm (m) and rotation angle (rad),
    for all i at once (evo loops over the pairs in Python: 76 ms per trajectory, measured in the tests)."""
    def steps(T):
        R, t = T[:, :3, :3], T[:, :3, 3]
        return np.einsum("nji,njk->nik", R[:-1], R[1:]), np.einsum("nji,nj->ni", R[:-1], t[1:] - t[:-1])
    (Rq, tq), (Rp, tp) = steps(truth), steps(estimate)
    R = np.einsum("nji,njk->nik", Rq, Rp)
    translation = np.linalg.norm(np.einsum("nji,nj->ni", Rq, tp - tq), axis=1)
    axis = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1)
    angle = np.arctan2(0.5 * np.linalg.norm(axis, axis=1), 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0))
    return translation, angle


def position_consistency(est_pos: np.ndarray, true_pos: np.ndarray, sigma_pos: np.ndarray) -> dict:
    """Share of per-axis position errors inside 1/2/3 sigma (ideal: 68.3 / 95.4 / 99.7 %)."""
    z = np.abs(est_pos - true_pos) / sigma_pos
    return {axis: {f"{n}sigma": float(np.mean(z[:, i] <= n) * 100) for n in (1, 2, 3)}
            for i, axis in enumerate("xyz"[: z.shape[1]])}
