"""Observability diagnostic of the cable calibration (thesis eqs. 4.6/4.7, docs/models/cable_rigid.md): the squared
measurement is linear in the lifted unknowns; its rank and conditioning tell whether a trajectory
excites each cable, and which way to move when it does not."""

from __future__ import annotations

import json
import re

import gtsam
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import fusionkit
from fusionkit.cli.main import main
from fusionkit_plugins.cable_rigid.observability import analyze, lifted_system, solve_lifted, verdict

PULLEYS = np.array([[-2.0, -1.5, 3.2], [2.0, -1.5, 3.2], [2.0, 1.5, 3.2], [-2.0, 1.5, 3.2]])
ATTACH = np.array([[-0.15, -0.15, 0.05], [0.15, -0.15, 0.05], [0.15, 0.15, 0.05], [-0.15, 0.15, 0.05]])
OFFSETS = np.array([-2.9, -2.8, -3.0, -2.95])
SIGMA = 0.001  # encoder, m


def trajectory(rng, n: int, extent, tilt_deg: float = 3.0, yaw_deg: float = 3.0):
    """Random positions in a box of half-extent `extent` around (0, 0, 1.2) and small rotations."""
    t = rng.uniform(-1, 1, (n, 3)) * np.asarray(extent) + [0.0, 0.0, 1.2]
    rv = rng.normal(size=(n, 3)) * np.radians([tilt_deg, tilt_deg, yaw_deg])
    return t, Rotation.from_rotvec(rv).as_matrix()


def lengths(t, R, i: int, alpha=1.0):
    return alpha * np.linalg.norm(t + R @ ATTACH[i] - PULLEYS[i], axis=1) + OFFSETS[i]


@pytest.fixture
def rng():
    return np.random.default_rng(4)


# --- the linear system ---------------------------------------------------------------------------
def test_3d_motion_gives_full_rank_and_recovers_pulleys_and_offsets_to_1e_10(rng):
    t, R = trajectory(rng, 300, [0.5, 0.5, 0.5])
    for i in range(4):
        sys = lifted_system(t, lengths(t, R, i), R @ ATTACH[i])
        r = analyze(sys, SIGMA)
        # measured: conditions 33..35, weakest combination excited by 13-15 mm rms (limit 3 mm)
        assert (r["rank"], r["unknowns"], r["observable"]) == (5, 5, True)
        assert 10 < r["condition"] < 200
        assert r["excitation_m"] > 5 * SIGMA
        sol = solve_lifted(sys)  # noise-free: the derivation is exact, rotations included
        np.testing.assert_allclose(sol["pulley"], PULLEYS[i], atol=1e-10)
        assert sol["offset"] == pytest.approx(OFFSETS[i], abs=1e-10)
        # the weakest combination trades the offset against the distance along the cable
        u = PULLEYS[i] - t.mean(axis=0)
        assert abs(np.dot(r["weakest_direction"], u / np.linalg.norm(u))) > 0.99
        assert re.fullmatch(rf"cable {i}: observable \(rank 5/5, condition 3\.\de1\)", verdict(i, r))


def test_unknown_scale_gives_rank_6_and_recovers_scale_pulley_and_offset_to_1e_9(rng):
    """VO translations up to the scale s (eq. 4.3), constant orientation: six unknowns, exact."""
    t, _ = trajectory(rng, 300, [0.5, 0.5, 0.5])
    R = np.tile(Rotation.from_rotvec([0.05, -0.02, 0.3]).as_matrix(), (300, 1, 1))
    s = 2.5  # metres per VO unit
    sys = lifted_system(t / s, lengths(t, R, 2), R @ ATTACH[2], unknown_scale=True)
    r = analyze(sys, SIGMA / s)
    assert (r["rank"], r["unknowns"], r["observable"]) == (6, 6, True)
    assert r["condition"] < 200  # measured 56
    sol = solve_lifted(sys)
    assert sol["scale"] == pytest.approx(s, rel=1e-10)
    np.testing.assert_allclose(sol["pulley"], PULLEYS[2], atol=1e-9)
    assert sol["offset"] == pytest.approx(OFFSETS[2], abs=1e-9)


