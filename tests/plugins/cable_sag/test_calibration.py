"""The kinematic-static calibration of spec cable_sag.md (fig. 5.2) on the static simulator's data
and on the external finite-element poses: Table 5.2's errors, the rigid-model ablation, the CLI."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fusionkit.testing.external_data import external_data, missing_reason
from fusionkit_plugins.cable_sag.experiments import (SOURCE_CODE_POSE_SIGMA, calibrate, errors, recurdyn_calibration,
                                                     recurdyn_model_errors, recurdyn_poses, table_5_2)

FE_DATA = external_data("cdpr_recurdyn")
needs_fe_data = pytest.mark.skipif(not FE_DATA.is_dir(),
                                   reason=missing_reason("cdpr_recurdyn", "external finite-element data"))


@pytest.fixture(scope="module")
def large35():
    return [calibrate("cdpr_large", 35, seed) for seed in range(3)]


def test_large_robot_35_poses_matches_table_5_2(large35):
    """Source: 0.191 m pulleys, 0.173 m offsets from starts up to 10 m off. Measured over 10
    seeds: 0.185 / 0.175 m; every run inside its own sigmas."""
    e = np.array([errors(r) for r in large35])
    assert e[:, 0].mean() < 0.3 and e[:, 1].mean() < 0.3
    for r in large35:
        ev = r.evaluation["parameters"]["cdpr"]
        assert np.abs(ev["pulley"]["z_per_axis"]).max() < 4 and np.abs(ev["offset"]["z_per_axis"]).max() < 4


def test_small_robot_8_poses():
    """Source: 0.149 / 0.115 m from starts up to 1 m off; measured (10 seeds, 1 mm vision) 0.125 /
    0.120 m; without the refined solve (1 cm height tolerance throughout) 0.161 / 0.155 m."""
    e = np.array([errors(calibrate("cdpr_small", 8, seed)) for seed in range(3)])
    assert e[:, 0].mean() < 0.2 and e[:, 1].mean() < 0.2


@pytest.mark.parametrize("robot, poses, source", [("cdpr_large", 9, (0.387, 0.380)), ("cdpr_small", 8, (0.149, 0.115))])
def test_table_5_2_at_the_source_codes_vision_noise(robot, poses, source):
    """At the vision noise of the source's public code (0.19 mm, 0.019 deg per axis) the fewest-pose
    settings beat Table 5.2: measured over 10 seeds 0.119 / 0.117 m (large, 9) and 0.098 / 0.094 m
    (small, 8), the table's ten starts."""
    t = table_5_2(range(10), settings=((robot, poses),), params={"pose_sigma": SOURCE_CODE_POSE_SIGMA})
    r = t[(robot, poses)]
    assert r["pulley_m"] < source[0] and r["offset_m"] < source[1]


def test_few_poses_at_1_cm_vision_are_bounded_by_the_data():
    """At 1 cm vision, 9 poses cannot give the source's 0.387 m: the marginals predict 0.9 m of
    pulley error (measured 0.626 m achieved over 10 seeds); the estimate is no worse than the bound."""
    r = table_5_2(range(3), settings=(("cdpr_large", 9),))[("cdpr_large", 9)]
    assert r["predicted_pulley_m"] > 0.387
    assert r["pulley_m"] < 1.2 * r["predicted_pulley_m"]


def test_rigid_graph_is_ten_times_worse(large35):
    """The ablation: the same data through cable.length (massless cables). Source: 2.34 m vs 0.19 m."""
    rigid = calibrate("cdpr_large", 35, 0, rigid=True)
    assert errors(rigid)[0] > 10 * errors(large35[0])[0]


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
@pytest.mark.parametrize("robot, poses, limit", [("cdpr_large", 93, 0.2), ("cdpr_small", 8, 0.15)])
def test_calibration_on_the_finite_element_poses(robot, poses, limit):
    """Measured: large (93 poses) pulleys 0.11 m, offsets 0.09 m; small (8) 0.08 / 0.06 m."""
    report = recurdyn_calibration(recurdyn_poses(FE_DATA, robot), seeds=range(1))
    assert report["poses"] == poses
    assert report["pulley_m"] < limit and report["offset_m"] < limit
