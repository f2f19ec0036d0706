"""A site with no surveyed anchor: `uwb.multilateration` with every anchor in `unknown` places the
anchors from the ranges (plugins/uwb/survey.py), in the anchor frame (anchor 0 at the origin,
anchor 1 on +x) held by gauge priors, or on the description's values when they carry priors; what
cannot be placed is one located line and exit 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fusionkit_plugins.uwb.survey import anchor_frame, line_of_sight, place_anchors
from research.uwb_experiments import run

ROOM = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]])  # uwb.sim's anchors: drawn in the anchor frame
EVERY = [0, 1, 2, 3]
CONSTANT_BIAS = {"bias_model": "constant", "bias_drift": 0.0, "unknown_anchors": EVERY}


def _path(k: int) -> np.ndarray:
    s = np.linspace(0.0, 2 * np.pi, k)
    return np.column_stack([5 + 3 * np.sin(s), 4 + 2.5 * np.sin(2 * s)])


@pytest.mark.parametrize("anchors", [ROOM[:3], ROOM,
                                     np.array([[1.0, 2.0], [7.0, -1.0], [9.0, 6.0], [3.0, 9.0], [-2.0, 4.0]])])
def test_exact_ranges_give_the_anchor_geometry_in_closed_form(anchors):
    tags = _path(80)
    ranges = np.linalg.norm(tags[:, None] - anchors[None], axis=2)
    placed, placed_tags = place_anchors(ranges)
    pairs = lambda a: np.linalg.norm(a[:, None] - a[None], axis=2)  # noqa: E731
    assert np.abs(pairs(placed) - pairs(anchors)).max() < 1e-6
    assert np.abs(np.linalg.norm(placed_tags[:, None] - placed[None], axis=2) - ranges).max() < 1e-6
    frame = anchor_frame(placed)
    a0, a1 = frame.transformFrom(placed[0]), frame.transformFrom(placed[1])
    assert np.abs(a0).max() < 1e-9 and abs(a1[1]) < 1e-9 and a1[0] > 0


def test_a_path_along_a_line_cannot_place_the_anchors():
    tags = np.column_stack([np.linspace(2, 8, 80), np.full(80, 3.0)])
    ranges = np.linalg.norm(tags[:, None] - ROOM[None], axis=2)
    with pytest.raises(ValueError, match="does not span the plane"):
        place_anchors(ranges + np.random.default_rng(0).normal(0, 0.05, ranges.shape))


def test_a_burst_of_long_ranges_is_left_out_of_the_survey():
    """The burst goes; so may a few ranges beside it (its values pull the running median), none
    farther than the 4 s window reaches, nor at the ends of the recording."""
    t = np.arange(0, 30, 0.1)
    z = 5 + np.sin(t / 3)  # the range to an anchor changing by up to 0.33 m/s
    z[100:110] += 0.8  # one second of a reflection
    keep = line_of_sight(t, np.zeros(len(t), int), z)
    assert not keep[100:110].any() and keep[np.abs(t - 10.45) > 2.5].all()


def aligned_anchor_errors(result) -> list[float]:
    """The report's anchor errors after the trajectory's SE(2) alignment (the anchor frame is not the world's)."""
    return result.evaluation["parameters"]["anchors"]["anchor"]["aligned_abs_error"]


@pytest.mark.parametrize("seed", [0, 2])
def test_every_anchor_unknown_places_them_in_the_anchor_frame_within_30_cm_ate_3_cm(seed):
    """Measured (60 s, constant bias, seeds 0-4): anchors 0.006-0.157 m from the truth after
    aligning the trajectory, trajectory 1.1-1.6 cm after alignment (with the anchors surveyed,
    unaligned: 1.1-1.4 cm)."""
    r = run(CONSTANT_BIAS, seed)
    anchors = np.asarray(r.parameters["anchors"]["anchor"].values, float)
    assert np.abs(anchors[0]).max() < 1e-5 and abs(anchors[1][1]) < 1e-5  # the gauge as documented
    assert np.linalg.norm(anchors - ROOM, axis=1).max() < 0.3  # uwb.sim's room is drawn in that frame: no mirror
    assert max(aligned_anchor_errors(r)) < 0.25
    ev = r.evaluation["trajectories"]["a"]
    assert ev["align"] == "se2" and ev["ate_rmse_m"] < 0.03
    assert any("anchor frame" in note and "not the world" in note for note in r.problem.notes)
    assert any(rec.label == "gauge:anchors/anchor" for rec in r.problem.records)


def test_wheel_odometry_picks_the_mirror_image_the_convention_would_not():
    """Anchors numbered 1, 0, 3, 2: in the anchor frame the true anchor 2 lies on the -y side, so
    only the odometry's sense of turning can choose it (solved errors measured 1145 against 4385
    for the +y placement, seed 0). Measured: anchors 0.04-0.14 m from where they belong."""
    def renumber(config):
        for entry in config["factors"] + config["initializers"]:
            if entry["type"] in ("uwb.range", "uwb.multilateration"):
                entry["columns"] = ["r1", "r0", "r3", "r2"]
    r = run(CONSTANT_BIAS, 0, edit=renumber)
    anchors = np.asarray(r.parameters["anchors"]["anchor"].values, float)
    expected = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, -8.0], [0.0, -8.0]])  # the room from (10, 0) to (0, 0)
    assert np.linalg.norm(anchors - expected, axis=1).max() < 0.3
    assert r.evaluation["trajectories"]["a"]["ate_rmse_m"] < 0.03


