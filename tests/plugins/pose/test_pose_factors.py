"""Each pose factor type, built from a config, has the residual of its documented model, computed
here by hand with 4x4 matrices; sensor mounts are applied as body_T_sensor; association and
interpolation report what they leave out in `problem.notes`."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

import fusionkit
from fusionkit.graph.variables import POSE3
from fusionkit.pipeline import build_problem, read_sources

RATE = 10.0
N = 20
T = np.arange(N) / RATE
SIGMA = {"rotation": 0.01, "translation": 0.02}
LEVER = np.array([0.10, -0.05, 0.20])
MOUNT_RPY = np.array([0.1, 0.2, -0.3])


def truth_pose(t: float) -> gtsam.Pose3:
    """Position linear in t and rotation at a constant rate about a fixed axis: both exactly
    reproduced by linear/slerp interpolation, so interpolated measurements are exact too."""
    axis = np.array([0.2, -0.1, 1.0]) / np.linalg.norm([0.2, -0.1, 1.0])
    rotation = gtsam.Rot3.RzRyRx(0.3, -0.2, 0.5) * gtsam.Rot3.Expmap(0.8 * t * axis)
    return gtsam.Pose3(rotation, np.array([1.0 + 0.5 * t, -0.3 * t, 2.0 + 0.1 * t]))


TRUTH = [truth_pose(t) for t in T]
EXACT = 1e-7  # residuals at truth: data files hold 9 decimals


def rpy_matrix(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), by hand."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def H(pose: gtsam.Pose3) -> np.ndarray:
    return pose.matrix()


def inv(m: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return out


def log(m: np.ndarray) -> np.ndarray:
    """GTSAM tangent [rotation, translation] of a 4x4 transform."""
    return gtsam.Pose3.Logmap(gtsam.Pose3(m))


def describe(sensors: dict | None = None, parameters: dict | None = None) -> dict:
    return {"name": "rig", "frames": ["world", "body"], "sensors": sensors or {}, "parameters": parameters or {}}


def problem_of(workspace, robots: dict, sources: list, factors: list, initializers: list = ()):
    path = workspace.config({"robots": robots, "sources": sources, "factors": factors,
                             "initializers": list(initializers)})
    config = fusionkit.load_config(path)
    streams, _ = read_sources(config)
    return build_problem(config, streams)


def factors_of(problem, label: str) -> list:
    return [r.factor for r in problem.records if r.label == label]


def values_of(problem, robot: str = "r", poses=TRUTH, extra: dict | None = None) -> gtsam.Values:
    v = gtsam.Values()
    for k, p in enumerate(poses):
        v.insert(problem.states[robot].key(k), p)
    for key, value in (extra or {}).items():
        v.insert(key, value)
    return v


def perturbed(rng, poses, scale=0.05):
    return [p.compose(gtsam.Pose3.Expmap(scale * rng.standard_normal(6))) for p in poses]


# --- pose.absolute and sensor mounts ---------------------------------------------------------------

MARKER = {"type": "mocap_marker", "frame": "body",
          "mount": {"translation": LEVER.tolist(), "rotation_rpy": MOUNT_RPY.tolist()}}


def marker_measurements(rows):
    """world_T_marker by hand: position t + R lever, orientation R R_mount."""
    out = []
    for k in rows:
        R, t = TRUTH[k].rotation().matrix(), TRUTH[k].translation()
        m = np.eye(4)
        m[:3, :3] = R @ rpy_matrix(MOUNT_RPY)
        m[:3, 3] = t + R @ LEVER
        out.append(gtsam.Pose3(m))
    return out


@pytest.fixture
def mocap_problem(workspace):
    rows = np.arange(0, N, 5)
    sources = [workspace.poses("clock", T, TRUTH), workspace.poses("mocap", T[rows], marker_measurements(rows))]
    factors = [{"type": "pose.absolute", "label": "with_mount", "robot": "r", "stream": "mocap", "sensor": "marker",
                "sigma": SIGMA},
               {"type": "pose.absolute", "label": "no_mount", "robot": "r", "stream": "mocap", "sigma": SIGMA}]
    robots = {"r": {"description": describe({"marker": MARKER}), "states": {"stream": "clock"}}}
    return problem_of(workspace, robots, sources, factors), rows


def test_absolute_pose_of_a_mounted_marker_has_the_hand_computed_residual(mocap_problem):
    problem, rows = mocap_problem
    factors = factors_of(problem, "with_mount")
    assert [problem.keys.name_of(f.keys()[0]) for f in factors] == [f"r/pose[{k}]" for k in rows]
    truth = values_of(problem)
    for f in factors:
        assert np.abs(f.unwhitenedError(truth)).max() < EXACT
    # away from truth the residual is Log(prior^-1 x) with prior = the true body pose
    x = perturbed(np.random.default_rng(1), TRUTH)
    values = values_of(problem, poses=x)
    for k, f in zip(rows, factors):
        np.testing.assert_allclose(f.unwhitenedError(values), log(inv(H(TRUTH[k])) @ H(x[k])), atol=EXACT)
        # whitened with the configured sigmas [rot x3, trans x3]
        np.testing.assert_allclose(f.whitenedError(values), log(inv(H(TRUTH[k])) @ H(x[k])) /
                                   np.array([0.01] * 3 + [0.02] * 3), atol=EXACT / 0.01)


def test_the_mount_maps_the_marker_pose_to_the_body_pose(mocap_problem):
    """With `sensor: marker` the prior is on world_T_body = world_T_marker marker_T_body; without
    it, on the marker pose itself, off by the lever arm (R lever) and the mount rotation."""
    problem, rows = mocap_problem
    for k, with_mount, without in zip(rows, factors_of(problem, "with_mount"), factors_of(problem, "no_mount")):
        np.testing.assert_allclose(with_mount.prior().matrix(), H(TRUTH[k]), atol=EXACT)
        marker = without.prior()
        R = TRUTH[k].rotation().matrix()
        np.testing.assert_allclose(marker.translation() - TRUTH[k].translation(), R @ LEVER, atol=EXACT)
        np.testing.assert_allclose(marker.rotation().matrix(), R @ rpy_matrix(MOUNT_RPY), atol=EXACT)


def test_mounted_marker_run_recovers_the_body_trajectory_to_1e_6(workspace):
    """End to end on noise-free data: odometry + mocap of a marker with a lever arm give the
    body trajectory (not the marker's) to numerical precision."""
    rows = np.arange(0, N, 5)
    sources = [workspace.poses("odom", T, [TRUTH[0].between(p) for p in TRUTH]),
               workspace.poses("mocap", T[rows], marker_measurements(rows)),
               workspace.poses("truth", T, TRUTH)]
    robots = {"r": {"description": describe({"marker": MARKER}), "states": {"stream": "odom"}}}
    config = {"robots": robots, "sources": sources[:2],
              "factors": [{"type": "pose.relative", "robot": "r", "stream": "odom", "sigma": SIGMA},
                          {"type": "pose.absolute", "robot": "r", "stream": "mocap", "sensor": "marker",
                           "sigma": SIGMA}],
              "initializers": [{"type": "pose.dead_reckoning", "robot": "r", "stream": "odom"}],
              "truth": {"trajectories": {"r": "truth.tum"}}}
    result = fusionkit.run(workspace.config(config))
    assert result.evaluation["trajectories"]["r"]["ate_rmse_m"] < 1e-6
    est = result.trajectories["r"].poses()
    for p, q in zip(est, TRUTH):
        assert np.abs(POSE3.local(q, p)).max() < 1e-6


def test_planar_mounted_marker_residual_vanishes_at_truth_with_x_y_theta_sigmas(workspace):
    """Pose2 states: the body pose (x, y, yaw) from the marker pose and its lever arm."""
    yaw = 0.4 + 0.3 * T
    body = [gtsam.Pose3(gtsam.Rot3.Yaw(a), np.array([np.cos(a), np.sin(a), 0.0])) for a in yaw]
    lever = np.array([0.3, 0.1, 0.5])
    marker = [gtsam.Pose3(p.rotation(), p.translation() + p.rotation().matrix() @ lever) for p in body]
    sources = [workspace.poses("clock", T, body), workspace.poses("mocap", T, marker)]
    sensors = {"marker": {"type": "mocap_marker", "mount": {"translation": lever.tolist()}}}
    robots = {"r": {"description": describe(sensors), "states": {"stream": "clock", "type": "pose2"}}}
    problem = problem_of(workspace, robots, sources, [{"type": "pose.absolute", "robot": "r", "stream": "mocap",
                                                       "sensor": "marker", "sigma": SIGMA}])
    v = gtsam.Values()
    for k, a in enumerate(yaw):
        v.insert(problem.states["r"].key(k), gtsam.Pose2(np.cos(a), np.sin(a), a))
    factors = [r.factor for r in problem.records]
    assert len(factors) == N
    for f in factors:
        assert f.dim() == 3
        assert np.abs(f.unwhitenedError(v)).max() < EXACT
        # planar sigmas are [x, y, theta]
        np.testing.assert_allclose(np.asarray(f.noiseModel().sigmas()), [0.02, 0.02, 0.01])


# --- pose.origin -----------------------------------------------------------------------------------

def test_origin_prior_initializes_the_first_pose_and_has_the_hand_computed_residual(workspace):
    start = [1.0, 2.0, 3.0, 0.0, 0.0, float(np.sin(0.25)), float(np.cos(0.25))]  # yaw 0.5 rad
    problem = problem_of(workspace, {"r": {"description": describe(), "states": {"stream": "clock"}}},
                         [workspace.poses("clock", T, TRUTH)],
                         [{"type": "pose.origin", "robot": "r", "sigma": SIGMA, "pose": start}])
    (f,) = [r.factor for r in problem.records]
    key = problem.states["r"].key(0)
    assert list(f.keys()) == [key]
    expected = gtsam.Pose3(gtsam.Rot3.Yaw(0.5), np.array([1.0, 2.0, 3.0]))
    assert problem.initial.atPose3(key).equals(expected, 1e-12)
    x = gtsam.Pose3(gtsam.Rot3.Yaw(0.6), np.array([1.0, 2.5, 3.0]))
    v = gtsam.Values()
    v.insert(key, x)
    np.testing.assert_allclose(f.unwhitenedError(v), log(inv(H(expected)) @ H(x)), atol=1e-12)


# --- pose.relative ---------------------------------------------------------------------------------

def odometry_of_mounted_sensor(times, mount: gtsam.Pose3, odom_frame: gtsam.Pose3):
    """odom_T_sensor(t) = odom_T_world world_T_body(t) body_T_sensor."""
    return [gtsam.Pose3(inv(H(odom_frame)) @ H(truth_pose(t)) @ H(mount)) for t in times]


def test_relative_pose_from_mounted_sensors_has_the_hand_computed_body_increments(workspace):
    """Odometry of a sensor in its own odometry frame gives body increments
    mount (s_a^-1 s_b) mount^-1 = x_a^-1 x_b: `cam` (rotated and offset) at the state times, and
    `imu` (rotated) at 40 Hz, never at a state time, interpolated (exact for this motion)."""
    odom_frame = gtsam.Pose3(gtsam.Rot3.Yaw(1.0), np.array([5.0, -2.0, 0.3]))
    cam = gtsam.Pose3(gtsam.Rot3.RzRyRx(*MOUNT_RPY), LEVER)
    imu = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.3, -0.1, 0.2), np.zeros(3))
    t_imu = np.arange(-0.0125, T[-1] + 0.03, 0.025)
    sources = [workspace.poses("cam_odom", T, odometry_of_mounted_sensor(T, cam, odom_frame)),
               workspace.poses("imu_odom", t_imu, odometry_of_mounted_sensor(t_imu, imu, odom_frame))]
    sensors = {"cam": {"type": "camera", "mount": {"translation": LEVER.tolist(), "rotation_rpy": MOUNT_RPY.tolist()}},
               "imu": {"type": "imu", "mount": {"rotation_rpy": [0.3, -0.1, 0.2]}}}
    problem = problem_of(workspace, {"r": {"description": describe(sensors), "states": {"stream": "cam_odom"}}},
                         sources,
                         [{"type": "pose.relative", "label": label, "robot": "r", "stream": f"{label}_odom",
                           "sensor": label, "sigma": SIGMA} for label in ("cam", "imu")])
    assert problem.notes == []
    truth = values_of(problem)
    x = perturbed(np.random.default_rng(2), TRUTH)
    values = values_of(problem, poses=x)
    for label in ("cam", "imu"):
        factors = factors_of(problem, label)
        assert len(factors) == N - 1
        for k, f in enumerate(factors, start=1):
            assert [problem.keys.name_of(key) for key in f.keys()] == [f"r/pose[{k - 1}]", f"r/pose[{k}]"]
            assert np.abs(f.unwhitenedError(truth)).max() < EXACT
            z = inv(H(TRUTH[k - 1])) @ H(TRUTH[k])
            np.testing.assert_allclose(f.unwhitenedError(values), log(inv(z) @ inv(H(x[k - 1])) @ H(x[k])),
                                       atol=EXACT)


