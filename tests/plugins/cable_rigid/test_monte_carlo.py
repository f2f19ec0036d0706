"""`cable.monte_carlo` (docs/models/cable_rigid.md, "Initialization: Monte-Carlo self-calibration"):
pulleys, encoder offsets and the VO scale from encoder readings and unscaled VO alone, starting
from particles uniform over a region; the belief narrows shell -> ring -> cluster as the motion
covers more axes; an under-excited cable is reported as unresolved; a config that runs it before
dead reckoning converges to the truth.

The data: an ARAS-CAM-like robot generated here with numpy (pulleys near (+-2, +-1.5, 3.2) m,
attachments (+-0.15, +-0.15, 0.05) m), 750 poses at 30 Hz moving along x, then y, then z, then a
mixed 3-D motion with a few degrees of rotation; 1 mm encoders; VO at scale 2.0, expressed in an
arbitrary VO frame, with small per-frame noise."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import fusionkit
from fusionkit.errors import ConfigError
from fusionkit_plugins.cable_rigid.monte_carlo import calibrate, motion_stages

NOMINAL = np.array([[-2.0, -1.5, 3.2], [2.0, -1.5, 3.2], [2.0, 1.5, 3.2], [-2.0, 1.5, 3.2]])
ATTACH = np.array([[-0.15, -0.15, 0.05], [0.15, -0.15, 0.05], [0.15, 0.15, 0.05], [-0.15, 0.15, 0.05]])
HOME = np.array([0.0, 0.0, 1.2])
REGION = ([-3.0, -2.5, 2.0], [3.0, 2.5, 4.5])  # the whole ceiling of the room: no prior on the pulleys
SCALE_RANGE = (1.0, 4.0)
SIGMA = 0.001
RATE = 30.0


def _blend(s):
    s = np.clip(s, 0.0, 1.0)
    return s ** 3 * (10 - 15 * s + 6 * s ** 2)


def trajectory(n: int, axes: str, mixed: bool) -> tuple[np.ndarray, np.ndarray]:
    """Positions (n, 3) and rotations (n, 3, 3): rest, then home -> +A -> -A -> home along each
    axis in turn (minimum jerk), then a windowed Lissajous figure with a few degrees of rotation."""
    u = np.linspace(0.0, 1.0, n)
    amp = np.array([1.0, 0.8, 0.5])
    rest, segments = 0.02, len(axes) + mixed
    width = (1 - rest) / segments
    pos = np.tile(HOME, (n, 1))
    for j, axis in enumerate(axes):
        v = (u - rest - j * width) / width
        profile = np.where(v < 0.25, _blend(v / 0.25),
                           np.where(v < 0.75, 1 - 2 * _blend((v - 0.25) / 0.5), -1 + _blend((v - 0.75) / 0.25)))
        pos[:, "xyz".index(axis)] += amp["xyz".index(axis)] * np.where((v >= 0) & (v <= 1), profile, 0.0)
    angles = np.zeros((n, 3))
    if mixed:
        v = np.clip((u - rest - len(axes) * width) / width, 0.0, 1.0)
        env = (_blend(v / 0.15) * _blend((1 - v) / 0.15))[:, None]
        pos += env * [0.7, 0.6, 0.35] * np.sin(2 * np.pi * np.array([2.0, 3.0, 2.5]) * v[:, None] + [0, np.pi / 2, 0])
        angles = env * np.radians([3, 3, 5]) * np.sin(2 * np.pi * np.array([1.5, 2.0, 1.0]) * v[:, None] + [0, 1, 0])
    return pos, Rotation.from_rotvec(angles).as_matrix()


@dataclass
class Dataset:
    t: np.ndarray
    pos: np.ndarray           # true end-effector positions (n, 3)
    rot: np.ndarray           # (n, 3, 3)
    pulleys: np.ndarray       # true (4, 3)
    offsets: np.ndarray       # true l0_i
    nominal_offsets: np.ndarray  # the description's guess (within 3 cm)
    z: np.ndarray             # encoder readings (n, 4)
    vo: np.ndarray            # (n, 7) x y z qx qy qz qw, unscaled, arbitrary VO frame
    scale: float


def make_dataset(seed: int = 0, n: int = 750, axes: str = "xyz", mixed: bool = True, scale: float = 2.0,
                 vo_rot: float = 2e-4, vo_trans: float = 2.5e-4) -> Dataset:
    """vo_rot (rad) and vo_trans (VO units) per frame: small noise on the VO increments."""
    rng = np.random.default_rng(seed)
    pulleys = NOMINAL + rng.normal(0.0, 0.05, NOMINAL.shape)
    pos, rot = trajectory(n, axes, mixed)
    lengths = np.linalg.norm(np.einsum("kij,cj->kci", rot, ATTACH) + pos[:, None] - pulleys, axis=2)
    offsets = -lengths[0] + rng.normal(0.0, 0.01, 4)  # relative encoders, about zero at home
    z = lengths + offsets + rng.normal(0.0, SIGMA, lengths.shape)
    nominal = offsets + rng.uniform(-0.03, 0.03, 4)
    R_vo, t_vo = [Rotation.from_rotvec(rng.normal(size=3)).as_matrix()], [rng.normal(size=3)]
    for k in range(1, n):
        dR = rot[k - 1].T @ rot[k] @ Rotation.from_rotvec(rng.normal(0.0, vo_rot, 3)).as_matrix()
        dt = rot[k - 1].T @ (pos[k] - pos[k - 1]) / scale + rng.normal(0.0, vo_trans, 3)
        t_vo.append(t_vo[-1] + R_vo[-1] @ dt)
        R_vo.append(R_vo[-1] @ dR)
    vo = np.column_stack([np.array(t_vo), Rotation.from_matrix(np.array(R_vo)).as_quat()])
    return Dataset(np.arange(n) / RATE, pos, rot, pulleys, offsets, nominal, z, vo, scale)


def core_inputs(D: Dataset):
    """calibrate()'s arrays: the user's zero pose X0 is the true first pose (pose.origin)."""
    R = Rotation.from_quat(D.vo[:, 3:]).as_matrix()
    R_rel = np.einsum("ji,kjl->kil", R[0], R)
    t_rel = np.einsum("ji,kj->ki", R[0], D.vo[:, :3] - D.vo[0, :3])
    R0, p0 = D.rot[0], D.pos[0]
    c = np.einsum("ij,kjl,cl->cki", R0, R_rel, ATTACH) + p0
    d = t_rel @ R0.T
    z = D.z.T
    return c, d, z, z[:, 0] - D.nominal_offsets


def run_core(D: Dataset, seed: int = 0, **kw):
    c, d, z, L0 = core_inputs(D)
    kw.setdefault("vo_sigma", (2e-4, 2.5e-4))
    return calibrate(c, d, z, L0, REGION, SCALE_RANGE, SIGMA, rng=np.random.default_rng(seed), **kw)


@pytest.fixture(scope="module")
def full():
    D = make_dataset()
    return D, run_core(D)


# ------------------------------------------------------------------------------------ accuracy
def test_uniform_region_gives_pulleys_within_10_cm_offsets_5_cm_scale_2_percent(full):
    """No prior on the pulleys: particles start uniform over the whole ceiling box."""
    D, res = full
    pulley_err = np.linalg.norm(res.pulley - D.pulleys, axis=1)
    offset_err = (D.z[0] - res.length) - D.offsets
    # measured: pulleys 2.0-3.2 cm off (1-2 sigma), offsets 0.9-1.9 cm, scale -0.05 %
    assert pulley_err.max() < 0.10
    assert np.abs(offset_err).max() < 0.05
    assert res.scale == pytest.approx(D.scale, rel=0.02)
    assert res.stage_poses[-1] == 750 and res.axes_covered == 3
    assert (res.principal_spread()[:, 0] < 0.1).all()  # every pulley resolved
    assert (res.fit_rms < 0.02).all()


def test_noise_free_vo_puts_pulleys_within_1_cm_and_inside_their_covariance():
    """With exact VO the error is the encoder noise's doing, and the belief says how large it is:
    errors within the reported covariance (Mahalanobis^2 of a 3-D Gaussian: mean 3)."""
    D = make_dataset(seed=1, vo_rot=0.0, vo_trans=0.0)
    res = run_core(D, seed=1, vo_sigma=(0.0, 0.0))
    err = res.pulley - D.pulleys
    mahal = np.array([e @ np.linalg.solve(C, e) for e, C in zip(err, res.pulley_cov)])
    assert np.linalg.norm(err, axis=1).max() < 0.01  # measured 1-6 mm
    assert (mahal < 16.0).all() and mahal.mean() < 8.0  # measured 0.5-5.8, mean 3.3
    assert (1e-3 < res.principal_spread()[:, 0]).all() and (res.principal_spread()[:, 0] < 6e-3).all()
    assert res.scale == pytest.approx(D.scale, rel=1e-3)
    assert res.scale_sigma < 1e-3
    assert np.abs((D.z[0] - res.length) - D.offsets).max() < 0.01


def test_750_poses_5000_particles_4_cables_put_every_pulley_within_10_cm():
    """The benchmark's full-size case (its speed is measured in benchmarks/bench_cable_rigid.py)."""
    D = make_dataset(seed=2)
    c, d, z, L0 = core_inputs(D)
    res = calibrate(c, d, z, L0, REGION, SCALE_RANGE, SIGMA, particles=5000, rng=np.random.default_rng(0),
                    vo_sigma=(2e-4, 2.5e-4))
    assert z.shape == (4, 750) and res.particles == 5000
    assert np.linalg.norm(res.pulley - D.pulleys, axis=1).max() < 0.10


