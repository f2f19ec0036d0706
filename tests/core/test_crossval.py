"""`fusionkit crossval`: the folds (which factors train, which are held out, which are cut), the held-out errors
against the error the model predicts (self-consistency on simulated data with the estimator's own noise, and the
check failing with the noise mis-stated both ways), the command's table, files and one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fusionkit.cli.main import main
from fusionkit.crossval.folds import Plan, folds, partition
from fusionkit.crossval.run import crossval
from fusionkit.simulate import write_dataset

TOOL = "factors[1]:arm.tool_pose"


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    """A simulated UR10 calibration: 30 random configurations, tracker 0.1 mm / 0.1 mrad, told as simulated."""
    out = tmp_path_factory.mktemp("arm")
    write_dataset("arm.sim", out, ["configurations=30"], seed=3)
    return out / "config.yaml"


def test_k_folds_interleave_samples_and_a_split_holds_out_the_later_part():
    assert [f.tolist() for f in folds(Plan("sample", folds=3), 7)] == [[0, 3, 6], [1, 4], [2, 5]]
    assert [f.tolist() for f in folds(Plan("sample", leave_one_out=True), 3)] == [[0], [1], [2]]
    assert [f.tolist() for f in folds(Plan("sample", split=0.7), 10)] == [[7, 8, 9]]
    assert [f.tolist() for f in folds(Plan("segment", folds=4), 4)] == [[0], [1], [2], [3]]


def test_a_factor_linking_a_training_unit_with_a_held_out_one_is_in_neither():
    of_record = [np.array([0]), np.array([0, 1]), np.array([1]), np.array([1, 2]), np.array([], int), np.array([2])]
    train, held, across = partition(of_record, np.array([1]))
    assert (train, held, across) == ([0, 4, 5], [2], 2)  # the static-only factor (4) always trains


def test_simulated_arm_held_out_errors_match_what_the_model_predicts_self_consistency(arm):
    """Self-consistency (the simulator's noise is the estimator's): the held-out marker errors are what the
    model's sigmas and the training information predict, e'S^-1e per dimension near 1 (180 dimensions: 1 +- 0.11),
    and near the tracker's floor (sqrt(3) x 0.1 mm in position); no warning."""
    out = crossval(str(arm), [], Plan("auto", folds=5), ["joints"])
    assert out.plan.by == "sample"  # static configurations: no factor links two
    entry = out.pooled[TOOL]
    position = entry["parts"]["position"]
    assert position["count"] == 30 and position["unit"] == "m"
    assert 0.7 < entry["chi2_per_dim"] < 1.4
    assert 0.75 < position["rmse"] / position["predicted_rmse"] < 1.33
    assert np.sqrt(3) * 1e-4 * 0.8 < position["rmse"] < np.sqrt(3) * 1e-4 * 1.6
    assert entry["check"] is None
    assert all(f["training"]["status"] == "accepted" and not f["anchored_by"] for f in out.folds)


@pytest.mark.parametrize("told, says", [(1 / 3, "too small"), (3.0, "stated too large")])
def test_mis_stated_tracker_noise_fails_the_predictive_check(arm, told, says):
    """The same data with the tracker's sigma told a third or three times the simulated one: the held-out errors
    stay where they were (the estimate hardly moves) and the check says which way the sigmas are off."""
    sigma = 1e-4 * told
    out = crossval(str(arm), [f"factors.1.sigma.rotation={sigma}", f"factors.1.sigma.translation={sigma}"],
                   Plan("auto", folds=5), ["joints"])
    entry = out.pooled[TOOL]
    assert entry["chi2_per_dim"] == pytest.approx(1 / told ** 2, rel=0.4)
    assert says in entry["check"]
    assert np.sqrt(3) * 1e-4 * 0.8 < entry["parts"]["position"]["rmse"] < np.sqrt(3) * 1e-4 * 1.6