def test_relative_pose_skips_gaps_and_states_outside_the_stream(workspace):
    """Odometry samples 20 ms before states 3-9 and 13-19: states 0-2 and 19 lie outside the
    stream, states 9-12 inside a 0.4 s gap (max_gap 0.15 s); no factor touches them."""
    keep = (T >= 0.3) & ((T < 0.95) | (T > 1.25))
    t_odom = T[keep] - 0.02
    sources = [workspace.poses("clock", T, TRUTH),
               workspace.poses("odom", t_odom, [truth_pose(t) for t in t_odom])]
    problem = problem_of(workspace, {"r": {"description": describe(), "states": {"stream": "clock"}}}, sources,
                         [{"type": "pose.relative", "label": "odo", "robot": "r", "stream": "odom", "sigma": SIGMA,
                           "max_gap": 0.15}])
    pairs = [tuple(problem.keys.decode(k)[1] for k in r.factor.keys()) for r in problem.records]
    assert pairs == [(k, k + 1) for k in range(3, 8)] + [(k, k + 1) for k in range(13, 18)]
    assert problem.notes == [f"odo: 8 of {N} states of 'r' lie outside stream 'odom' (or across a gap) and get no "
                             "factor from it"]


def test_a_state_on_the_first_sample_after_a_gap_keeps_its_odometry(workspace):
    """States clocked by the odometry stream itself: the state on the first sample after the gap
    is a measured pose (no interpolation), so odometry resumes from it."""
    keep = (T < 0.95) | (T > 1.25)  # samples at states 0-9 and 13-19
    sources = [workspace.poses("odom", T[keep], [p for p, k in zip(TRUTH, keep) if k])]
    problem = problem_of(workspace, {"r": {"description": describe(), "states": {"stream": "odom"}}}, sources,
                         [{"type": "pose.relative", "robot": "r", "stream": "odom", "sigma": SIGMA, "max_gap": 0.15}])
    pairs = [tuple(problem.keys.decode(k)[1] for k in r.factor.keys()) for r in problem.records]
    # states index the kept samples: 0-9 before the gap, 10-16 after it
    assert pairs == [(k, k + 1) for k in range(0, 9)] + [(k, k + 1) for k in range(10, 16)]