# ------------------------------------------------------------------------------------ the belief
def test_motion_stages_split_where_the_motion_turns_to_y_and_to_z(full):
    D, res = full
    n1, n2, K = res.stage_poses
    # the y segment starts at about pose 199, the z segment at about 383 (rest, then 4 equal parts)
    assert 185 <= n1 <= 205 and 370 <= n2 <= 390 and K == 750
    moved = np.abs(D.pos[:n1] - HOME)
    assert moved[:, 1].max() < 0.01 and moved[:, 2].max() < 0.01  # stage 1: along x only
    assert np.abs(D.pos[:n2, 2] - HOME[2]).max() < 0.01            # stage 2: no z yet
    assert motion_stages(np.zeros((50, 3))) == ([50, 50, 50], 0)


def test_belief_shrinks_from_band_to_spot_to_a_cluster_under_5_cm(full):
    """Principal 1-sigma spreads of the pulley belief: after the x motion a thin curved band (the
    part of the ring around the line of motion inside the region, on the initial-length shell),
    after the y motion a spot elongated along the cable, at the end a cluster."""
    D, res = full
    for i in range(4):
        s1, s2, s3 = res.stage_spread[:, i]  # largest first; measured (cable 0): 0.64/0.13/0.015,
        assert s1[0] > 0.4 and s1[2] < 0.05  # 0.029/0.014/0.009, 0.020/0.011/0.008 m
        assert s2[0] < 0.1 * s1[0] and s3[0] < s2[0] and s3[0] < 0.05
        assert np.prod(s1) > 100 * np.prod(s2) > 100 * np.prod(s3)


