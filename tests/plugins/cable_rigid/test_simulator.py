"""Simulator `cable.cdpr` (docs/models/cable_rigid.md, ARAS-CAM): the streams agree with the measurement
models at truth to the noise level, the trajectory moves along x, then y, then z inside the
workspace, dynamic motion swings where the encoders cannot see it, and the written dataset's
config runs and recovers the pulleys and the VO scale."""

from __future__ import annotations


import gtsam
import numpy as np
import pytest
import yaml

import fusionkit
from fusionkit.cli.main import main
from fusionkit.api import robot_description_data
from fusionkit.data.stream import poses_from_array
from fusionkit_plugins.cable_rigid.simulators import (CdprSimulator, Geometry, commanded_trajectory,
                                                     encoder_readings, gravity_wrench, nominal_geometry,
                                                     wrench_matrix)
from fusionkit_plugins.cable_rigid.kinematics import forward_kinematics

SIM = CdprSimulator()
SEED = 0


def simulate(**params):
    p = SIM._params(params)
    return p, SIM.simulate(p, np.random.default_rng(SEED))


@pytest.fixture(scope="module")
def smooth():
    return simulate()


@pytest.fixture(scope="module")
def dynamic():
    return simulate(motion="dynamic")


def true_geometry(params: dict, out) -> Geometry:
    nominal = nominal_geometry(robot_description_data(params["robot"]))
    pulleys = np.array(out.truth_calibration["cdpr"]["pulley"]["values"])
    return Geometry(pulleys, nominal.attachments, nominal.stiffness_EA, nominal.mass, nominal.com)


def pose_arrays(stream) -> tuple[np.ndarray, np.ndarray]:
    arr = stream.pose_array()
    return arr[:, :3], np.array([p.rotation().matrix() for p in poses_from_array(arr)])


