"""D-optimal pose selection before any data are taken (selection.py) and `fusionkit select-poses`: the
selected configurations carry more information than random ones, the log det kept by the determinant lemma
equals a direct slogdet, the predicted sigmas are those of the selected information matrix, and the command
writes its two files or refuses in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fusionkit.api import load_robot_description
from fusionkit.cli.main import main
from fusionkit_plugins.serial_arm.selection import design_of, information, predicted_sigma, select
from fusionkit_plugins.serial_arm.simulators import random_configurations

POSE_SIGMA = np.full(6, 1e-4)


@pytest.fixture(scope="module")
def ur10():
    """The shipped UR10's design, 300 random candidates (seed 0) and the 15 D-optimal ones among them."""
    design = design_of(load_robot_description("ur10_tracker"))
    candidates = random_configurations(design.chain, 300, np.random.default_rng(0))
    return design, candidates, select(design, candidates, "pose", POSE_SIGMA, 15)


def test_15_d_optimal_configurations_beat_every_random_15_and_3n_random_gives_what_they_do_not(ur10):
    """The selection's log det exceeds that of each of 30 random picks of 15 of the same candidates (353.3 against
    at most 350.9), and its predicted sigmas are smaller: geometric mean x0.87 and worst (largest sigma / prior)
    x0.80 of a random 15 (medians of 20 picks; thresholds 0.95 and 0.9). Measured, against the issue's hope:
    45 random configurations (3N) give smaller sigmas still -- worst-case sigma of the selection / of 45 random
    ones 1.63-1.74 over 10 draws -- because on a full-range 6-D tracker every configuration carries nearly
    the same information (the documented finding: docs/models/serial_arm.md#pose-selection)."""
    design, candidates, chosen = ur10
    G, P = chosen.blocks, chosen.prior
    rng = np.random.default_rng(1)
    picks = [rng.choice(len(candidates), 15, replace=False) for _ in range(30)]
    assert chosen.log_det > max(np.linalg.slogdet(information(G, P, rows))[1] for rows in picks)
    geo, worst = [], []
    for rows in picks[:20]:
        r = chosen.sigma_of(rows)
        geo.append(np.exp(np.mean(np.log(chosen.sigma / r))))
        worst.append(np.max(chosen.sigma / chosen.scale) / np.max(r / chosen.scale))
    assert np.median(geo) < 0.95 and np.median(worst) < 0.9
    ratios = [np.max(chosen.sigma / chosen.scale) / np.max(predicted_sigma(
        design, random_configurations(design.chain, 45, np.random.default_rng(100 + s)), "pose", POSE_SIGMA,
        chosen) / chosen.scale) for s in range(10)]
    assert 1.3 < min(ratios) and max(ratios) < 2.2  # the worst-case sigma ratio vs 3N random, as measured


def test_the_greedy_and_exchange_log_det_is_the_slogdet_of_the_selected_information(ur10):
    """The log det accumulated by the determinant lemma (greedy steps and exchange swaps) equals a direct
    slogdet of P + sum G_c^T G_c over the chosen candidates, and the sigmas are its inverse's diagonal."""
    design, candidates, chosen = ur10
    assert chosen.swaps > 0 and len(set(chosen.indices.tolist())) == 15
    direct = np.linalg.slogdet(information(chosen.blocks, chosen.prior, chosen.indices))[1]
    assert chosen.log_det == pytest.approx(direct, rel=1e-10)
    np.testing.assert_allclose(chosen.sigma, chosen.sigma_of(chosen.indices), rtol=1e-8)
    np.testing.assert_allclose(chosen.sigma, predicted_sigma(design, candidates[chosen.indices], "pose", POSE_SIGMA,
                                                             chosen), rtol=1e-8)


def test_a_parameter_without_prior_and_a_position_tracker_keep_the_log_det_exact():
    """A laser tracker (3 rows per configuration) and the base without a prior (vanishing prior information):
    the lemma's log det still equals the direct slogdet, and the held parameters include the marker's rotation."""
    design = design_of(load_robot_description("ur10_tracker"))
    design.prior[:6] = np.inf
    candidates = random_configurations(design.chain, 80, np.random.default_rng(2))
    chosen = select(design, candidates, "position", np.full(3, 1e-4), 10)
    direct = np.linalg.slogdet(information(chosen.blocks, chosen.prior, chosen.indices))[1]
    assert chosen.log_det == pytest.approx(direct, rel=1e-10)
    assert {"marker.rx", "marker.ry", "marker.rz"} <= {design.names[j] for j in chosen.held}
    assert np.all(chosen.sigma[:6] < 1e-3)  # the unpriored base is determined by the data (m, rad)


def run_command(*args) -> int:
    return main(["select-poses", "ur10_tracker", *args, "-q"])


def test_select_poses_writes_the_configurations_and_the_predicted_sigmas(tmp_path, capsys):
    out = tmp_path / "poses"
    assert run_command("--count", "8", "--random", "60", "--seed", "3", "--out", str(out)) == 0
    printed = capsys.readouterr().out
    assert "8 of 60 random candidates (seed 3)" in printed and "predicted 1-sigma, worst first" in printed
    lines = (out / "configurations.csv").read_text().splitlines()
    assert lines[0] == ("t,shoulder_pan_joint,shoulder_lift_joint,elbow_joint,wrist_1_joint,wrist_2_joint,"
                        "wrist_3_joint") and len(lines) == 9
    doc = json.loads((out / "selection.json").read_text())
    assert len(doc["parameters"]) == 30 and len(doc["held"]) == 24
    assert "joint_offsets[shoulder_pan_joint]" in doc["held"]  # named as the identifiability verdict names it
    assert doc["parameters"]["joint_offsets[elbow_joint]"]["unit"] == "rad"
    assert doc["parameters"]["base.tx"]["prior_sigma"] == 0.05 and 0 < doc["parameters"]["base.tx"]["sigma"] < 1e-3
    # the written configurations read back as candidates: choosing all 8 of them predicts the same sigmas
    again = tmp_path / "again"
    assert run_command("--count", "8", "--candidates", str(out / "configurations.csv"), "--out", str(again)) == 0
    redo = json.loads((again / "selection.json").read_text())
    assert redo["log_det"] == pytest.approx(doc["log_det"], rel=1e-9)


@pytest.mark.parametrize("args, message", [
    (["--count", "0", "--out", "{tmp}/a"], "--count 0: expected a positive number"),
    (["--count", "5", "--random", "3", "--out", "{tmp}/a"], "--count 5: more than the 3 candidates"),
    (["--count", "2", "--random", "20", "--out", "{tmp}/user"], "was not written by fusionkit"),
])
def test_select_poses_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    (tmp_path / "user").mkdir()
    (tmp_path / "user" / "notes.txt").write_text("mine")
    assert run_command(*[a.format(tmp=tmp_path) for a in args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not (tmp_path / "a").exists() and sorted(p.name for p in (tmp_path / "user").iterdir()) == ["notes.txt"]


def test_select_poses_names_the_installed_descriptions_for_an_unknown_one(tmp_path, capsys):
    assert main(["select-poses", "ur11_tracker", "--count", "3", "--out", str(tmp_path / "a"), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown robot description 'ur11_tracker'" in err and "ur10_tracker" in err and len(err.splitlines()) == 1