def ring_coordinates(D: Dataset, i: int, cloud: np.ndarray):
    """Distance from, and angle about, the x line through cable i's first attachment point."""
    c0 = D.pos[0] + D.rot[0] @ ATTACH[i]
    rho = np.hypot(cloud[1] - c0[1], cloud[2] - c0[2])
    return rho, np.arctan2(cloud[2] - c0[2], cloud[1] - c0[1]), np.hypot(*(D.pulleys[i, 1:] - c0[1:]))


@pytest.fixture(scope="module")
def exact_vo():
    D = make_dataset(seed=8, vo_rot=0.0, vo_trans=0.0)
    return D, run_core(D, seed=8, vo_sigma=(0.0, 0.0))


def test_after_a_line_the_belief_is_the_ring_through_the_truth(exact_vo):
    """With exact VO the likelihood of a straight-line motion does not depend on the angle about
    the line: the cloud spreads over the whole arc of the ring inside the region (144 deg here),
    at the right distance and position along the line, through the truth. (With drifting VO the
    line is not straight and some angles of the ring fit better than others.)"""
    D, res = exact_vo
    for i in range(4):
        rho, angle, true_rho = ring_coordinates(D, i, res.clouds[0][i])
        assert np.std(rho) < 0.03 and abs(np.median(rho) - true_rho) < 0.03
        assert np.ptp(angle) > np.radians(120)
        assert abs(np.median(res.clouds[0][i][0]) - D.pulleys[i, 0]) < 0.03
        assert np.min(np.linalg.norm(res.clouds[0][i].T - D.pulleys[i], axis=1)) < 0.03
        # then a spot, then a cluster around the truth
        for j in (1, 2):
            assert np.linalg.norm(res.clouds[j][i].mean(axis=1) - D.pulleys[i]) < 3 * res.stage_spread[j, i, 0] + 0.005