# --- pose.scaled_relative --------------------------------------------------------------------------

def test_scaled_relative_pose_residual_matches_the_hand_computed_one_in_vo_units(workspace):
    scale = 2.5
    vo = [gtsam.Pose3(p.rotation(), p.translation() / scale) for p in TRUTH]  # VO reports t / s
    params = {"vo_scale": {"type": "scalar", "value": 1.0, "sigma": 10.0}}
    problem = problem_of(workspace, {"r": {"description": describe(parameters=params), "states": {"stream": "vo"}}},
                         [workspace.poses("vo", T, vo)],
                         [{"type": "pose.scaled_relative", "label": "vo", "robot": "r", "stream": "vo",
                           "scale": "vo_scale", "sigma": SIGMA}])
    s_key = problem.keys.get("r", "vo_scale").key(0)
    assert problem.keys.name_of(s_key) == "r/vo_scale"
    factors = factors_of(problem, "vo")
    assert len(factors) == N - 1
    prior = factors_of(problem, "prior:r/vo_scale")
    assert len(prior) == 1
    truth = values_of(problem, extra={s_key: scale})
    for f in factors:
        assert list(f.keys())[2] == s_key
        assert np.abs(f.unwhitenedError(truth)).max() < EXACT
    # at a wrong scale s' and perturbed poses, in VO units: e = Log( z^-1 B_s ), B_s = (R_B, t_B / s')
    s_wrong = 2.2
    x = perturbed(np.random.default_rng(3), TRUTH)
    values = values_of(problem, poses=x, extra={s_key: s_wrong})
    for k, f in enumerate(factors, start=1):
        z = inv(H(vo[k - 1])) @ H(vo[k])
        b = inv(H(x[k - 1])) @ H(x[k])
        b[:3, 3] /= s_wrong
        np.testing.assert_allclose(f.unwhitenedError(values), log(inv(z) @ b), atol=EXACT)
    # the prior on the scale: (s - 1) / 10
    np.testing.assert_allclose(prior[0].whitenedError(values), [(s_wrong - 1.0) / 10.0], atol=1e-12)


