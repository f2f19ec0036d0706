"""The kinematic-static calibration of docs/models/cable_sag.md (thesis fig. 5.2) on the static simulator's data
and on the external finite-element poses: Table 5.2's errors, the rigid-model ablation, the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from research.external_data import external_data, missing_reason
from research.cable_sag_experiments import (SOURCE_CODE_POSE_SIGMA, calibrate, errors, force_cross_validation,
                                            recurdyn_calibration, recurdyn_model_errors, recurdyn_poses, table_5_2)

FE_DATA = external_data("cdpr_recurdyn")
needs_fe_data = pytest.mark.skipif(not FE_DATA.is_dir(),
                                   reason=missing_reason("cdpr_recurdyn", "external finite-element data"))


@pytest.fixture(scope="module")
def large35():
    return [calibrate("cdpr_large", 35, seed) for seed in range(3)]


@pytest.mark.slow
def test_large_robot_35_poses_matches_table_5_2(large35):
    """Source: 0.191 m pulleys, 0.173 m offsets from starts up to 10 m off. Measured at 1 cm / 5 mrad
    vision over 10 seeds: 0.185 / 0.175 m; every run inside its own sigmas."""
    e = np.array([errors(r) for r in large35])
    assert e[:, 0].mean() < 0.3 and e[:, 1].mean() < 0.3
    for r in large35:
        ev = r.evaluation["parameters"]["cdpr"]
        assert np.abs(ev["pulley"]["z_per_axis"]).max() < 4 and np.abs(ev["offset"]["z_per_axis"]).max() < 4


@pytest.mark.slow
def test_small_robot_8_poses_at_1_cm_vision_is_within_its_marginals():
    """The small robot under the large one's noise policy (1 cm / 5 mrad vision), from starts up to
    1 m off (0.55 m on average): 8 poses tell its pulleys little. Measured on these 3 seeds 0.426 /
    0.414 m (per seed 0.28-0.50 m; 0.402 / 0.380 m over 10), the marginals predicting 0.73 m; the
    bound below leaves room for the seed spread, not for a solve that stays at its start."""
    runs = table_5_2(range(3), settings=(("cdpr_small", 8),))[("cdpr_small", 8)]
    assert runs["pulley_m"] < 0.5 and runs["offset_m"] < 0.5
    assert runs["pulley_m"] < runs["predicted_pulley_m"]


@pytest.mark.slow
def test_refined_solve_helps_where_the_data_match_the_model():
    """The simulator's data satisfy the catenary exactly: the second solve with the attachment
    heights held to 0.1 mm (solver.refine) takes the small robot at the source code's vision noise
    from 0.224 to 0.155 m pulleys (measured, these 3 seeds; 0.142 -> 0.098 m over 10)."""
    settings, noise = (("cdpr_small", 8),), {"pose_sigma": SOURCE_CODE_POSE_SIGMA}
    one = table_5_2(range(3), settings=settings, params=noise, refine=False)[("cdpr_small", 8)]
    refined = table_5_2(range(3), settings=settings, params=noise)[("cdpr_small", 8)]
    assert refined["pulley_m"] < 0.8 * one["pulley_m"]


@pytest.mark.slow
@pytest.mark.parametrize("robot, poses, source", [("cdpr_large", 9, (0.387, 0.380)), ("cdpr_small", 8, (0.149, 0.115))])
def test_table_5_2_at_the_source_codes_vision_noise(robot, poses, source):
    """The contract: at the vision noise of the source's public simulation code (0.19 mm, 0.019 deg
    per axis) the fewest-pose settings beat Table 5.2: measured over 10 seeds 0.119 / 0.117 m
    (large, 9) and 0.098 / 0.094 m (small, 8), the table's ten starts."""
    t = table_5_2(range(10), settings=((robot, poses),), params={"pose_sigma": SOURCE_CODE_POSE_SIGMA})
    r = t[(robot, poses)]
    assert r["pulley_m"] < source[0] and r["offset_m"] < source[1]


def test_nine_poses_at_1_cm_vision_are_within_their_marginals_which_exceed_table_5_2():
    """At 1 cm vision the marginal covariance at the 9-pose estimate predicts 0.87 m of pulley error
    (over 10 seeds), more than Table 5.2's 0.387 m. Evaluated at the truth that would be a
    Cramer-Rao-type bound for unbiased estimators without priors, not a limit on every estimator:
    this one (biased) achieves 0.626 m, below it."""
    r = table_5_2(range(3), settings=(("cdpr_large", 9),))[("cdpr_large", 9)]
    assert r["predicted_pulley_m"] > 0.387
    assert r["pulley_m"] < 1.2 * r["predicted_pulley_m"]


