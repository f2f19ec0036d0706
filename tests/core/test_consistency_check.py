"""Sigmas judged against the errors versus truth: overconfident and underconfident verdicts on known error
series, no verdict for right sigmas (also with one error shared by every state), and the note of a run whose
factor sigmas were divided by 5."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fusionkit.cli.main import main
from fusionkit.eval.consistency import effective_samples, sigma_check
from fusionkit.eval.notes import evaluation_notes
from fusionkit.eval.trajectory import position_consistency
from fusionkit.simulate import write_dataset


def verdict(z: np.ndarray) -> dict:
    percent = position_consistency(z, np.zeros_like(z), np.ones_like(z))
    return sigma_check(z, percent)


def test_effective_samples_are_n_for_independent_1_for_shared_and_ar1_formula_errors():
    rng = np.random.default_rng(0)
    assert effective_samples(rng.standard_normal(2000)) == pytest.approx(2000, rel=0.1)
    assert effective_samples(np.full(500, 0.7)) == 1.0  # one error shared by every state
    rho, e = 0.9, np.zeros(20000)
    for k in range(1, len(e)):
        e[k] = rho * e[k - 1] + rng.standard_normal()
    assert effective_samples(e) == pytest.approx(20000 * (1 - rho) / (1 + rho), rel=0.1)


def test_right_sigmas_get_no_verdict():
    z = np.random.default_rng(1).standard_normal((300, 3))
    check = verdict(z)
    assert check["overconfident"] == [] and check["underconfident"] == []
    assert min(check["effective_samples"].values()) > 200  # independent: about n (the lag-1 estimate is noisy)


def test_sigmas_three_times_too_small_are_overconfident():
    z = np.random.default_rng(2).standard_normal((300, 3))
    z[:, 1] *= 3.0  # y's sigma is a third of its error's
    check = verdict(z)
    assert check["overconfident"] == ["y"] and check["underconfident"] == []


def test_sigmas_three_times_too_large_are_underconfident_with_independent_errors_only():
    rng = np.random.default_rng(3)
    z = rng.standard_normal((300, 3)) / 3.0
    assert verdict(z)["underconfident"] == ["x", "y", "z"]
    # the same share inside 1 sigma from one error shared by all states (a right sigma: 0.3 of it) proves nothing
    shared = np.full((300, 3), 0.3) + rng.standard_normal((300, 3)) * 0.01
    check = verdict(shared)
    assert check["underconfident"] == [] and max(check["effective_samples"].values()) < 2


def test_notes_word_the_verdict_with_the_shares():
    ev = {"trajectories": {"cam": {
        "states": 180, "matched_poses": 180,
        "consistency_percent": {"x": {"1sigma": 70.0, "2sigma": 96.0, "3sigma": 100.0},
                                "y": {"1sigma": 6.0, "2sigma": 8.0, "3sigma": 10.0},
                                "z": {"1sigma": 100.0, "2sigma": 100.0, "3sigma": 100.0}},
        "consistency_check": {"effective_samples": {"x": 150.0, "y": 3.0, "z": 90.0},
                              "overconfident": ["y"], "underconfident": ["z"]}}}}
    assert evaluation_notes(ev) == [
        "sigmas of cam y are overconfident (inside 1/2/3 sigma: y 6/8/10 %; ideal 68/95/99.7 %): the errors against "
        "truth are larger than the sigmas say; check the noise sigmas of the factors",
        "sigmas of cam z are underconfident (inside 1/2/3 sigma: z 100/100/100 %; ideal 68/95/99.7 %): the errors "
        "against truth are smaller than the sigmas say; check the noise sigmas of the factors"]


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("consistency") / "ds"
    write_dataset("pose.scaled_vo", folder, ["duration=6"], seed=1)
    return folder


def test_run_with_factor_sigmas_divided_by_five_notes_overconfident_sigmas(simulated, tmp_path, capsys):
    config = simulated / "config.yaml"
    assert main(["run", str(config), "--out", str(tmp_path / "right"), "--no-plots"]) == 0
    right = json.loads((tmp_path / "right" / "report.json").read_text())
    assert right["evaluation"]["trajectories"]["cam"]["consistency_check"]["overconfident"] == []
    assert not any(n.startswith("sigmas of") for n in right["notes"])
    capsys.readouterr()
    divided = ["--set", "factors.0.sigma={rotation: 0.0004, translation: 0.00032}",   # the simulator's / 5
               "--set", "factors.1.sigma={rotation: 0.002, translation: 0.002}",
               "--set", "solver.max_cost_ratio=1000"]  # let the chi-square gate pass what it would refuse
    assert main(["run", str(config), "--out", str(tmp_path / "over"), "--no-plots", *divided]) == 0
    out = capsys.readouterr().out
    report = json.loads((tmp_path / "over" / "report.json").read_text())
    ev = report["evaluation"]["trajectories"]["cam"]
    flagged = [a for a in "xyz" if ev["consistency_percent"][a]["3sigma"] < 90]
    assert flagged and ev["consistency_check"]["overconfident"] == flagged
    note = next(n for n in report["notes"] if n.startswith("sigmas of cam"))
    assert note.startswith(f"sigmas of cam {', '.join(flagged)} are overconfident (inside 1/2/3 sigma: ")
    assert f"  note: {note}" in out.splitlines()