def test_elastic_cable_is_recovered_exactly_and_weak_tension_variation_is_named(rng):
    t, R = trajectory(rng, 300, [0.5, 0.5, 0.5])
    for tension in (rng.uniform(10, 60, 300), np.full(300, 30.0)):
        alpha = 1 - tension / 2.0e4
        sys = lifted_system(t, lengths(t, R, 1, alpha), R @ ATTACH[1], alpha=alpha)
        sol = solve_lifted(sys)
        np.testing.assert_allclose(sol["pulley"], PULLEYS[1], atol=1e-9)
        assert sol["offset"] == pytest.approx(OFFSETS[1], abs=1e-9)
        r = analyze(sys, SIGMA)
        assert r["observable"]
        if np.ptp(tension) > 0:  # |a|^2 and l0^2 separate only through the tension changes
            assert (r["rank"], r["unknowns"]) == (5, 6)
            assert "tension varies too little" in verdict(1, r)
        else:
            assert (r["rank"], r["unknowns"]) == (5, 5)


def test_horizontal_plane_names_z(rng):
    """Attachment points in a horizontal plane (yaw only): the z column vanishes."""
    t, R = trajectory(rng, 300, [0.5, 0.5, 0.0], tilt_deg=0.0, yaw_deg=20.0)
    sys = lifted_system(t, lengths(t, R, 0), R @ ATTACH[0])
    r = analyze(sys, SIGMA)
    assert (r["rank"], r["unknowns"], r["observable"]) == (4, 5, False)
    assert r["condition"] > 1e12
    np.testing.assert_allclose(r["weakest_direction"], [0, 0, 1], atol=1e-6)
    assert r["extent_m"][2] < 1e-12 and r["extent_m"][:2].min() > 0.9
    text = verdict(0, r)
    assert text.startswith("cable 0: NOT observable from this trajectory (rank 4/5, condition ")
    assert "does not excite it along z (" in text and text.endswith("move the end-effector along z (up/down) as well")


def test_nearly_flat_with_pose_noise_names_z(rng):
    """No z motion, but noisy pose estimates: the rank still drops (z wobble < 3 encoder sigmas)."""
    t, R = trajectory(rng, 300, [0.5, 0.5, 0.0], tilt_deg=0.0, yaw_deg=0.0)
    z = lengths(t, R, 3) + rng.normal(0, SIGMA, 300)
    t_est = t + rng.normal(0, 0.001, t.shape)
    r = analyze(lifted_system(t_est, z, R @ ATTACH[3]), SIGMA)
    assert not r["observable"] and r["rank"] == 4
    assert r["condition"] > 200  # measured 4.1e2 (3-D motion: 33..35)
    assert "does not excite it along z (" in verdict(3, r)


def test_single_line_names_the_missing_axes(rng):
    t, R = trajectory(rng, 200, [0.6, 0.0, 0.0], tilt_deg=0.0, yaw_deg=0.0)
    r = analyze(lifted_system(t, lengths(t, R, 1), R @ ATTACH[1]), SIGMA)
    assert (r["rank"], r["observable"]) == (3, False)
    assert "does not excite it along y and z (" in verdict(1, r)
    assert "move the end-effector along y and z (up/down) as well" in verdict(1, r)
    # a slanted line: the missing directions are not axes, they are named as vectors
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    t2 = np.outer(rng.uniform(-0.6, 0.6, 200), d) + [0, 0, 1.2]
    text = verdict(1, analyze(lifted_system(t2, lengths(t2, R, 1), R @ ATTACH[1]), SIGMA))
    assert "along [0.00, 0.00, 1.00] and" not in text and "along z and [0.71, -0.71, 0.00]" in text


def test_small_motion_cannot_separate_offset_from_distance(rng):
    """A 10 cm cloud 3 m from the pulley: the sphere's curvature (< 1 mm) hides under the noise."""
    t, R = trajectory(rng, 300, [0.05, 0.05, 0.05])
    r = analyze(lifted_system(t, lengths(t, R, 0), R @ ATTACH[0]), SIGMA)
    assert not r["observable"] and r["excitation_m"] < 3 * SIGMA
    assert "too small to tell the offset from the distance to the pulley" in verdict(0, r)