# --- pose.co_registration --------------------------------------------------------------------------

def test_co_registration_residual_matches_the_hand_computed_one(workspace):
    base = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.05, -0.02, 0.7), np.array([2.0, -1.0, 0.1]))  # worldA_T_baseB
    b_world = [gtsam.Pose3(gtsam.Rot3.Yaw(-0.5 * t), np.array([3.0 - t, 1.0, 0.0])) for t in T]
    b = [base.between(p) for p in b_world]
    rows = np.arange(0, N, 4)
    z = [TRUTH[k].between(b_world[k]) for k in rows]
    sources = [workspace.poses("a_clock", T, TRUTH), workspace.poses("b_clock", T, b),
               workspace.poses("a_sees_b", T[rows], z)]
    robots = {n: {"description": describe(), "states": {"stream": f"{n}_clock"}} for n in ("a", "b")}
    problem = problem_of(workspace, robots, sources,
                         [{"type": "pose.co_registration", "label": "seen", "robot": "a", "other": "b",
                           "stream": "a_sees_b", "sigma": SIGMA,
                           "base_sigma": {"rotation": 0.5, "translation": 2.0}}])
    w_key = problem.keys.get("b", "base_in_a").key(0)
    assert problem.keys.name_of(w_key) == "b/base_in_a"
    assert len(factors_of(problem, "prior:b/base_in_a")) == 1
    factors = factors_of(problem, "seen")
    assert len(factors) == len(rows)

    def values(a_poses, w, b_poses):
        v = values_of(problem, "a", a_poses)
        for k, p in enumerate(b_poses):
            v.insert(problem.states["b"].key(k), p)
        v.insert(w_key, w)
        return v

    truth = values(TRUTH, base, b)
    for f in factors:
        assert np.abs(f.unwhitenedError(truth)).max() < EXACT
    rng = np.random.default_rng(4)
    xa, xb = perturbed(rng, TRUTH), perturbed(rng, b)
    w = base.compose(gtsam.Pose3.Expmap(0.1 * rng.standard_normal(6)))
    v = values(xa, w, xb)
    for k, zk, f in zip(rows, z, factors):
        assert list(f.keys()) == [problem.states["a"].key(k), w_key, problem.states["b"].key(k)]
        expected = log(inv(H(zk)) @ inv(H(xa[k])) @ H(w) @ H(xb[k]))
        np.testing.assert_allclose(f.unwhitenedError(v), expected, atol=EXACT)