@pytest.mark.slow
def test_rigid_graph_is_ten_times_worse(large35):
    """The ablation: the same data through cable.length (massless cables). Source: 2.34 m vs 0.19 m."""
    rigid = calibrate("cdpr_large", 35, 0, rigid=True)
    assert errors(rigid)[0] > 10 * errors(large35[0])[0]


@pytest.mark.slow
def test_simulate_and_run_from_the_command_line(tmp_path):
    cli = Path(sys.executable).parent / "fusionkit"
    subprocess.run([str(cli), "simulate", "cable.sag_static", "--out", str(tmp_path / "sim"), "--seed", "2",
                    "--set", "poses=12"], check=True, capture_output=True)
    for name in ("data/poses.tum", "data/lengths.csv", "data/force.csv", "truth/calibration.yaml", "robots/cdpr.yaml"):
        assert (tmp_path / "sim" / name).is_file(), name
    proc = subprocess.run([str(cli), "run", str(tmp_path / "sim/config.yaml"), "--out", str(tmp_path / "out")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    report = json.loads((tmp_path / "out/report.json").read_text())
    assert report["evaluation"]["parameters"]["cdpr"]["pulley"]["mean_abs_error"] < 1.0  # started up to 10 m off


@needs_fe_data
def test_catenary_against_the_finite_element_cables():
    """Source: MPE-L 0.0089 % (large). Measured: 0.0070 %. Forces from lengths: 1.42 % (source
    0.92 %), of which 1.40 % is a bias: the finite-element cables differ from the published
    geometry systematically (the data's end-effector also tilts 0.47 times as far as the catenary
    equilibrium at the same position and yaw), not by scatter."""
    report = recurdyn_model_errors(recurdyn_poses(FE_DATA, "cdpr_large"))
    assert report["poses"] == 93
    assert report["mpe_length_percent"] < 0.0089
    assert report["mpe_force_percent"] < 2.0
    assert report["force_bias_percent"] > 0.9 * report["mpe_force_percent"]
    assert 0.3 < report["tilt_ratio"] < 0.7


@needs_fe_data
def test_cross_validated_attachment_height_removes_the_force_bias_on_held_out_poses():
    """An effective parameter for the 1.42 % force error, fitted on one half of the poses and
    reported on the other: attachments 2.6 cm higher (both folds) leave 0.38 % and 0.58 % on the
    held-out halves, against 1.39 % and 1.43 % with the published geometry (measured)."""
    folds = force_cross_validation(recurdyn_poses(FE_DATA, "cdpr_large"))
    assert len(folds) == 2 and {tuple(f["fit_rows"]) for f in folds} == {(0, 45), (46, 92)}
    for f in folds:
        assert 0.015 < f["attachment_dz_m"] < 0.04
        assert f["effective_mpe_force_percent"] < 0.5 * f["published_mpe_force_percent"]
    assert abs(folds[0]["attachment_dz_m"] - folds[1]["attachment_dz_m"]) < 0.005


@needs_fe_data
def test_refined_solve_makes_the_small_robot_worse_on_the_finite_element_poses():
    """Those cables differ from the catenary by about the first solve's 1 cm height tolerance:
    holding them to 0.1 mm takes the small robot's pulleys from 0.079 to 0.181 m off (measured,
    seed 0). On the large robot's poses it changes little (0.110 -> 0.104 m over 3 seeds)."""
    fe = recurdyn_poses(FE_DATA, "cdpr_small")
    one = recurdyn_calibration(fe, seeds=range(1))
    refined = recurdyn_calibration(fe, seeds=range(1), refine=True)
    assert refined["pulley_m"] > 1.5 * one["pulley_m"]


@pytest.mark.slow
@needs_fe_data
@pytest.mark.parametrize("robot, poses, limit", [("cdpr_large", 93, 0.2), ("cdpr_small", 8, 0.15)])
def test_calibration_on_the_finite_element_poses(robot, poses, limit):
    """Measured: large (93 poses) pulleys 0.11 m, offsets 0.09 m; small (8) 0.08 / 0.06 m."""
    report = recurdyn_calibration(recurdyn_poses(FE_DATA, robot), seeds=range(1))
    assert report["poses"] == poses
    assert report["pulley_m"] < limit and report["offset_m"] < limit