def test_lengths_that_fit_far_worse_than_the_encoder_noise_are_judged_at_their_residual_level(rng):
    """The real-robot case: every cable "observable" at the encoder's 1 mm while the model missed by more.
    Lengths 8 mm off the rigid model (a swinging, sagging robot would do it): the fit's rms is reported,
    and a motion that excites the weakest direction by about 5 mm -- enough for 1 mm, not for 8 -- is no
    longer called observable; a large motion (0.8 m) still is, with the warning."""
    t, R = trajectory(rng, 300, [0.3, 0.3, 0.3])
    clean = analyze(lifted_system(t, lengths(t, R, 0) + rng.normal(0, SIGMA, 300), R @ ATTACH[0]), SIGMA)
    assert clean["observable"] and clean["fit_rms_m"] < 1.2 * SIGMA and clean["judged_at_m"] == SIGMA
    assert 3 * SIGMA < clean["excitation_m"] < 3 * 0.008  # measured 5.4 mm
    z = lengths(t, R, 0) + rng.normal(0, 0.008, 300)
    r = analyze(lifted_system(t, z, R @ ATTACH[0]), SIGMA)
    assert not r["observable"] and 0.007 < r["fit_rms_m"] < 0.009 and r["judged_at_m"] == r["fit_rms_m"]
    text = verdict(0, r)
    assert text.startswith(f"cable 0: the lengths fit this motion to {r['fit_rms_m'] * 1e3:.1f} mm rms, more than 2 "
                           "encoder sigmas: the model misses something") and "NOT observable" in text
    t, R = trajectory(rng, 300, [0.8, 0.8, 0.8])
    big = analyze(lifted_system(t, lengths(t, R, 0) + rng.normal(0, 0.008, 300), R @ ATTACH[0]), SIGMA)
    assert big["observable"] and "the model misses something" in verdict(0, big)


# --- the diagnostic in a run -----------------------------------------------------------------
CDPR = {"name": "cdpr_test", "summary": "4-cable test robot", "model": "cdpr", "frames": ["base", "end_effector"],
        "sensors": {"encoders": {"type": "cable_length_encoders", "frame": "base"}},
        "cables": {"attachments": ATTACH.tolist()},
        "parameters": {"pulley": {"type": "point3", "values": (PULLEYS + 0.05).tolist(), "sigma": 0.5},
                       "offset": {"type": "scalar", "values": (OFFSETS + 0.02).tolist(), "sigma": 0.5}}}


def write_run(workspace, rng, extent):
    n = 120
    tt = np.arange(n) * 0.1
    t, R = trajectory(rng, n, extent, tilt_deg=0.0, yaw_deg=0.0)
    poses = [gtsam.Pose3(gtsam.Rot3(Ri), ti) for Ri, ti in zip(R, t)]
    cols = {f"l{i}": lengths(t, R, i) + rng.normal(0, SIGMA, n) for i in range(4)}
    (workspace.folder / "cdpr.yaml").write_text(yaml.safe_dump(CDPR, sort_keys=False))
    return workspace.config({
        "name": "cable_observability",
        "robots": {"ee": {"description": "cdpr.yaml", "states": {"stream": "mocap"}}},
        "sources": [workspace.poses("mocap", tt, poses), workspace.columns("enc", tt, **cols)],
        "factors": [{"type": "pose.absolute", "robot": "ee", "stream": "mocap",
                     "sigma": {"rotation": 0.002, "translation": 0.001}},
                    {"type": "cable.length", "robot": "ee", "stream": "enc", "sigma": SIGMA}],
        "initializers": [{"type": "pose.interpolate", "robot": "ee", "stream": "mocap"}],
        "solver": {"type": "batch", "method": "lm"}})


LABEL = "factors[1]:cable.length"


