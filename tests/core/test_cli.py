"""The `fusionkit` command line on good input: validate, run, --set, plugins, simulate."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.data.files import read_tum

REPO = Path(__file__).resolve().parents[2]
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
FAST = ["--set", "sources.0.params.duration=5"]


def test_validate_scaled_vo_prints_stream_and_factor_counts(capsys):
    assert main(["validate", str(SCALED_VO), *FAST]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    lines = captured.out.splitlines()
    assert lines[0] == f"{SCALED_VO}: OK"
    pose_columns = "columns x, y, z, qx, qy, qz, qw"
    # 5 s at 30 Hz -> 150 VO frames; motion capture every 2 s -> t = 0, 2, 4
    assert f"  stream vo: 150 samples, t = 0.000 .. 4.967 s, {pose_columns}" in lines
    assert f"  stream mocap: 3 samples, t = 0.000 .. 4.000 s, {pose_columns}" in lines
    assert "  robot cam: 150 states" in lines
    assert "  prior:cam/vo_scale: 1 factors" in lines
    assert "  factors[0]:pose.scaled_relative: 149 factors" in lines
    assert "  factors[1]:pose.absolute: 3 factors" in lines
    assert "  151 variables, 153 factors; every variable is constrained" in lines


def test_validate_full_scaled_vo_counts_750_vo_samples_and_751_variables(capsys):
    assert main(["validate", str(SCALED_VO)]) == 0
    out = capsys.readouterr().out
    assert "  stream vo: 750 samples, t = 0.000 .. 24.967 s" in out
    assert "  stream mocap: 13 samples, t = 0.000 .. 24.000 s" in out
    assert "  751 variables, 763 factors; every variable is constrained" in out


def test_run_scaled_vo_writes_the_outputs_and_recovers_the_scale_within_0_5(tmp_path, capsys):
    out = tmp_path / "result"
    assert main(["run", str(SCALED_VO), *FAST, "--out", str(out), "--no-plots"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    assert captured.out.startswith("fusionkit: scaled_vo_mocap: batch-lm, ")
    assert f"  outputs: {out}/" in captured.out
    assert sorted(p.name for p in out.iterdir()) == [".fusionkit-output", "calibration.yaml", "report.html",
                                                     "report.json", "scene.json", "trajectories"]
    assert [p.name for p in tmp_path.iterdir()] == ["result"]  # no temporary folder left beside it
    report = json.loads((out / "report.json").read_text())
    assert report["name"] == "scaled_vo_mocap"
    assert report["problem"]["factors"] == 153 and report["problem"]["variables"] == 151
    assert report["problem"]["states"] == {"cam": 150}
    assert report["solver"]["solver"] == "batch-lm"
    assert report["final_cost"] < report["solver"]["initial_cost"]
    scale = report["parameters"]["cam"]["vo_scale"]
    assert scale["type"] == "scalar" and scale["sigma"] > 0
    assert abs(scale["value"] - 2.5) < 0.5  # the simulator's true scale; the prior alone says 1.0 +- 10
    calibration = yaml.safe_load((out / "calibration.yaml").read_text())
    assert calibration["robots"]["cam"]["vo_scale"]["value"] == pytest.approx(scale["value"], rel=1e-12)
    trajectory = read_tum(out / "trajectories" / "cam.tum", "cam")
    assert len(trajectory) == 150
    assert trajectory.t[-1] == pytest.approx(149 / 30, abs=1e-6)


@pytest.mark.parametrize("solver, name", [("isam2", "isam2"), ("batch", "batch-gn")])
def test_solver_type_override_selects_the_solver_and_recovers_the_scale_within_0_5(tmp_path, capsys, solver, name):
    out = tmp_path / "o"
    extra = ["--set", "solver.method=gn"] if name == "batch-gn" else []
    assert main(["run", str(SCALED_VO), *FAST, "--set", f"solver.type={solver}", *extra, "--out", str(out),
                 "--no-plots"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["solver"]["solver"] == name
    assert abs(report["parameters"]["cam"]["vo_scale"]["value"] - 2.5) < 0.5


def test_set_looser_vo_rotation_sigma_lowers_the_final_cost(tmp_path, capsys):
    """A looser VO rotation sigma (0.01 instead of 0.002) gives a smaller final cost on the same data."""
    costs = []
    for sigma in ("0.002", "0.01"):
        out = tmp_path / sigma
        assert main(["run", str(SCALED_VO), *FAST, "--set", f"factors.0.sigma.rotation={sigma}",
                     "--out", str(out), "--no-plots"]) == 0
        costs.append(json.loads((out / "report.json").read_text())["final_cost"])
    assert costs[1] < costs[0]


def test_plugins_lists_what_is_installed(capsys):
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert "fusionkit.data.builtin_sources" in lines and "fusionkit.descriptions.generic" in lines
    for kind, name in [("source", "csv"), ("source", "tum"), ("source", "simulate"), ("robot model", "generic"),
                       ("factor type", "pose.absolute"), ("factor type", "pose.scaled_relative"),
                       ("initializer", "pose.dead_reckoning"), ("simulator", "pose.scaled_vo")]:
        assert any(line.split()[:len(kind.split()) + 1] == [*kind.split(), name] for line in lines), (kind, name)


def test_plugins_json_lists_sources_with_summary_and_schema_and_every_builtin_name(capsys):
    assert main(["plugins", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    sources = {item["name"]: item for item in listing["fusionkit.data.builtin_sources"]["sources"]}
    assert set(sources) >= {"csv", "tum", "simulate"}
    assert sources["tum"]["summary"] == "TUM trajectory: t x y z qx qy qz qw per line (poses; several files: recordings)"
    assert sources["csv"]["schema"]["required"] == ["name", "path"]
    names = {item["name"] for provided in listing.values() for items in provided.values() for item in items}
    assert {"generic", "pose.absolute", "pose.scaled_relative", "pose.scale_from_absolute",
            "pose.scaled_vo"} <= names


def test_simulate_writes_a_dataset_whose_config_recovers_the_scale_within_3_sigma(tmp_path, capsys):
    data = tmp_path / "sim"
    assert main(["simulate", "pose.scaled_vo", "--out", str(data)]) == 0
    out = capsys.readouterr().out
    assert out == f"wrote 6 files to {data}/; run it with: fusionkit run {data / 'config.yaml'}\n"
    files = sorted(str(p.relative_to(data)) for p in data.rglob("*") if p.is_file())
    assert files == [".fusionkit-output", "config.yaml", "data/mocap.tum", "data/vo.tum", "robots/cam.yaml", "truth/calibration.yaml",
                     "truth/cam.tum"]
    config = yaml.safe_load((data / "config.yaml").read_text())
    assert config["sources"] == [{"type": "tum", "name": "vo", "path": "data/vo.tum"},
                                 {"type": "tum", "name": "mocap", "path": "data/mocap.tum"}]
    assert config["truth"] == {"trajectories": {"cam": "truth/cam.tum"}, "calibration": "truth/calibration.yaml"}
    truth_scale = yaml.safe_load((data / "truth" / "calibration.yaml").read_text())["robots"]["cam"]["vo_scale"]
    assert truth_scale["value"] == 2.5
    assert len(read_tum(data / "data" / "vo.tum", "vo")) == 750  # 25 s at 30 Hz

    result = tmp_path / "result"
    assert main(["run", str(data / "config.yaml"), "--out", str(result), "--no-plots"]) == 0
    report = json.loads((result / "report.json").read_text())
    estimate = report["parameters"]["cam"]["vo_scale"]
    assert abs(estimate["value"] - 2.5) < 3 * estimate["sigma"]
    z = report["evaluation"]["parameters"]["cam"]["vo_scale"]["z_per_axis"][0][0]
    assert abs(z) < 3 and z == pytest.approx((estimate["value"] - 2.5) / estimate["sigma"], rel=1e-6)
    assert report["evaluation"]["trajectories"]["cam"]["matched_poses"] == 750
    assert report["evaluation"]["trajectories"]["cam"]["ate_rmse_m"] < 0.1


def test_simulate_set_duration_13_rate_10_gives_130_frames_and_mocap_every_6_s(tmp_path, capsys):
    data = tmp_path / "sim"
    assert main(["simulate", "pose.scaled_vo", "--out", str(data), "--seed", "3", "--set", "duration=13",
                 "--set", "rate=10"]) == 0
    vo = read_tum(data / "data" / "vo.tum", "vo")
    assert len(vo) == 130
    np.testing.assert_allclose(vo.t[:3], [0.0, 0.1, 0.2], atol=1e-9)
    mocap = read_tum(data / "data" / "mocap.tum", "mocap")
    np.testing.assert_allclose(mocap.t, [0.0, 6.0, 12.0], atol=1e-9)  # every 60th frame
    assert main(["validate", str(data / "config.yaml")]) == 0
    assert "  robot cam: 130 states" in capsys.readouterr().out


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-m", "fusionkit.cli.main", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=300, check=False)


@pytest.mark.slow
def test_subprocess_validate_and_run_exit_0_silently_and_write_to_out_config_name(tmp_path):
    proc = _cli("validate", str(SCALED_VO), *FAST, cwd=tmp_path)
    assert proc.returncode == 0 and proc.stderr == ""
    assert "151 variables, 153 factors; every variable is constrained" in proc.stdout
    proc = _cli("run", str(SCALED_VO), *FAST, "--no-plots", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    assert (tmp_path / "out" / "scaled_vo_mocap" / "report.json").is_file()  # default: out/<config name>


def test_version_and_simulate_help_list_every_installed_scenario_with_its_parameters(capsys):
    import fusionkit
    from fusionkit.plugins import registry
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and capsys.readouterr().out == f"fusionkit {fusionkit.__version__}\n"
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = capsys.readouterr().out
    reg = registry()
    for name in reg.names("simulators"):
        cls = reg.get("simulators", name)
        assert f"  {name:<18} {cls.summary}" in text
        for key in cls.schema.get("properties", {}):
            assert f"{key}=" in text or f"{key} (required)" in text, (name, key)
    assert "duration=25.0" in text  # pose.scaled_vo's default duration


def test_debug_and_quiet_are_accepted_after_the_command(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("robots: {}\n")
    assert main(["validate", str(bad)]) == 2  # without --debug: one line
    capsys.readouterr()
    from fusionkit.errors import ConfigError
    with pytest.raises(ConfigError):  # --debug after the command re-raises (the traceback is shown)
        main(["validate", "--debug", str(bad)])
    with pytest.raises(ConfigError):
        main(["--debug", "validate", str(bad)])
    assert main(["run", str(SCALED_VO), *FAST, "-q", "--no-plots", "--out", str(tmp_path / "o")]) == 0
    assert capsys.readouterr().err == ""


def test_status_line_shows_the_stage_and_iterations_once_work_takes_long(monkeypatch):
    import io
    import time

    from rich.console import Console

    import fusionkit.progress
    monkeypatch.setattr(fusionkit.progress, "SHOW_AFTER_S", 0.05)
    stream = io.StringIO()
    with fusionkit.progress.StatusLine(Console(file=stream, force_terminal=True, width=100)) as status:
        status.stage("quick")  # over before the line appears: nothing is shown
        status.stage("solving (batch)")
        waited = 0.0
        while not status._started and waited < 10:  # the line appears after SHOW_AFTER_S, however loaded
            time.sleep(0.05)
            waited += 0.05
        status(3, 12.5)
        time.sleep(0.3)  # rich redraws the line a few times a second
    shown = stream.getvalue()
    assert "solving (batch): iteration 3, cost 12.5" in shown and "quick" not in shown
