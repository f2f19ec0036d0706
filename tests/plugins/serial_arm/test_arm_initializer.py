"""`arm.hand_eye`: the closed-form base and marker start (Shah's robot-world/hand-eye solve) recovers B and M
exactly from noise-free poses and near them from noisy ones, starts a simulated UR10 whose description knows
neither (identity base and marker) close enough for the full calibration to reach the truth, and refuses
poses that cannot determine them with one located line."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.pipeline import build_problem, estimate, read_sources
from fusionkit.simulate import simulated_config
from fusionkit_plugins.serial_arm.initializers import Degenerate, hand_eye
from fusionkit_plugins.serial_arm.simulators import ArmSimulator

from arm_helpers import typed


def random_pose(rng, scale: float = 1.0) -> np.ndarray:
    return gtsam.Pose3.Expmap(rng.normal(scale=scale, size=6)).matrix()


def pose_error(A: np.ndarray, B: np.ndarray) -> tuple[float, float]:
    """(rotation rad, translation m) between two 4x4 poses."""
    d = gtsam.Pose3.Logmap(gtsam.Pose3(np.linalg.inv(A) @ B))
    return float(np.linalg.norm(d[:3])), float(np.linalg.norm(A[:3, :3] @ d[3:]))


def test_hand_eye_recovers_base_and_marker_exactly_from_noise_free_poses():
    rng = np.random.default_rng(0)
    B, M = random_pose(rng), random_pose(rng, 0.3)
    F = np.array([random_pose(rng) for _ in range(5)])
    B_est, M_est = hand_eye(B @ F @ M, F)
    assert max(pose_error(B, B_est) + pose_error(M, M_est)) < 1e-9


def test_hand_eye_lands_within_the_noise_from_noisy_poses():
    """23 poses with 2 mm / 5 mrad per axis (the real UR10 recording's level): measured at most 4.0 mrad / 2.2 mm
    over seeds 0-4 for B and M."""
    rng = np.random.default_rng(1)
    B, M = random_pose(rng), random_pose(rng, 0.3)
    F = np.array([random_pose(rng) for _ in range(23)])
    noise = np.array([gtsam.Pose3.Expmap(np.r_[rng.normal(0, 5e-3, 3), rng.normal(0, 2e-3, 3)]).matrix()
                      for _ in F])
    B_est, M_est = hand_eye(B @ F @ M @ noise, F)
    for truth, est in ((B, B_est), (M, M_est)):
        rot, trans = pose_error(truth, est)
        assert rot < 5e-3 and trans < 5e-3


def test_rotations_about_one_axis_or_two_poses_leave_the_solution_open():
    rng = np.random.default_rng(2)
    B, M = random_pose(rng), random_pose(rng, 0.3)
    F = np.array([gtsam.Pose3(gtsam.Rot3.Rz(a), rng.normal(size=3)).matrix() for a in rng.uniform(-3, 3, 6)])
    with pytest.raises(Degenerate):
        hand_eye(B @ F @ M, F)
    with pytest.raises(Degenerate):
        hand_eye((B @ F @ M)[:2], F[:2])


def unknown_base_and_marker(params: dict):
    """A config edit: the simulated arm's description inline, with identity base and marker and no priors on
    them, started by arm.hand_eye."""
    sim = ArmSimulator()
    full = {**sim.defaults, **params, "drift": {**sim.defaults["drift"], **params.get("drift", {})}}

    def edit(config: dict) -> None:
        desc = sim.robots(full)["arm"]
        for name in ("base", "marker"):
            desc["parameters"][name] = {"type": "pose3", "value": {"translation": [0.0, 0.0, 0.0]}}
        config["robots"]["arm"]["description"] = desc
        config["initializers"] = [{"type": "arm.hand_eye", "robot": "arm", "stream": "tracker"}]
    return edit


@pytest.fixture(scope="module")
def simulated():
    params = {"configurations": 40}
    with simulated_config("arm.sim", params, seed=3, edit=unknown_base_and_marker(params)) as config:
        streams, truth = read_sources(config)
        yield config, build_problem(config, streams), truth, estimate(config)


def test_the_initializer_starts_an_unknown_base_and_marker_near_the_truth(simulated):
    """From identity (1.3 m and 0.6 rad off the true base): measured at most 1.1 mrad / 1.2 mm (base) and 2.2 mrad /
    2.3 mm (marker) over seeds 3-5, from the nominal kinematics of an arm with placement errors (0.5 mm, 1 mrad)
    and offsets (5 mrad) it does not know."""
    config, problem, truth, _ = simulated
    for name in ("base", "marker"):
        key = problem.keys.get("arm", name).key(0)
        start = problem.initial.atPose3(key).matrix()
        true = typed(truth.calibration["arm"][name], None).matrix()
        rot, trans = pose_error(true, start)
        assert rot < 0.01 and trans < 0.01, name


def test_the_calibration_from_that_start_reaches_the_truth(simulated):
    """Every estimated axis within 4 sigma (as from the shipped description's nominal base and marker)."""
    *_, result = simulated
    for name, ev in result.evaluation["parameters"]["arm"].items():
        sigma = np.ravel(result.parameters["arm"][name].sigma)
        z = np.ravel(ev["z_per_axis"])[sigma > 1e-6]
        assert np.all(np.abs(z) < 4.0), name


def run_validate(tmp_path, capsys, config: dict) -> tuple[int, str]:
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    code = main(["validate", str(path)])
    return code, capsys.readouterr().err


def base_config() -> dict:
    states = {"stream": "joints", "type": "vector6", "family": "joints"}
    config = {"name": "init", "robots": {"arm": {"states": states}},
              "sources": [{"type": "simulate", "scenario": "arm.sim", "params": {"configurations": 5}}],
              "factors": [{"type": "arm.joint_encoders", "robot": "arm", "stream": "joints", "sigma": 1e-5},
                          {"type": "arm.tool_pose", "robot": "arm", "stream": "tracker",
                           "sigma": {"rotation": 1e-4, "translation": 1e-4}}]}
    unknown_base_and_marker({})(config)
    return config


def test_two_configurations_stop_validate_with_one_located_line(tmp_path, capsys):
    config = base_config()
    config["sources"][0]["params"]["configurations"] = 2
    code, err = run_validate(tmp_path, capsys, config)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "initializers[0].stream: stream 'tracker': the marker poses of 2 configuration(s)" in err
    assert "Traceback" not in err


def test_a_description_without_base_and_tool_stops_validate_with_one_located_line(tmp_path, capsys):
    config = base_config()
    del config["robots"]["arm"]["description"]["kinematics"]["base"]
    del config["robots"]["arm"]["description"]["kinematics"]["tool"]
    code, err = run_validate(tmp_path, capsys, config)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "initializers[0].robot: robot 'arm' has neither a base nor a tool parameter" in err


def test_a_position_stream_is_refused_at_load(tmp_path, capsys):
    config = base_config()
    config["sources"][0]["params"]["measurement"] = "position"
    config["factors"][1] = {"type": "arm.tool_position", "robot": "arm", "stream": "tracker", "sigma": 1e-4}
    code, err = run_validate(tmp_path, capsys, config)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "initializers[0].stream: stream 'tracker' (sources[0]) lacks column(s) qx, qy, qz, qw" in err


def test_the_start_keeps_a_time_varying_offset_per_sample():
    """A drifting offset (one variable per state) is read per sample; the start still lands near the truth."""
    params = {"motion": "trajectory", "duration": 20.0, "rate": 2.0, "drift": {"change": 0.004}}
    with simulated_config("arm.sim", params, seed=2, edit=unknown_base_and_marker(params)) as config:
        streams, truth = read_sources(config)
        problem = build_problem(config, streams)
    assert problem.keys.get("arm", "drifting_offset[0]") is not None
    start = problem.initial.atPose3(problem.keys.get("arm", "base").key(0)).matrix()
    rot, trans = pose_error(typed(truth.calibration["arm"]["base"], None).matrix(), start)
    assert rot < 0.01 and trans < 0.01