def test_single_axis_motion_reports_a_wide_belief_not_a_confident_answer():
    """Motion along x only: the pulley stays on its ring; the result says so."""
    for vo in (0.0, 2e-4):
        D = make_dataset(seed=3, axes="x", mixed=False, vo_rot=vo, vo_trans=vo)
        res = run_core(D, seed=3, vo_sigma=(vo, vo))
        assert res.axes_covered == 1 and res.stage_poses == [750, 750, 750]
        assert (res.principal_spread()[:, 0] > 0.3).all()  # measured 0.5-1.5 m
        assert res.scale == pytest.approx(D.scale, rel=0.03)  # the curvature of one line gives the scale
        if vo == 0.0:  # the truth is on the believed ring; the mean is no claim
            for i in range(4):
                assert np.min(np.linalg.norm(res.clouds[2][i].T - D.pulleys[i], axis=1)) < 0.03


# ------------------------------------------------------------------------------------ config runs
def description(D: Dataset) -> dict:
    """The robot as a user would describe it: attachments known, pulleys unknown (placeholder
    values, no prior), nominal offsets within 3 cm, scale unknown."""
    return {"name": "aras_test", "summary": "ARAS-CAM-like test robot", "model": "cdpr",
            "frames": ["base", "end_effector"],
            "sensors": {"camera": {"type": "monocular_camera", "frame": "end_effector"}},
            "cables": {"attachments": ATTACH.tolist()},
            "parameters": {"pulley": {"type": "point3", "values": [[0.0, 0.0, 3.0]] * 4},
                           "offset": {"type": "scalar", "values": D.nominal_offsets.round(4).tolist()},
                           "vo_scale": {"type": "scalar", "value": 1.0}}}


def write_config(workspace, D: Dataset, **mc) -> str:
    (workspace.folder / "robot.yaml").write_text(yaml.safe_dump(description(D), sort_keys=False))
    home = list(map(float, D.pos[0])) + [0.0, 0.0, 0.0, 1.0]
    entry = {"type": "cable.monte_carlo", "robot": "cdpr", "stream": "vo", "lengths": "lengths",
             "region": {"min": REGION[0], "max": REGION[1]}, "scale_range": list(SCALE_RANGE),
             "scale": "vo_scale", "sigma": SIGMA, "vo_sigma": {"rotation": 2e-4, "translation": 2.5e-4},
             "seed": 1, **mc}
    config = {
        "name": "monte_carlo_test",
        "robots": {"cdpr": {"description": "robot.yaml", "states": {"stream": "vo"}}},
        "sources": [workspace.poses("vo", D.t, D.vo),
                    workspace.columns("lengths", D.t, **{f"l{i}": D.z[:, i] for i in range(4)})],
        "factors": [
            {"type": "pose.origin", "robot": "cdpr", "pose": home, "sigma": {"rotation": 0.001, "translation": 0.001}},
            {"type": "pose.scaled_relative", "robot": "cdpr", "stream": "vo", "scale": "vo_scale",
             "sigma": {"rotation": 2e-4, "translation": 2.5e-4}},
            {"type": "cable.length", "robot": "cdpr", "stream": "lengths", "sigma": SIGMA}],
        "initializers": [entry, {"type": "pose.dead_reckoning", "robot": "cdpr", "stream": "vo", "scale": "vo_scale"}],
        "solver": {"type": "batch", "method": "lm"}}
    return workspace.config(config)


@pytest.mark.slow
def test_config_run_puts_pulleys_within_3_cm_and_the_scale_within_0_5_percent(workspace, tmp_path):
    D = make_dataset(seed=4)
    result = fusionkit.run(write_config(workspace, D))
    diag = result.problem.diagnostics["initializers[0]:cable.monte_carlo"]
    init = np.array([c["pulley"] for c in diag["cables"]])
    assert np.linalg.norm(init - D.pulleys, axis=1).max() < 0.10  # the initial values it set: 1.4-3.2 cm
    assert diag["scale"]["value"] == pytest.approx(2.0, rel=0.02)
    assert all(c["resolved"] for c in diag["cables"]) and diag["stages"]["axes_covered"] == 3
    assert len(diag["cables"][0]["stage_spread_m"]) == 3 and diag["verdict"][0].startswith("VO scale")
    # the factor graph from there (measured: pulleys 0.9-1.8 cm, offsets 2-6 mm, scale +0.1 %, 5 iterations)
    est = result.parameters["cdpr"]
    assert np.linalg.norm(np.array(est["pulley"].values) - D.pulleys, axis=1).max() < 0.03
    assert np.abs(np.array(est["offset"].values) - D.offsets).max() < 0.02
    assert est["vo_scale"].values[0] == pytest.approx(D.scale, rel=0.005)
    assert result.solution.stats()["iterations"] < 30
    # the belief figure
    png = tmp_path / "belief.png"
    result.problem.plots["monte_carlo_belief"](png)
    assert png.stat().st_size > 10_000


