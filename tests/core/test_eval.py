"""Trajectory errors (ATE with and without alignment, RPE) and sigma consistency, on known cases."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.data.stream import pose_array_from, pose_stream
from fusionkit.eval.trajectory import fit_alignment, position_consistency, relative_pose_errors, trajectory_errors


def _circle(n: int = 200):
    t = np.linspace(0, 20, n)
    poses = [gtsam.Pose3(gtsam.Rot3.Yaw(a), np.array([np.cos(a) * 3, np.sin(a) * 3, 0.1 * a]))
             for a in t * 0.3]
    return t, poses


def test_ate_of_constant_offset_equals_offset_and_vanishes_after_se3_alignment():
    t, poses = _circle()
    truth = pose_stream("truth", t, poses)
    offset = gtsam.Pose3(gtsam.Rot3.Yaw(0.2), np.array([0.3, -0.4, 0.0]))  # rigid motion of the whole path
    moved = pose_stream("est", t, [offset.compose(p) for p in poses])
    shifted = pose_stream("est", t, pose_array_from(poses) + np.array([0.3, 0.4, 0.0, 0, 0, 0, 0]))
    assert abs(trajectory_errors(shifted, truth)["ate_rmse_m"] - 0.5) < 1e-9
    assert trajectory_errors(moved, truth)["ate_rmse_m"] > 0.3
    assert trajectory_errors(moved, truth, align="se3")["ate_rmse_m"] < 1e-9


def test_sim3_alignment_recovers_a_scale_of_2_5_and_zero_ate():
    t, poses = _circle()
    truth = pose_stream("truth", t, poses)
    arr = pose_array_from(poses)
    arr[:, :3] *= 0.4
    out = trajectory_errors(pose_stream("est", t, arr), truth, align="sim3")
    assert out["ate_rmse_m"] < 1e-9
    assert abs(out["alignment_scale"] - 2.5) < 1e-9


def test_se2_alignment_undoes_a_planar_motion_and_fits_no_tilt_to_height_noise():
    """A planar path turned 0.7 rad about z and moved in x, y: SE(2) alignment brings the ATE to 0; with
    heights that are pure noise (a planar robot's z) it fits a rotation about z only, where SE(3) tilts."""
    rng = np.random.default_rng(2)
    t = np.linspace(0, 20, 200)
    xy = np.column_stack([3 * np.cos(0.3 * t), 1.5 * np.sin(0.6 * t)])
    truth = np.column_stack([xy, rng.normal(0, 0.05, len(t))])
    c, s_ = np.cos(0.7), np.sin(0.7)
    moved = np.column_stack([xy @ np.array([[c, s_], [-s_, c]]) + [1.0, -2.0], rng.normal(0, 0.05, len(t))])
    planar = fit_alignment(moved, truth, "se2")
    assert np.allclose(planar.apply(moved)[:, :2], xy, atol=1e-9) and planar.R[2, 2] == 1.0
    assert fit_alignment(moved, truth, "se3").R[2, 2] < 1.0 - 1e-6  # SE(3) fits a tilt to the noise
    poses = lambda p: pose_stream("p", t, [gtsam.Pose3(gtsam.Rot3(), q) for q in p])  # noqa: E731
    assert trajectory_errors(poses(moved), poses(np.column_stack([xy, moved[:, 2]])), align="se2")["ate_rmse_m"] < 1e-9


def test_rpe_of_one_10_cm_step_is_its_share_of_49_steps():
    t, poses = _circle(50)
    truth = pose_stream("truth", t, poses)
    arr = pose_array_from(poses)
    arr[25:, 0] += 0.1  # one jump of 10 cm between frames 24 and 25
    out = trajectory_errors(pose_stream("est", t, arr), truth)
    # 49 relative steps, one of which is off by 0.1 m (in the body frame: same norm)
    assert abs(out["rpe_translation_rmse_m"] - np.sqrt(0.1 ** 2 / 49)) < 1e-9
    assert out["rpe_rotation_rmse_deg"] < 1e-6


def test_relative_pose_errors_equal_evos_rpe_per_frame_to_1e_12_on_random_3d_paths():
    """The vectorized per-frame RPE against evo's own (its RPE with delta 1 frame, translation part and
    rotation angle), on random poses with turns up to 180 degrees between frames."""
    from evo.core import metrics
    from evo.core.trajectory import PosePath3D
    rng = np.random.default_rng(4)

    def path(n):
        return [gtsam.Pose3(gtsam.Rot3.Expmap(rng.uniform(-1.8, 1.8, 3)), rng.normal(0, 2, 3)).matrix() for _ in range(n)]
    truth, estimate = path(60), path(60)
    translation, angle = relative_pose_errors(np.array(truth), np.array(estimate))
    for relation, ours in ((metrics.PoseRelation.translation_part, translation),
                           (metrics.PoseRelation.rotation_angle_deg, np.degrees(angle))):
        rpe = metrics.RPE(relation, delta=1, delta_unit=metrics.Unit.frames)
        rpe.process_data((PosePath3D(poses_se3=truth), PosePath3D(poses_se3=estimate)))
        assert np.max(np.abs(rpe.error - ours)) < 1e-12 * max(1.0, np.max(ours))


def test_gaussian_errors_fall_within_1_2_3_sigma_at_68_95_99_7_percent():
    rng = np.random.default_rng(0)
    sigma = rng.uniform(0.01, 0.1, size=(20000, 3))
    truth = rng.normal(size=(20000, 3))
    est = truth + rng.standard_normal((20000, 3)) * sigma
    c = position_consistency(est, truth, sigma)
    for axis in "xyz":
        assert abs(c[axis]["1sigma"] - 68.27) < 1.5
        assert abs(c[axis]["2sigma"] - 95.45) < 0.8
        assert abs(c[axis]["3sigma"] - 99.73) < 0.3
    over = position_consistency(est, truth, sigma / 2)  # over-confident sigmas show up
    assert over["x"]["1sigma"] < 45