def test_every_anchor_unknown_with_a_drifting_bias_within_45_cm_ate_10_cm():
    """The default time-varying bias (0.03 m/sqrt(s) drift), seeds 0-4: anchors within 0.02-0.375 m
    after alignment, trajectory 4.3-6.6 cm after alignment."""
    r = run({"unknown_anchors": EVERY}, 1)
    assert max(aligned_anchor_errors(r)) < 0.45
    assert r.evaluation["trajectories"]["a"]["ate_rmse_m"] < 0.1


def test_anchor_priors_fix_the_frame_when_every_anchor_is_unknown():
    """A rough survey (each anchor 0.06-0.48 m off, sigma 0.5 m) in the description: the placement
    is moved onto it and no gauge prior is added. Measured: anchors 0.08-0.20 m from the truth
    without any alignment."""
    guesses = ROOM + np.random.default_rng(0).normal(0, 0.3, ROOM.shape)

    def rough_survey(config):
        config["robots"]["anchors"]["description"] = {"name": "anchors", "parameters": {"anchor": {
            "type": "point2", "values": guesses.round(3).tolist(), "sigma": 0.5}}}
    r = run(CONSTANT_BIAS, 0, edit=rough_survey)
    assert not any(rec.label.startswith("gauge:") for rec in r.problem.records)
    assert max(r.evaluation["parameters"]["anchors"]["anchor"]["abs_error"]) < 0.3
    assert any("description's anchor values" in note for note in r.problem.notes)


def _fusionkit(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(Path(sys.executable).parent / "fusionkit"), *args], capture_output=True, text=True)


@pytest.mark.parametrize("duration, expected", [("0.5", "5 epochs have a range to every anchor; at least 12"),
                                                ("2", "does not span the plane")])
@pytest.mark.slow
def test_too_short_a_recording_with_no_surveyed_anchor_is_one_located_line(tmp_path, duration, expected):
    sim = tmp_path / "sim"
    assert _fusionkit("simulate", "uwb.sim", "--out", str(sim), "--set", "unknown_anchors=[0,1,2,3]",
                      "--set", f"duration={duration}").returncode == 0
    proc = _fusionkit("run", str(sim / "config.yaml"), "--out", str(tmp_path / "out"))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and f"{sim / 'config.yaml'}:" in lines[0]
    assert "initializers[0].unknown: every anchor is unknown" in lines[0] and expected in lines[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_every_anchor_unknown_in_3d_is_refused_before_solving(tmp_path):
    sim = tmp_path / "sim"
    assert _fusionkit("simulate", "uwb.drone", "--out", str(sim), "--set", "duration=5").returncode == 0
    proc = _fusionkit("run", str(sim / "config.yaml"), "--out", str(tmp_path / "out"),
                      "--set", "initializers.0.unknown=[0,1,2,3,4,5]")
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "initializers[0].unknown" in lines[0] and "planar robot" in lines[0]


def test_simulator_refuses_an_anchor_index_it_does_not_have(tmp_path):
    proc = _fusionkit("simulate", "uwb.sim", "--out", str(tmp_path / "sim"), "--set", "unknown_anchors=[7]")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1 and "unknown_anchors" in proc.stderr
