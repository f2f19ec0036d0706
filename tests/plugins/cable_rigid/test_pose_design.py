"""D-optimal static poses for a cable robot (plugins/cable_rigid/design.py, `fusionkit select-cable-poses`): the
taut-cable test, the design's Jacobian against the cable model's closed form, designed poses predicting the sigmas
of twice as many random ones, and the calibration from them reporting the sigmas the design predicted."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fusionkit.api import compared_with_random, robot_description_data
from fusionkit.cli.main import main
from fusionkit_plugins.cable_rigid.design import candidate_blocks, design_of, random_candidates, select, taut
from fusionkit_plugins.cable_rigid.simulators import cables, home_position
from research.cable_design_experiments import case

ENCODER, MOCAP = 1e-3, {"rotation": 2e-3, "translation": 1e-3}


@pytest.fixture(scope="module")
def arascam():
    desc = robot_description_data("arascam")
    return desc, design_of(desc)


def test_cables_are_taut_under_the_pulleys_and_slack_outside_them(arascam):
    desc, design = arascam
    home = home_position(desc)
    outside = home + np.array([3.0, 0.0, 0.0])  # beyond the pulleys' footprint (x within +-2 m)
    assert taut(design, np.array([home, outside])).tolist() == [True, False]


def test_the_designs_jacobian_is_the_cable_direction_and_one_per_offset(arascam):
    """With a motion capture a million times better than the encoder, a candidate's block is the length's
    Jacobian / encoder sigma x prior sigma: d l_i / d a_i = u_i (attachment towards the pulley), d l_i / d l0_i = 1."""
    desc, design = arascam
    positions = random_candidates(desc, design, 5, np.random.default_rng(1))
    blocks = candidate_blocks(design, positions, ENCODER, {"rotation": 1e-9, "translation": 1e-9})
    _, u, _ = cables(positions, np.broadcast_to(np.eye(3), (5, 3, 3)), design.geometry)
    n = design.geometry.n
    J = blocks * ENCODER / design.scale
    for i in range(n):
        np.testing.assert_allclose(J[:, i, 3 * i:3 * i + 3], u[:, i], atol=1e-6)
        np.testing.assert_allclose(J[:, i, 3 * n + i], 1.0, atol=1e-9)
    assert np.count_nonzero(np.abs(J) > 1e-9) == 5 * n * 4  # each length reads its own pulley and offset only


def test_designed_poses_predict_the_sigmas_of_twice_as_many_random_ones(arascam):
    desc, design = arascam
    rng = np.random.default_rng(0)
    candidates = random_candidates(desc, design, 500, rng)
    choice = select(design, candidates, 8, ENCODER, MOCAP)
    against = compared_with_random(choice, (8, 16), 20, rng)
    assert against[8]["geometric_mean"] < 0.5 and against[16]["geometric_mean"] < 0.8
    assert against[16]["worst"] < 0.7
    assert len(set(choice.indices.tolist())) == 8


def test_the_calibration_from_designed_poses_reports_the_sigmas_the_design_predicted():
    """Self-consistency (the simulated noise is the design's): fusionkit's calibration from 8 designed poses reports
    pulley and offset sigmas within 20 % of the design's prediction and errors of that size."""
    designed = case(seed=5, count=8, multiples=(2,))["designed"]
    ratio = designed["reported"] / designed["predicted"]
    assert 0.8 < ratio.min() and ratio.max() < 1.25
    assert designed["status"] == "accepted"
    assert designed["pulley_rms_m"] < 3 * np.sqrt(np.mean(designed["predicted"][:12] ** 2))


def test_select_cable_poses_writes_the_poses_and_their_predicted_sigmas(tmp_path, capsys):
    out = tmp_path / "plan"
    assert main(["select-cable-poses", "arascam", "--count", "6", "--random", "200", "--out", str(out)]) == 0
    assert "6 of 200 random taut candidates" in capsys.readouterr().out
    poses = np.loadtxt(out / "poses.tum")
    assert poses.shape == (6, 8) and np.all(poses[:, 7] == 1.0)
    selection = json.loads((out / "selection.json").read_text())
    assert set(selection["parameters"]) >= {"pulley[0].x", "offset[3]"}
    assert all(p["sigma"] < p["prior_sigma"] for p in selection["parameters"].values())


@pytest.mark.parametrize("args, says", [
    (["ur10_tracker", "--count", "3"], "select-cable-poses needs a cdpr description"),
    (["arascam", "--count", "0"], "--count 0: expected a positive number"),
    (["arascam", "--count", "30", "--random", "20"], "--count 30: more than the 20 candidates"),
])
def test_bad_select_cable_poses_input_is_one_line(tmp_path, capsys, args, says):
    assert main(["select-cable-poses", *args, "--out", str(tmp_path / "plan")]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1
    assert not (tmp_path / "plan").exists()