def test_unresolved_cable_is_named_in_the_verdict(workspace):
    """The verdict comes from the initializer, before any solve (as `fusionkit validate` shows it)."""
    from fusionkit.pipeline import build_problem, read_sources
    D = make_dataset(seed=5, axes="x", mixed=False)
    config = fusionkit.load_config(write_config(workspace, D))
    problem = build_problem(config, read_sources(config)[0])
    diag = problem.diagnostics["initializers[0]:cable.monte_carlo"]
    assert not any(c["resolved"] for c in diag["cables"])
    unresolved = [line for line in diag["verdict"] if "NOT resolved" in line]
    assert len(unresolved) == 4 and "move the end-effector along more axes" in unresolved[0]


def test_region_that_misses_the_cables_is_a_config_error(workspace):
    D = make_dataset(seed=6, n=120)
    path = write_config(workspace, D, region={"min": [10.0, 10.0, 10.0], "max": [11.0, 11.0, 11.0]})
    with pytest.raises(ConfigError, match="region"):
        fusionkit.run(path)


def test_bad_region_and_scale_range_fail_the_check(workspace):
    D = make_dataset(seed=7, n=60)
    with pytest.raises(ConfigError, match="min must be below max"):
        fusionkit.load_config(write_config(workspace, D, region={"min": [0, 0, 3], "max": [1, 1, 2]}))
    with pytest.raises(ConfigError, match="scale_range"):
        fusionkit.load_config(write_config(workspace, D, scale_range=[3.0, 1.0]))
    with pytest.raises(ConfigError, match="no parameter 'nope'"):
        fusionkit.load_config(write_config(workspace, D, scale="nope"))


# ------------------------------------------------------------------------------------ cable.cdpr
def test_cdpr_simulator_graph_from_monte_carlo_start_reaches_scale_0_5_percent_ate_3_cm(tmp_path):
    """The `cable.cdpr` dataset (default: VO drifting 15-25 cm over the run): the Monte-Carlo
    values land within 0.7 m (pulleys) and 12 % (scale) of the truth, and LM from there reaches the
    scale within 0.5 %, the pulleys within 20 cm and the trajectory within 3 cm."""
    from fusionkit.simulate import write_dataset

    write_dataset("cable.cdpr", tmp_path / "sim", [], seed=0)
    config = yaml.safe_load((tmp_path / "sim" / "config.yaml").read_text())
    vo_sigma = next(f["sigma"] for f in config["factors"] if f["type"] == "pose.scaled_relative")
    config["initializers"] = [
        {"type": "cable.monte_carlo", "robot": "cdpr", "stream": "vo", "lengths": "lengths",
         "region": {"min": [-3.0, -2.5, 2.0], "max": [3.0, 2.5, 4.5]}, "scale_range": [0.5, 5.0],
         "scale": "vo_scale", "sigma": 0.001, "vo_sigma": vo_sigma}] + config["initializers"]
    config["solver"] = {"type": "batch", "method": "lm"}
    path = tmp_path / "sim" / "mc.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    result = fusionkit.run(path)
    truth = result.truth.calibration["cdpr"]
    diag = result.problem.diagnostics["initializers[0]:cable.monte_carlo"]
    init = np.array([c["pulley"] for c in diag["cables"]])
    # measured: 0.26-0.47 m and -6 %: the VO drifts 15-25 cm and the initializer trusts it (a
    # regression on noisy regressors: the scale comes out low); the graph fixes both
    assert np.linalg.norm(init - np.array(truth["pulley"]["values"]), axis=1).max() < 0.7
    assert diag["scale"]["value"] == pytest.approx(2.0, rel=0.12)
    est = result.parameters["cdpr"]
    assert est["vo_scale"].values[0] == pytest.approx(2.0, rel=0.005)  # measured 2.0012
    assert np.linalg.norm(np.array(est["pulley"].values) - np.array(truth["pulley"]["values"]), axis=1).max() < 0.2
    assert result.evaluation["trajectories"]["cdpr"]["ate_rmse_m"] < 0.03  # measured 0.017