def test_validate_and_run_report_the_diagnostic(workspace, rng, capsys, tmp_path):
    path = write_run(workspace, rng, [0.5, 0.5, 0.5])
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    lines = [ln for ln in out.splitlines() if ln.startswith(f"    {LABEL}: cable ")]  # in the identifiability section
    assert len(lines) == 4 and all(": observable (rank 5/5, condition " in ln for ln in lines)
    assert out.index("  identifiability at the initial values") < out.index(lines[0])

    result = fusionkit.run(path)
    diag = result.problem.diagnostics[LABEL]
    assert [c["cable"] for c in diag["cables"]] == [0, 1, 2, 3]
    for c in diag["cables"]:
        assert c["observable"] and (c["rank"], c["unknowns"]) == (5, 5) and c["condition"] < 200
        assert min(c["extent_m"]) > 0.9 and len(c["weakest_direction"]) == 3
    pulley = result.parameters["ee"]["pulley"]  # the calibration the diagnostic vouches for
    err = np.array(pulley.values) - PULLEYS
    assert np.abs(err).max() < 0.03 and np.all(np.abs(err) < 4 * pulley.sigma)

    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["diagnostics"][LABEL]["verdict"] == diag["verdict"]
    assert report["identifiability"]["analyses"][LABEL] == diag["verdict"]  # an instance of the same report
    assert "cable 0: observable (rank 5/5" in capsys.readouterr().out


def test_validate_flags_planar_motion(workspace, rng, capsys):
    path = write_run(workspace, rng, [0.5, 0.5, 0.0])
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    flagged = [ln for ln in out.splitlines() if "NOT observable" in ln]
    assert len(flagged) == 4
    assert all("does not excite it along z (" in ln and "along z (up/down) as well" in ln for ln in flagged)


@pytest.mark.parametrize("extent, expect", [([0.5, 0.5, 0.5], "observable (rank 6/6"),
                                            ([0.5, 0.0, 0.5], "does not excite it along y (")])
def test_monocular_vo_adds_the_scale_unknown(workspace, rng, capsys, extent, expect):
    """ARAS-CAM setting: VO up to scale (pose.scaled_relative) + encoders, no motion capture: the
    diagnostic checks the six unknowns of eq. 4.7 (s a, s^2, l0, |a|^2 - l0^2)."""
    n, s = 120, 2.5
    t = trajectory(rng, n, extent, tilt_deg=0.0, yaw_deg=0.0)[0]
    t -= t[0]  # VO starts at the origin of the base frame (the user's zero pose)
    tt = np.arange(n) * 0.1
    pulleys = PULLEYS - [0.0, 0.0, 1.2]
    cols = {f"l{i}": np.linalg.norm(t + ATTACH[i] - pulleys[i], axis=1) + OFFSETS[i] for i in range(4)}
    desc = {**CDPR, "parameters": {**CDPR["parameters"], "vo_scale": {"type": "scalar", "value": 2.0, "sigma": 10.0}}}
    (workspace.folder / "cdpr.yaml").write_text(yaml.safe_dump(desc, sort_keys=False))
    path = workspace.config({
        "name": "cable_vo",
        "robots": {"ee": {"description": "cdpr.yaml", "states": {"stream": "vo"}}},
        "sources": [workspace.poses("vo", tt, [gtsam.Pose3(gtsam.Rot3(), ti / s) for ti in t]),
                    workspace.columns("enc", tt, **cols)],
        "factors": [{"type": "pose.origin", "robot": "ee", "sigma": {"rotation": 0.001, "translation": 0.001}},
                    {"type": "pose.scaled_relative", "robot": "ee", "stream": "vo", "scale": "vo_scale",
                     "sigma": {"rotation": 0.002, "translation": 0.002}},
                    {"type": "cable.length", "robot": "ee", "stream": "enc", "sigma": SIGMA}],
        "initializers": [{"type": "pose.dead_reckoning", "robot": "ee", "stream": "vo", "scale": "vo_scale"}]})
    assert main(["validate", str(path)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("    factors[2]:cable.length: cable")]
    assert len(lines) == 4 and all(expect in ln for ln in lines), lines