@pytest.mark.slow
def test_two_local_workers_give_the_folds_of_one(arm):
    one = crossval(str(arm), [], Plan("auto", folds=4), ["joints"], workers=1)
    two = crossval(str(arm), [], Plan("auto", folds=4), ["joints"], workers=2)
    assert [f["fold"] for f in two.folds] == list(range(4))
    for a, b in zip(one.folds, two.folds):
        assert a["entries"][TOOL]["parts"]["position"]["rmse"] == pytest.approx(
            b["entries"][TOOL]["parts"]["position"]["rmse"], rel=1e-9)


@pytest.mark.slow
def test_the_ray_backend_gives_the_folds_of_one_process(arm):
    """With Ray installed (`pip install 'fusionkit[scale]'`): a local Ray instance runs each fold as a task."""
    pytest.importorskip("ray", reason="Ray is an optional extra (fusionkit[scale])")
    one = crossval(str(arm), [], Plan("auto", folds=3), ["joints"])
    ray = crossval(str(arm), [], Plan("auto", folds=3), ["joints"], backend="ray")
    for a, b in zip(one.folds, ray.folds):
        assert a["entries"][TOOL]["parts"]["position"]["rmse"] == pytest.approx(
            b["entries"][TOOL]["parts"]["position"]["rmse"], rel=1e-9)