def model_lengths(geo: Geometry, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    return np.linalg.norm(geo.pulleys[None] - pos[:, None] - np.einsum("kij,cj->kci", rot, geo.attachments), axis=2)


# ------------------------------------------------------------------------------------- the streams
def test_streams_have_750_samples_their_columns_and_truth_pulleys_5_cm_off_nominal(smooth):
    params, out = smooth
    assert set(out.streams) == set(SIM.stream_columns(params)) == {"vo", "lengths", "tensions", "mocap"}
    for name, cols in SIM.stream_columns(params).items():
        assert out.streams[name].columns == cols
        assert len(out.streams[name]) == 750  # 25 s at 30 Hz
    assert out.streams["lengths"].columns == ("l0", "l1", "l2", "l3")
    assert out.streams["tensions"].columns == ("T0", "T1", "T2", "T3")
    cal = out.truth_calibration["cdpr"]
    assert cal["vo_scale"]["value"] == 2.0
    nominal = np.array(robot_description_data("arascam")["parameters"]["pulley"]["values"])
    error = np.array(cal["pulley"]["values"]) - nominal
    assert 0.02 < error.std() < 0.08 and np.abs(error).max() < 0.2  # pulley_error 0.05 m per axis
    assert out.truth_trajectories["cdpr"].pose_array()[0] == pytest.approx(SIM.home_pose(params))


@pytest.mark.parametrize("robot", ["arascam", "cdpr_small"])
def test_encoders_match_the_model_at_truth_to_their_noise_within_20_percent(robot):
    """z_i = (1 - T_i/EA) l*_i + l0_i + noise (arascam, EA = 2e4 N) or l*_i + l0_i + noise
    (cdpr_small, no stiffness): residual std within 20% of encoder_sigma (measured: -0.5%)."""
    params, out = simulate(robot=robot)
    geo = true_geometry(params, out)
    pos, rot = pose_arrays(out.truth_trajectories["cdpr"])
    offsets = np.array(out.truth_calibration["cdpr"]["offset"]["values"])
    tensions = out.streams["tensions"].values  # measured: quantized, the stretch error is ~20 um
    z = out.streams["lengths"].values
    residual = z - encoder_readings(model_lengths(geo, pos, rot), tensions, offsets, geo.stiffness_EA)
    assert abs(residual.std() / params["encoder_sigma"] - 1) < 0.2
    assert np.abs(residual.mean(axis=0)).max() < 3 * params["encoder_sigma"] / np.sqrt(750) + 1e-4
    # relative encoders zeroed at home: the first readings are 0 up to noise
    assert np.abs(z[0]).max() < 4 * params["encoder_sigma"]
    rigid = z - model_lengths(geo, pos, rot) - offsets
    if robot == "arascam":  # the stretch T l*/EA (about 1.5 mm) is visible against a rigid model
        assert np.abs(rigid - residual).mean() > 0.5e-3
    else:
        np.testing.assert_allclose(rigid, residual, rtol=0, atol=1e-12)


def test_tensions_balance_gravity_and_are_quantized(smooth):
    """Static equilibrium J^T T = -w_gravity (NNLS for 4 cables, 6 equations), quantized to
    0.25 N: the force residual is a few % of m g (measured max 2.8%, mean 1.2%); torque is not
    exactly balanced at the prescribed orientation (max 2.4 N m, the least-squares compromise)."""
    params, out = smooth
    geo = true_geometry(params, out)
    pos, rot = pose_arrays(out.truth_trajectories["cdpr"])
    tensions = out.streams["tensions"].values
    assert tensions.min() >= 0 and tensions.min() > 0  # all cables taut
    steps = tensions / params["tension_resolution"]
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    wrench = np.einsum("kij,kj->ki", wrench_matrix(pos, rot, geo), tensions) + gravity_wrench(rot, geo)
    mg = geo.mass * 9.81
    force = np.linalg.norm(wrench[:, :3], axis=1)
    assert force.max() < 0.05 * mg
    assert force.mean() < 0.02 * mg
    # the vertical balance: the tensions carry the weight
    assert np.median(np.einsum("kij,kj->ki", wrench_matrix(pos, rot, geo)[:, :3], tensions)[:, 2]) \
        == pytest.approx(mg, rel=0.02)


def vo_increment_errors(vo, truth, scale: float) -> np.ndarray:
    """Log(true increment^-1 * scaled VO increment) per frame: [rotation (rad), translation (m)]."""
    v, tr = vo.poses(), truth.poses()
    errors = []
    for k in range(1, len(v)):
        d = v[k - 1].between(v[k])
        scaled = gtsam.Pose3(d.rotation(), scale * d.translation())
        errors.append(gtsam.Pose3.Logmap(tr[k - 1].between(tr[k]).between(scaled)))
    return np.array(errors)


@pytest.mark.parametrize("motion", ["smooth", "dynamic"])
def test_vo_increments_times_scale_match_the_truth_to_their_sigma_within_10_percent(motion, smooth, dynamic):
    params, out = smooth if motion == "smooth" else dynamic
    vo, truth = out.streams["vo"], out.truth_trajectories["cdpr"]
    assert vo.pose_array()[0] == pytest.approx([0, 0, 0, 0, 0, 0, 1])  # VO's own frame
    err = vo_increment_errors(vo, truth, params["scale"])
    factor = params["dynamic_vo_factor"] if motion == "dynamic" else 1.0
    sigma = np.array([params["vo_sigma"]["rotation"]] * 3 + [params["vo_sigma"]["translation"]] * 3) * factor
    sigma[3:] *= params["scale"]  # translation noise is drawn in VO units; the errors here are metric
    np.testing.assert_allclose(err.std(axis=0) / sigma, 1, atol=0.1)  # 749 samples: std known to 3%
    assert np.all(np.abs(err.mean(axis=0)) < 4 * sigma / np.sqrt(len(err)))
    # the VO reports translation / scale: its path is half as long as the true one, less the length the
    # per-frame noise adds (2 VO-units per axis per frame: about 5%; dynamic, 2.5 times more: 15%)
    length = [np.linalg.norm(np.diff(x.pose_array()[:, :3], axis=0), axis=1).sum() for x in (vo, truth)]
    assert length[1] / length[0] == pytest.approx(params["scale"], rel=0.07 if motion == "smooth" else 0.2)


def test_mocap_is_the_true_pose_with_its_sigmas_within_10_percent(smooth):
    params, out = smooth
    mocap, truth = out.streams["mocap"].poses(), out.truth_trajectories["cdpr"].poses()
    err = np.array([gtsam.Pose3.Logmap(t.between(m)) for t, m in zip(truth, mocap)])
    np.testing.assert_allclose(err[:, :3].std(), params["mocap_sigma"]["rotation"], rtol=0.1)
    np.testing.assert_allclose(err[:, 3:].std(), params["mocap_sigma"]["translation"], rtol=0.1)


# ---------------------------------------------------------------------------------- the trajectory
def test_trajectory_moves_along_x_then_y_then_z_inside_the_workspace(smooth):
    params, out = smooth
    desc = robot_description_data("arascam")
    geo = nominal_geometry(desc)
    truth = out.truth_trajectories["cdpr"]
    t, arr = truth.t, truth.pose_array()
    pos = arr[:, :3]
    home = np.array(SIM.home_pose(params)[:3])
    assert home[:2] == pytest.approx([0, 0])
    # home: nominal cable lengths match the description's nominal offsets (-2.9 m)
    assert np.linalg.norm(geo.pulleys - home - geo.attachments, axis=1) == pytest.approx([2.9] * 4)
    # below the pulleys (>= 0.5 m), inside the footprint with a 0.5 m margin
    top = pos[:, 2] + geo.attachments[:, 2].max()
    assert top.max() < geo.pulleys[:, 2].min() - 0.5
    assert np.abs(pos[:, 0]).max() < 2.0 - 0.5 and np.abs(pos[:, 1]).max() < 1.5 - 0.5
    plan = commanded_trajectory(t, desc)
    ranges = {}
    for axis, (t0, t1) in plan.segments.items():
        seg = (t >= t0) & (t < t1)
        ranges[axis] = np.ptp(pos[seg], axis=0)
    # each single-axis segment moves along its axis only (a line for the Monte-Carlo initializer)
    for i, axis in enumerate("xyz"):
        others = [j for j in range(3) if j != i]
        assert ranges[axis][i] > 0.8
        assert ranges[axis][others] == pytest.approx([0, 0], abs=1e-12)
    assert list(plan.segments) == ["x", "y", "z", "mixed"]
    assert plan.segments["x"][0] <= 0.5 and plan.segments["mixed"][0] == pytest.approx(14.0)
    assert np.all(ranges["mixed"] > 0.5)  # the mixed segment moves in all three axes
    # orientation: identity on the single-axis segments, a few degrees in the mixed segment
    angle = np.degrees([np.linalg.norm(gtsam.Rot3.Logmap(gtsam.Rot3.Quaternion(q[3], q[0], q[1], q[2])))
                        for q in arr[:, 3:]])
    mixed = t >= plan.segments["mixed"][0]
    assert angle[~mixed].max() < 1e-6
    assert 2 < angle[mixed].max() < 6
    # smooth: no jumps (30 Hz; measured at most 2.0 m/s)
    assert np.linalg.norm(np.diff(pos, axis=0), axis=1).max() < 2.5 / 30


# ---------------------------------------------------------------------------------- dynamic motion
def test_dynamic_swing_is_invisible_to_the_encoders(smooth, dynamic):
    """The swing keeps every cable length (4 cables leave 2 degrees of freedom): the encoders read
    the commanded lengths, which the true swinging poses have too, while forward kinematics at the
    assumed (level) orientation cannot see it."""
    _, out_s = smooth
    params_d, out_d = dynamic
    # commanded motion and noise draws are the same: identical encoder readings and tensions
    np.testing.assert_array_equal(out_d.streams["lengths"].values, out_s.streams["lengths"].values)
    np.testing.assert_array_equal(out_d.streams["tensions"].values, out_s.streams["tensions"].values)
    dev = out_d.truth_trajectories["cdpr"].pose_array() - out_s.truth_trajectories["cdpr"].pose_array()
    horizontal = np.linalg.norm(dev[:, :2], axis=1)
    assert horizontal.max() == pytest.approx(params_d["swing_amplitude"], rel=0.05)  # after the length fix
    assert horizontal[0] == 0  # at rest at home
    assert np.sqrt(np.mean(horizontal ** 2)) > 0.25 * params_d["swing_amplitude"]  # keeps swinging
    # dominant frequency of the swing: the pendulum's 0.6 Hz
    spectrum = np.abs(np.fft.rfft(dev[:, 0] - dev[:, 0].mean()))
    freq = np.fft.rfftfreq(len(dev), 1 / params_d["rate"])
    assert freq[np.argmax(spectrum)] == pytest.approx(params_d["swing_frequency"], abs=0.1)
    # same cable lengths at the true swinging and the commanded poses
    geo = true_geometry(params_d, out_d)
    lengths = [model_lengths(geo, *pose_arrays(o.truth_trajectories["cdpr"])) for o in (out_s, out_d)]
    np.testing.assert_allclose(lengths[1], lengths[0], rtol=0, atol=1e-9)
    # so the encoders match the truth to their noise in both sequences
    offsets = np.array(out_d.truth_calibration["cdpr"]["offset"]["values"])
    tensions, z = out_d.streams["tensions"].values, out_d.streams["lengths"].values
    r = z - encoder_readings(lengths[1], tensions, offsets, geo.stiffness_EA)
    assert abs(r.std() / params_d["encoder_sigma"] - 1) < 0.2
    # forward kinematics (level orientation, true geometry, noiseless lengths) misses the swing:
    # measured rms 3.8 mm smooth (the commanded tilt of a few degrees), 12 mm dynamic (swing rms 8 mm)
    fk, rms = forward_kinematics(geo.pulleys, np.zeros(4), geo.attachments, lengths[1])
    assert rms.max() < 5e-3  # a level pose fits the lengths to mm
    fk_error = [np.sqrt(np.mean(np.sum((fk - o.truth_trajectories["cdpr"].pose_array()[:, :3]) ** 2, axis=1)))
                for o in (out_s, out_d)]
    swing_rms = np.sqrt(np.mean(horizontal ** 2))
    assert fk_error[0] < 0.005
    assert fk_error[1] > 2 * fk_error[0] and fk_error[1] > 0.8 * swing_rms


# -------------------------------------------------------------------------------- parameters, files
def test_nested_parameters_keep_their_other_defaults():
    p = SIM._params({"vo_sigma": {"rotation": 0.01}})
    assert p["vo_sigma"] == {"rotation": 0.01, "translation": 0.0005}
    assert SIM.vo_sigma({**p, "motion": "dynamic"}) == pytest.approx({"rotation": 0.025, "translation": 0.00125})


def test_descriptions_keep_the_nominal_values():
    arascam = SIM.robots({})["cdpr"]
    assert arascam == robot_description_data("arascam")  # nominal pulleys, offsets -2.9, vo_scale 1.0
    small = SIM.robots({"robot": "cdpr_small"})["cdpr"]
    shipped = robot_description_data("cdpr_small")
    assert small["parameters"]["pulley"] == shipped["parameters"]["pulley"]
    # encoders zeroed at home: nominal offsets are minus the nominal lengths there (10-11 m)
    assert all(-12 < v < -6 for v in small["parameters"]["offset"]["values"])
    assert small["parameters"]["vo_scale"] == {"type": "scalar", "value": 1.0, "sigma": 10.0}


def run_written(folder, *sets: str):
    data = folder / "ds"
    args = ["simulate", "cable.cdpr", "--out", str(data)]
    for s in sets:
        args += ["--set", s]
    assert main(args) == 0
    written = sorted(str(p.relative_to(data)) for p in data.rglob("*") if p.is_file())
    assert written == [".fusionkit-output", "config.yaml", "data/lengths.csv", "data/mocap.tum", "data/tensions.csv", "data/vo.tum",
                       "robots/cdpr.yaml", "truth/calibration.yaml", "truth/cdpr.tum"]
    result = fusionkit.run(data / "config.yaml")
    est = result.parameters["cdpr"]
    truth = result.truth.calibration["cdpr"]
    pulley_error = np.linalg.norm(np.array(est["pulley"].values) - np.array(truth["pulley"]["values"]), axis=1)
    scale_z = (est["vo_scale"].values[0] - truth["vo_scale"]["value"]) / est["vo_scale"].sigma[0][0]
    return result, pulley_error, scale_z


def test_written_config_recovers_pulleys_within_5_cm_and_the_scale_within_3_sigma(tmp_path, capsys):
    """VO 0.5 mrad / 0.25 VO units (0.5 mm) per frame: pulleys within 5 cm (the config's rigid cable
    factor ignores the ~1.5 mm elastic stretch), scale within 3 sigma."""
    result, pulley_error, scale_z = run_written(tmp_path, "vo_sigma={rotation: 0.0005, translation: 0.00025}")
    config = yaml.safe_load((tmp_path / "ds" / "config.yaml").read_text())
    assert [f["type"] for f in config["factors"]] == ["pose.origin", "pose.scaled_relative", "cable.length"]
    assert [i["type"] for i in config["initializers"]] == ["cable.monte_carlo", "pose.dead_reckoning"]
    assert np.all(pulley_error < 0.05)
    assert abs(scale_z) < 3
    assert result.evaluation["trajectories"]["cdpr"]["ate_rmse_m"] < 0.01  # measured 4.5 mm
    cable = result.evaluation["residuals_by_entry"]["factors[2]:cable.length"]
    assert cable["final_rms"] < 0.002 < cable["initial_rms"]  # the nominal start is cm off


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    return run_written(tmp_path_factory.mktemp("cdpr_default"))


def test_written_config_at_default_noise_tracks_within_1_5_cm_and_pulleys_12_cm(default_run):
    """VO 1 mrad / 0.5 VO units (1 mm) per frame, Monte-Carlo start: pulleys within 12 cm
    (measured 2-8 cm, mean over 30 seeds 4 cm), trajectory within 1.5 cm (measured 0.5-1 cm)."""
    result, pulley_error, _ = default_run
    assert result.evaluation["trajectories"]["cdpr"]["ate_rmse_m"] < 0.015
    assert np.all(pulley_error < 0.12)


def test_default_noise_scale_within_3_sigma(default_run):
    """The scaled-VO residual in VO units keeps the scale unbiased even with noisy VO."""
    assert abs(default_run[2]) < 3


@pytest.mark.parametrize("coplanar", [True, False])
def test_true_pulleys_lie_on_one_plane_unless_asked_otherwise(coplanar):
    """Pulleys on one frame (default): the fourth on the plane of the first three, the plane tilted."""
    from fusionkit_plugins.cable_rigid.residuals import plane_distance_residual
    _, out = simulate(coplanar_pulleys=coplanar, pulley_error=0.05)
    a = np.array(out.truth_calibration["cdpr"]["pulley"]["values"])
    distance = abs(plane_distance_residual(*a)[0])
    assert (distance < 1e-12) if coplanar else (distance > 1e-3)
    normal = np.cross(a[1] - a[0], a[2] - a[0])
    assert np.degrees(np.arccos(abs(normal[2]) / np.linalg.norm(normal))) > 0.1  # not exactly level
