"""The 3-D scene of a run (scene.json) and `fusionkit view`: what the scene holds (trajectories, point
parameters with 3-sigma ellipsoids, the cable robot drawing itself through RobotModel.geometry), the PNG
written by matplotlib when open3d is missing or crashes, and the refusals (existing file, not an output)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

import fusionkit.view as view
from fusionkit.cli.main import main
from fusionkit.view.scene import FRAMES, SCENE_FILE

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("view") / "quick"
    assert main(["run", str(REPO / "configs" / "quickstart.yaml"), "--out", str(out), "-q",
                 "--set", "sources.0.params.duration=8"]) == 0
    return out


def _scene(folder: Path) -> dict:
    return json.loads((folder / SCENE_FILE).read_text())


def _by_label(shapes: list[dict], label: str) -> list[dict]:
    return [s for s in shapes if s["label"] == label]


def test_the_scene_holds_the_trajectories_the_pulleys_with_3_sigma_ellipsoids_and_their_truth(run_folder):
    scene = _scene(run_folder)
    report = json.loads((run_folder / "report.json").read_text())
    est = _by_label(scene["trajectories"], "cdpr estimate")[0]
    traj = np.loadtxt(run_folder / "trajectories" / "cdpr.tum")
    np.testing.assert_allclose(np.asarray(est["segments"])[:, 0], traj[:-1, 1:4], atol=1e-9)
    assert _by_label(scene["trajectories"], "cdpr truth")
    pulley = report["parameters"]["cdpr"]["pulley"]
    np.testing.assert_allclose(_by_label(scene["static"], "cdpr/pulley")[0]["xyz"], pulley["values"], atol=1e-9)
    # the ellipsoid's semi-axes A (columns) give back the 3-sigma covariance: A A^T = 9 Sigma, whose diagonal
    # is 9 sigma^2 per axis
    A = np.asarray(_by_label(scene["static"], "cdpr/pulley[2] 3-sigma")[0]["axes"])
    np.testing.assert_allclose(np.sqrt(np.diag(A @ A.T)), 3 * np.asarray(pulley["sigma"][2]), rtol=1e-6)
    assert np.abs(A @ A.T - np.diag(np.diag(A @ A.T))).max() > 0  # oriented: the pulleys' x-z correlation
    assert len(_by_label(scene["static"], "cdpr/pulley truth")[0]["xyz"]) == 4


def test_the_cable_robot_draws_its_cables_from_each_pulley_to_its_attachment_at_each_time(run_folder):
    scene = _scene(run_folder)
    assert len(scene["times"]) == FRAMES == len(scene["frames"])
    pulleys = np.asarray(_by_label(scene["static"], "cdpr/pulley")[0]["xyz"])
    traj = np.loadtxt(run_folder / "trajectories" / "cdpr.tum")
    for k in (0, FRAMES // 2, FRAMES - 1):
        frame = scene["frames"][k]
        cables = np.asarray(_by_label(frame, "cdpr cables")[0]["segments"])
        np.testing.assert_allclose(cables[:, 0], pulleys, atol=1e-9)
        now = np.asarray(_by_label(frame, "cdpr now")[0]["xyz"])[0]
        row = traj[np.argmin(np.abs(traj[:, 0] - scene["times"][k]))]
        np.testing.assert_allclose(now, row[1:4], atol=1e-9)
        # the attachments sit within the end effector's size of its origin (arascam-like: < 0.3 m)
        assert np.linalg.norm(cables[:, 1] - now, axis=1).max() < 0.3
        assert _by_label(frame, "cdpr position 3-sigma")
        x_axis = np.asarray(_by_label(frame, "cdpr body x")[0]["segments"])[0]
        np.testing.assert_allclose(x_axis[0], now, atol=1e-12)
        q = row[4:8]  # qx qy qz qw: the body x axis is the rotation's first column
        R_x = np.array([1 - 2 * (q[1] ** 2 + q[2] ** 2), 2 * (q[0] * q[1] + q[2] * q[3]), 2 * (q[0] * q[2] - q[1] * q[3])])
        direction = (x_axis[1] - x_axis[0]) / np.linalg.norm(x_axis[1] - x_axis[0])
        np.testing.assert_allclose(direction, R_x, atol=1e-6)


def test_report_html_embeds_the_3d_render(run_folder):
    html = (run_folder / "report.html").read_text()
    assert (run_folder / "plots" / "scene_3d.png").stat().st_size > 10_000
    assert "alt='scene_3d.png'" in html


def test_view_png_without_open3d_draws_with_matplotlib_and_says_so(run_folder, tmp_path, monkeypatch, capsys):
    real = importlib.util.find_spec
    monkeypatch.setattr(view.importlib.util, "find_spec", lambda name: None if name == "open3d" else real(name))
    png = tmp_path / "scene.png"
    assert main(["view", str(run_folder), "--png", str(png), "--time", "4.0"]) == 0
    out = capsys.readouterr().out
    assert "open3d is not installed" in out and "drawn with matplotlib" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_an_open3d_process_that_crashes_falls_back_to_matplotlib(run_folder, tmp_path, monkeypatch):
    crash = tmp_path / "crash.py"
    crash.write_text("import os\nos.abort()\n")  # what open3d does without an OpenGL context
    monkeypatch.setattr(view, "RENDERER", crash)
    real = importlib.util.find_spec
    monkeypatch.setattr(view.importlib.util, "find_spec", lambda name: object() if name == "open3d" else real(name))
    png = tmp_path / "scene.png"
    note = view.render_png(run_folder, png)
    assert note.startswith("open3d could not render (exit code") and "drawn with matplotlib" in note
    assert png.stat().st_size > 10_000


def test_view_refuses_to_overwrite_a_file_and_a_folder_without_a_scene(run_folder, tmp_path, capsys):
    mine = tmp_path / "mine.png"
    mine.write_bytes(b"user data")
    assert main(["view", str(run_folder), "--png", str(mine)]) != 0
    assert "exists; fusionkit writes only new files" in capsys.readouterr().err
    assert mine.read_bytes() == b"user data"
    assert main(["view", str(tmp_path), "--png", str(tmp_path / "new.png")]) != 0
    assert "no scene.json" in capsys.readouterr().err
    assert not (tmp_path / "new.png").exists()


def test_render_png_never_replaces_a_file_and_leaves_nothing_behind(run_folder, tmp_path):
    mine = tmp_path / "mine.png"
    mine.write_bytes(b"user data")
    with pytest.raises(ValueError, match="exists; fusionkit writes only new files"):
        view.render_png(run_folder, mine, backend="matplotlib")
    assert mine.read_bytes() == b"user data"
    with pytest.raises(ValueError, match="does not exist"):
        view.render_png(run_folder, tmp_path / "no_such_folder" / "new.png", backend="matplotlib")
    new = tmp_path / "new.png"
    assert view.render_png(run_folder, new, backend="matplotlib") == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.png", "new.png"]  # no temporary file left


@pytest.mark.skipif(importlib.util.find_spec("open3d") is None,
                    reason="open3d is not installed (pip install 'fusionkit[view]'); the matplotlib path is tested")
def test_open3d_renders_the_scene_offscreen(run_folder, tmp_path):
    png = tmp_path / "o3d.png"
    note = view.render_png(run_folder, png, backend="open3d")
    assert png.stat().st_size > 5_000
    assert note == "" or "drawn with matplotlib" in note  # no OpenGL context on this machine: the fallback


def test_the_renderer_script_imports_nothing_of_fusionkit():
    """It runs in its own process, under any python with open3d and numpy."""
    text = (Path(view.__file__).with_name("render_open3d.py")).read_text()
    assert "fusionkit" not in "".join(line for line in text.splitlines() if line.startswith(("import", "from")))


def test_a_serial_arm_draws_its_links_to_the_flange_the_calibrated_kinematics_reach(tmp_path):
    from fusionkit.config.loader import load_config
    from fusionkit.pipeline import estimate
    from fusionkit.report.outputs import calibrated_description
    from fusionkit.view.scene import build_scene
    from fusionkit_plugins.serial_arm.model import arm_of

    result = estimate(load_config(REPO / "configs" / "arm_calibration.yaml"))
    scene = build_scene(result)
    k = len(scene["times"]) // 2
    tool = np.asarray(_by_label(scene["frames"][k], "arm tool")[0]["xyz"])[0]
    links = np.asarray(_by_label(scene["frames"][k], "arm links")[0]["segments"])
    np.testing.assert_allclose(links[-1, 1], tool, atol=1e-12)
    desc = calibrated_description(result, "arm")
    arm = arm_of(desc)
    series = [s for (robot, _), s in result.states.items() if robot == "arm"][0]
    q = np.asarray(series.values[int(np.argmin(np.abs(series.t - scene["times"][k])))], float).copy()
    for group in arm.offsets:
        q[list(group.joints)] += np.asarray(desc.parameters[group.parameter].values, float).ravel()
    base = desc.parameters[arm.base]
    flange = base.vartype.from_list(base.values[0]).matrix() @ arm.chain.flange(q).T
    np.testing.assert_allclose(tool, flange[:3, 3], atol=1e-9)


def test_a_wall_map_draws_its_walls_on_the_floor_once():
    from fusionkit.config.loader import load_config
    from fusionkit.pipeline import estimate
    from fusionkit.view.scene import build_scene
    from fusionkit_plugins.epuck.model import walls_of

    config = load_config(REPO / "configs" / "epuck_localization.yaml", ["sources.0.params.duration=5"])
    scene = build_scene(estimate(config))
    walls = np.asarray(_by_label(scene["static"], "arena walls")[0]["segments"])
    expected = walls_of(config.robots["arena"].description)
    np.testing.assert_allclose(walls[:, :, :2], expected)
    assert np.all(walls[:, :, 2] == 0)
    assert not any(_by_label(frame, "arena walls") for frame in scene["frames"])