def test_the_command_prints_the_table_and_writes_crossval_json_and_the_plot(arm, tmp_path, capsys):
    out = tmp_path / "cv"
    assert main(["crossval", str(arm), "--folds", "3", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "3 folds by sample, reference joints: 3 of 3 fits ran" in text
    assert f"{TOOL} position (n = 30)" in text and "mm" in text
    document = json.loads((out / "crossval.json").read_text())
    assert document["status"] == "consistent" and document["reference"] == ["joints"]
    assert len(document["folds"]) == 3 and sum(f["entries"][TOOL]["count"] for f in document["folds"]) == 30
    assert set(document["folds"][0]["parameters"]) >= {"arm/base", "arm/marker"}
    assert (out / "plots" / "folds.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args, says", [
    (["--folds", "3", "--reference", "nope"], "--reference nope: not a stream of the config"),
    (["--split", "1.5"], "--split 1.5: expected a fraction between 0 and 1"),
    (["--folds", "1"], "--folds 1: expected 2 or more"),
    (["--folds", "31"], "--folds 31: expected 2 .. 30"),
    (["--folds", "3", "--by", "sample", "--cuts", "3"], "--cuts: segments only"),
    (["--leave-one-out", "--by", "file"], "--by file: every source reads one file"),
    (["--split", "0.5", "--by", "file"], "--split and --by file"),
])
def test_bad_crossval_arguments_are_one_line_and_exit_2(arm, tmp_path, capsys, args, says):
    assert main(["crossval", str(arm), "--out", str(tmp_path / "cv"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1
    assert not (tmp_path / "cv").exists()


def test_a_config_crossval_cannot_fold_is_refused_before_any_work(tmp_path, capsys):
    assert main(["crossval", "configs/cable_sag_small.yaml", "--folds", "2", "--out", str(tmp_path / "cv")]) == 2
    assert "solver.refine is not supported by crossval" in capsys.readouterr().err


@pytest.fixture(scope="module")
def wheels(tmp_path_factory):
    """A simulated wheeled robot (20 s square): wheels and gyro calibrated from the robot's start (pose.origin), the
    camera's poses as pose.absolute: a trajectory, odometry linking its states."""
    import yaml
    out = tmp_path_factory.mktemp("wheels")
    write_dataset("wheels.sim", out, ["duration=20", "path=square"], seed=1)
    config = yaml.safe_load((out / "config.yaml").read_text())
    config["factors"].append({"type": "pose.absolute", "robot": "robot", "stream": "camera",
                              "sigma": {"rotation": 0.02, "translation": 0.0028}})
    (out / "camera.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return out / "camera.yaml"


def test_trajectory_folds_are_stretches_of_time_cut_at_their_ends_and_anchored_by_the_first_camera_pose(wheels):
    """By segment (the wheel factors link consecutive states): 2 stretches; the factors across the cut train in
    neither fold; the wheels and gyro alone measure motion: the first stretch starts at the robot's origin (its
    prior), the second at its first camera pose (dead reckoning from a measured start), and the held-out camera
    poses are predicted within centimetres."""
    out = crossval(str(wheels), [], Plan("auto", folds=2), ["wheels"])
    assert out.plan.by == "segment"
    camera = "factors[5]:pose.absolute"
    assert [f["anchored_by"] for f in out.folds] == [[], [camera]]
    assert all(f["cut_factors"] > 0 for f in out.folds)
    position = out.pooled[camera]["parts"]["position"]
    assert 0 < position["rmse"] < 0.02 and position["count"] > 150
    assert 0.5 < out.pooled[camera]["chi2_per_dim"] < 2


def test_crossval_needs_an_entry_to_predict_and_trajectories_need_their_segments_named(wheels, tmp_path, capsys):
    assert main(["crossval", str(wheels), "--leave-one-out", "--out", str(tmp_path / "cv")]) == 2
    assert "name the segments with --cuts" in capsys.readouterr().err
    assert main(["crossval", str(wheels), "--folds", "2", "--reference", "wheels", "--reference", "camera",
                 "--out", str(tmp_path / "cv")]) == 2
    assert "nothing to predict" in capsys.readouterr().err


@pytest.mark.slow
def test_a_cable_robot_predicts_its_second_half_lengths_as_its_sigmas_say_self_consistency():
    """configs/cable_mocap_lengths.yaml (simulated with the estimator's noise), `--split 0.5`: the second half's
    cable lengths predicted from its motion-capture poses to 1.47 mm RMS, the model predicting 1.44 mm."""
    out = crossval("configs/cable_mocap_lengths.yaml", [], Plan("auto", split=0.5), ["mocap"])
    entry = out.pooled["factors[1]:cable.elastic_length"]
    length = entry["parts"]["length"]
    assert out.plan.by == "sample" and length["count"] == 1500
    assert length["rmse"] == pytest.approx(1.47e-3, abs=1e-5)
    assert length["predicted_rmse"] == pytest.approx(1.44e-3, abs=1e-5)
    assert entry["check"] is None


@pytest.mark.slow
def test_lagging_cable_encoders_are_predicted_to_2_mm_with_the_time_offset_and_16_mm_without(tmp_path):
    """The time-offset protocol (ARAS-CAM swinging, encoders 30 ms late, 4 Hz motion capture, states on the 40 Hz
    encoders' clock; research/time_offset_experiments.py), `--split 0.5 --reference mocap`: the second half's lengths
    held out 2.08 mm with the offset estimated, 16.0 mm without (the training fit rejected, the check failing)."""
    import yaml
    from fusionkit.sweep import override_text
    from research import time_offset_experiments as protocol
    write_dataset("cable.cdpr", tmp_path, [f"{k}={override_text(v)}" for k, v in protocol.CABLE.items()], seed=0)
    rmse = {}
    for offset in (True, False):
        config = yaml.safe_load((tmp_path / "config.yaml").read_text())
        protocol.cable_config(config, 1e9, offset)
        config["robots"]["cdpr"]["states"].pop("end")
        path = tmp_path / f"offset_{offset}.yaml"
        path.write_text(yaml.safe_dump(config, sort_keys=False))
        out = crossval(str(path), [], Plan("auto", split=0.5), ["mocap"])
        entry = out.pooled["factors[2]:cable.elastic_length"]
        rmse[offset] = entry["parts"]["length"]["rmse"]
        if not offset:
            assert out.folds[0]["training"]["status"] == "rejected" and "too small" in entry["check"]
    assert rmse[True] == pytest.approx(2.08e-3, abs=5e-5) and rmse[False] == pytest.approx(16.0e-3, abs=5e-4)