# --- parameter.random_walk -------------------------------------------------------------------------

def test_random_walk_noise_grows_with_the_square_root_of_dt(workspace):
    t = np.array([0.0, 0.1, 0.3, 0.7, 1.5])
    params = {"drift": {"type": "point2", "value": [0.5, -0.5], "sigma": [0.2, 0.3], "time_varying": True}}
    problem = problem_of(workspace, {"r": {"description": describe(parameters=params), "states": {"stream": "clock"}}},
                         [workspace.columns("clock", t, dummy=np.zeros(len(t)))],
                         [{"type": "parameter.random_walk", "label": "walk", "robot": "r", "parameter": "drift",
                           "sigma": 0.05}])
    fam = problem.keys.get("r", "drift")
    assert [problem.keys.name_of(fam.key(k)) for k in (0, 4)] == ["r/drift[0]", "r/drift[4]"]
    walk = factors_of(problem, "walk")
    assert len(walk) == len(t) - 1
    (prior,) = factors_of(problem, "prior:r/drift")
    assert list(prior.keys()) == [fam.key(0)]
    np.testing.assert_allclose(np.asarray(prior.noiseModel().sigmas()), [0.2, 0.3])
    p = [np.array([0.5, -0.5]) + 0.1 * k * np.array([1.0, 2.0]) for k in range(len(t))]
    v = gtsam.Values()
    for k, pk in enumerate(p):
        v.insert(fam.key(k), pk)
    for k, f in enumerate(walk, start=1):
        dt = t[k] - t[k - 1]
        np.testing.assert_allclose(f.whitenedError(v), (p[k] - p[k - 1]) / (0.05 * np.sqrt(dt)), rtol=1e-9)
    assert [problem.key_time[fam.key(k)] for k in range(len(t))] == list(t)


# --- association notes -----------------------------------------------------------------------------

def test_association_keeps_samples_within_tolerance_and_notes_the_3_dropped(workspace):
    t_mocap = np.array([0.0, 0.202, 0.5, 0.71, 1.0, 1.3004, 2.5, 5.0])  # 0.71, 2.5 (after the last state) and 5.0 miss
    sources = [workspace.poses("clock", T, TRUTH),
               workspace.poses("mocap", t_mocap, [truth_pose(t) for t in t_mocap])]
    problem = problem_of(workspace, {"r": {"description": describe(), "states": {"stream": "clock"}}}, sources,
                         [{"type": "pose.absolute", "label": "mocap", "robot": "r", "stream": "mocap",
                           "sigma": SIGMA, "tolerance": 0.005}])
    assert sorted(problem.keys.decode(r.factor.keys()[0])[1] for r in problem.records) == [0, 2, 5, 10, 13]
    assert problem.notes == ["mocap: 3 of 8 samples of stream 'mocap' had no state within 0.005 s and were not used"]


def test_no_notes_when_every_sample_is_used(mocap_problem):
    problem, _ = mocap_problem
    assert problem.notes == []
