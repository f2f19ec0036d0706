"""Every bad input gives exactly one line on stderr that names the file and the key path or line, says what
was wrong and what is accepted; a non-zero exit; no traceback; and no output folder (not even a partial one)."""

from __future__ import annotations

import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.errors import SolverError
from fusionkit.solve.checks import check_solution

REPO = Path(__file__).resolve().parents[2]
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
ROBOT = REPO / "robots" / "pose" / "handheld_camera.yaml"
FAST = ["--set", "sources.0.params.duration=5"]
PREFIX = "fusionkit: error: "


# ---------------------------------------------------------------- helpers


def fails(capsys, argv: list[str], *needles: str, out: Path | None = None) -> str:
    """Run the CLI in-process; assert exit 2, one stderr line with every needle, no output folder."""
    code = main(argv)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2, captured.err
    assert len(lines) == 1, captured.err
    line = lines[0]
    assert line.startswith(PREFIX), line
    assert "Traceback" not in captured.err and "internal error" not in line
    for needle in needles:
        assert needle in line, f"{needle!r} not in {line!r}"
    if out is not None:
        assert not out.exists(), f"{out} was created"
        leftovers = [p.name for p in out.parent.iterdir() if p.name.startswith(f".{out.name}")]
        assert leftovers == [], leftovers
    return line[len(PREFIX):]


def line_of(path: Path, text: str, start: int = 1) -> int:
    """1-based number of the first line (from `start`) of `path` that contains `text`."""
    for n, line in enumerate(path.read_text().splitlines(), start=1):
        if n >= start and text in line:
            return n
    raise AssertionError(f"{text!r} not in {path}")


def rewrite(path: Path, old: str, new: str) -> Path:
    text = path.read_text()
    assert old in text, old
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.fixture
def out(tmp_path) -> Path:
    return tmp_path / "out"


def run(config: Path, out: Path, *extra: str) -> list[str]:
    return ["run", str(config), "--out", str(out), "--no-plots", *extra]


def scaled_vo_copy(tmp_path: Path) -> Path:
    """configs/scaled_vo_mocap.yaml with a copy of the shipped handheld_camera description beside it,
    named by its path (../robots/handheld_camera.yaml): a user's own description file."""
    (tmp_path / "configs").mkdir(parents=True)
    (tmp_path / "robots").mkdir()
    shutil.copy(ROBOT, tmp_path / "robots")
    config = Path(shutil.copy(SCALED_VO, tmp_path / "configs" / "scaled_vo_mocap.yaml"))
    return rewrite(config, "description: handheld_camera", "description: ../robots/handheld_camera.yaml")


def csv_dataset(ds: Path, text: str | None = None, columns: list[str] | None = None) -> Path:
    """Replace the mocap TUM source by a stream CSV (`text`, default: the same poses as CSV)."""
    if text is None:
        rows = [line.split() for line in (ds / "data" / "mocap.tum").read_text().splitlines()
                if not line.startswith("#")]
        text = "t,x,y,z,qx,qy,qz,qw\n" + "".join(",".join(r) + "\n" for r in rows)
    (ds / "data" / "mocap.csv").write_text(text)
    config = yaml.safe_load((ds / "config.yaml").read_text())
    config["sources"][1] = {"type": "csv", "name": "mocap", "path": "data/mocap.csv",
                            **({"columns": columns} if columns else {})}
    (ds / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return ds / "config.yaml"


def test_the_simulated_dataset_validates_and_runs_also_with_csv_mocap(ds, out, capsys):
    """The baseline the other tests break: it validates and runs."""
    assert main(["validate", str(ds / "config.yaml")]) == 0
    assert "  stream mocap: 3 samples" in capsys.readouterr().out
    assert main(run(ds / "config.yaml", out)) == 0
    assert (out / "report.json").is_file()
    csv_config = csv_dataset(ds)
    assert main(["validate", str(csv_config)]) == 0


# ---------------------------------------------------------------- 1. missing or unreadable files


def test_missing_config_says_file_not_found(tmp_path, out, capsys):
    config = tmp_path / "nope.yaml"
    assert fails(capsys, run(config, out), out=out) == f"{config}: file not found"


def test_config_that_is_a_folder_or_not_text_says_why_it_cannot_be_read(tmp_path, out, capsys):
    (tmp_path / "folder.yaml").mkdir()
    message = fails(capsys, run(tmp_path / "folder.yaml", out), out=out)
    assert message.startswith(f"{tmp_path / 'folder.yaml'}: cannot read file (IsADirectoryError")
    (tmp_path / "binary.yaml").write_bytes(b"name: \xff\xfe\n")
    message = fails(capsys, run(tmp_path / "binary.yaml", out), out=out)
    assert message.startswith(f"{tmp_path / 'binary.yaml'}: cannot read file (UnicodeDecodeError")


def test_config_without_read_permission_says_permission_denied(tmp_path, out, capsys, monkeypatch):
    config = scaled_vo_copy(tmp_path)
    original = pathlib.Path.read_text

    def read_text(self, *args, **kwargs):  # chmod 000 does not stop root, so refuse the read here
        if self == config:
            raise PermissionError(13, "Permission denied", str(self))
        return original(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "read_text", read_text)
    assert fails(capsys, run(config, out), out=out) == \
        f"{config}: cannot read file (PermissionError: [Errno 13] Permission denied: '{config}')"


def test_missing_robot_description_is_located_at_its_config_line(ds, out, capsys):
    config = rewrite(ds / "config.yaml", "robots/cam.yaml", "robots/camera.yaml")
    line = line_of(config, "description:")
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{line}: robots.cam.description: robot description file not found: {ds / 'robots' / 'camera.yaml'}")


def test_missing_data_file_is_located_at_its_config_line(ds, out, capsys):
    config = rewrite(ds / "config.yaml", "path: data/mocap.tum", "path: data/mocap2.tum")
    line = line_of(config, "path: data/mocap2.tum")
    assert fails(capsys, run(config, out), out=out) == \
        f"{config}:{line}: sources[1].path: file not found: {ds / 'data' / 'mocap2.tum'}"


def test_data_file_that_is_not_text_names_its_line_and_byte(ds, out, capsys):
    (ds / "data" / "vo.tum").write_bytes(b"# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n\xff\xfe\n")
    assert fails(capsys, run(ds / "config.yaml", out), out=out) == \
        f"{ds / 'data' / 'vo.tum'}:3: cannot read: byte 38 is not UTF-8 text; expected a text file"


@pytest.mark.parametrize("key, old, new", [
    ("truth.trajectories.cam", "cam: truth/cam.tum", "cam: truth/camera.tum"),
    ("truth.calibration", "calibration: truth/calibration.yaml", "calibration: truth/cal.yaml"),
])
def test_missing_truth_file_is_located_at_its_config_line(ds, out, capsys, key, old, new):
    config = rewrite(ds / "config.yaml", old, new)
    line = line_of(config, new)
    missing = ds / new.split(": ")[1]
    assert fails(capsys, run(config, out), out=out) == f"{config}:{line}: {key}: file not found: {missing}"


def test_validate_reports_missing_files_too(ds, capsys):
    config = rewrite(ds / "config.yaml", "path: data/vo.tum", "path: data/none.tum")
    fails(capsys, ["validate", str(config)], f"{config}:", "sources[0].path: file not found:", "none.tum")


# ---------------------------------------------------------------- 2. YAML syntax errors


def test_yaml_syntax_error_in_config_names_its_line(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "solver: {type: batch, method: lm}", "solver: {type: batch, method: lm")
    line = len(config.read_text().splitlines()) + 1  # the flow mapping is still open at the end of the file
    assert fails(capsys, run(config, out), out=out) == \
        f"{config}:{line}: YAML syntax error: expected ',' or '}}', but got '<stream end>'"


def test_yaml_bad_indentation_in_config_names_its_line(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "    states: {stream: vo}", "   states: {stream: vo}")
    line = line_of(config, "   states: {stream: vo}")
    message = fails(capsys, run(config, out), out=out)
    assert message.startswith(f"{config}:{line}: YAML syntax error: ")


def test_yaml_syntax_error_in_robot_description_names_its_line(ds, out, capsys):
    robot = rewrite(ds / "robots" / "cam.yaml", "vo_scale:", "vo_scale: [")
    # `type: scalar` still parses as a one-pair mapping inside the flow list; the next key is the error
    line = line_of(robot, "value: 1.0")
    assert fails(capsys, run(ds / "config.yaml", out), out=out) == \
        f"{robot}:{line}: YAML syntax error: expected ',' or ']', but got ':'"


def test_duplicate_key_names_both_lines(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "seed: 7", "seed: 7\n    seed: 8")
    first, second = line_of(config, "seed: 7"), line_of(config, "seed: 8")
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{second}: sources[0].seed: duplicate key 'seed' (first on line {first}); "
        "each key may appear once in a mapping")


# ---------------------------------------------------------------- 3. unknown keys and plugin types


def test_unknown_top_level_key_lists_the_accepted_keys(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "solver: {", "solvr: {")
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{line_of(config, 'solvr:')}: solvr: unknown key 'solvr'; accepted keys: factors, initializers, "
        "name, output, robots, seed, solver, sources, truth")


def test_unknown_factor_key_lists_the_accepted_keys(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "    sensor: marker\n", "    sensor: marker\n    sigmaa: 1\n")
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{line_of(config, 'sigmaa')}: factors[1].sigmaa: unknown key 'sigmaa'; accepted keys: label, "
        "noise_scale, robot, robust, sensor, sigma, stream, time_offset, tolerance, type")


def test_unknown_key_in_robot_description_lists_the_accepted_keys(ds, out, capsys):
    robot = rewrite(ds / "robots" / "cam.yaml", "frames:", "framez:")
    assert fails(capsys, run(ds / "config.yaml", out), out=out) == (
        f"{robot}:{line_of(robot, 'framez')}: framez: unknown key 'framez'; accepted keys: frames, model, name, "
        "parameters, sensors, summary")


@pytest.mark.parametrize("old, new, key, kind", [
    ("type: pose.absolute ", "type: pose.absolut ", "factors[1].type", "factor type 'pose.absolut'"),
    ("type: simulate", "type: simulated", "sources[0].type", "source 'simulated'"),
    ("type: pose.dead_reckoning", "type: pose.reckoning", "initializers[1].type", "initializer 'pose.reckoning'"),
])
def test_unknown_plugin_type_lists_installed(tmp_path, out, capsys, old, new, key, kind):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, old, new)
    message = fails(capsys, run(config, out), out=out)
    assert message.startswith(f"{config}:{line_of(config, new)}: {key}: unknown {kind}; installed: ")
    assert message.endswith(" (see `fusionkit plugins`)")
    installed = {"factors": ["pose.absolute", "pose.relative", "pose.scaled_relative", "pose.origin"],
                 "sources": ["csv", "tum", "simulate", "rosbag"],
                 "initializers": ["pose.dead_reckoning", "pose.scale_from_absolute", "pose.interpolate"]}
    for name in installed[key.split("[")[0]]:
        assert name in message


def test_unknown_scenario_and_robot_model_list_the_installed_ones(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "scenario: pose.scaled_vo", "scenario: pose.scaled")
    message = fails(capsys, run(config, out), out=out)
    assert message.startswith(f"{config}:{line_of(config, 'scenario')}: sources[0].scenario: unknown scenario "
                              "'pose.scaled'; installed: ")
    assert "pose.scaled_vo" in message and "pose.two_robots" in message
    config = scaled_vo_copy(tmp_path / "b")
    robot = rewrite(tmp_path / "b" / "robots" / "handheld_camera.yaml", "model: generic", "model: humanoid")
    shown = tmp_path / "b" / "configs" / ".." / "robots" / "handheld_camera.yaml"
    message = fails(capsys, run(config, out), out=out)
    assert message.startswith(f"{shown}:{line_of(robot, 'model:')}: model: unknown robot model 'humanoid'; installed: ")
    assert message.endswith(" (see `fusionkit plugins`)")
    assert "generic" in message.split("installed: ")[1].removesuffix(" (see `fusionkit plugins`)").split(", ")


def test_simulate_bad_scenario_or_parameter_says_what_is_accepted(tmp_path, capsys):
    target = tmp_path / "sim"
    message = fails(capsys, ["simulate", "pose.nope", "--out", str(target)], out=target)
    assert message.startswith("unknown scenario 'pose.nope'; installed: ")
    assert re.search(r"cable\.cdpr, cable\.sag_static, (\S+, )*pose\.scaled_vo, pose\.two_robots", message)  # sorted
    assert fails(capsys, ["simulate", "pose.scaled_vo", "--out", str(target), "--set", "durations=3"], out=target) == (
        "<simulate pose.scaled_vo>: durations: unknown key 'durations'; accepted keys: duration, marker_offset, "
        "mocap_every, mocap_sigma, rate, scale, vo_sigma")
    assert fails(capsys, ["simulate", "pose.scaled_vo", "--out", str(target), "--set", "duration=abc"], out=target) \
        == "<simulate pose.scaled_vo>: duration: got 'abc'; expected a number > 0"


# ---------------------------------------------------------------- 4. missing or mistyped parameters


@pytest.mark.parametrize("old, new, key, what", [
    ("{rotation: 0.002, translation: 0.0016}", '{rotation: "abc", translation: 0.004}', "factors[0].sigma.rotation",
     "got 'abc'; expected a number > 0"),
    ("{rotation: 0.002, translation: 0.0016}", "{rotation: -1, translation: 0.004}", "factors[0].sigma.rotation",
     "got -1; expected a number > 0"),
    ("{rotation: 0.002, translation: 0.0016}", "{rotation: .nan, translation: 0.004}", "factors[0].sigma.rotation",
     "got nan; expected a number > 0"),
    ("{rotation: 0.002, translation: 0.0016}", "{rotation: 0.002}", "factors[0].sigma",
     "'translation' is required but missing (expected a number > 0)"),
    ("{rotation: 0.01, translation: 0.01}", "0.01", "factors[1].sigma",
     "got 0.01; expected a mapping with keys rotation, translation"),
    ("duration: 25.0", "duration: ten", "sources[0].params.duration", "got 'ten'; expected a number > 0"),
    ("seed: 7", "seed: 7.5", "sources[0].seed", "got 7.5; expected an integer"),
])
def test_mistyped_parameter_says_what_is_expected_at_its_line(tmp_path, out, capsys, old, new, key, what):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, old, new)
    assert fails(capsys, run(config, out), out=out) == f"{config}:{line_of(config, new)}: {key}: {what}"


def test_missing_sigma_names_the_factor_line_and_the_expected_keys(tmp_path, out, capsys):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, "    sigma: {rotation: 0.01, translation: 0.01}\n", "")
    line = line_of(config, "type: pose.absolute")
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{line}: factors[1]: 'sigma' is required but missing (expected a mapping with keys rotation, "
        "translation)")


@pytest.mark.parametrize("old, new, at, key, what", [
    ("    sigma: 10.0 ", "    sigma: abc ", "sigma: abc", "parameters.vo_scale.sigma",
     "got 'abc'; expected a number, a list or null"),
    ("    sigma: 10.0 ", "    sigma: -1 ", "sigma: -1", "parameters.vo_scale.sigma",
     "sigmas must be positive and finite (to hold a parameter at its value, write `fixed: true` instead of a sigma)"),
    ("    value: 1.0 ", "    valu: 1.0 ", "valu: 1.0", "parameters.vo_scale.valu",
     "unknown key 'valu'; accepted keys: count, fixed, sigma, summary, time_varying, type, unit, value, values"),
    ("    type: scalar", "    type: scaler", "type: scaler", "parameters.vo_scale.type",
     ("unknown variable type 'scaler'; installed: imu_bias, point2, point3, pose2, pose3, rot3, scalar, velocity3, "
     "vectorN")),
    ("translation: [0.0, 0.0, 0.05]", "translation: [0.0, 0.05]", "translation: [0.0, 0.05]",
     "sensors.marker.mount.translation", "got [0.0, 0.05]; expected a list of 3 numbers"),
])
def test_mistyped_robot_parameter_says_what_is_expected_at_its_line(tmp_path, out, capsys, old, new, at, key, what):
    config = scaled_vo_copy(tmp_path)
    robot = rewrite(tmp_path / "robots" / "handheld_camera.yaml", old, new)
    shown = tmp_path / "configs" / ".." / "robots" / "handheld_camera.yaml"  # as the config spells it
    assert fails(capsys, run(config, out), out=out) == f"{shown}:{line_of(robot, at)}: {key}: {what}"


@pytest.mark.parametrize("old, new, at, key, what", [
    ("    robot: cam\n    stream: mocap", "    robot: camera\n    stream: mocap", "robot: camera", "factors[1].robot",
     "unknown robot 'camera'; the config defines: cam"),
    ("    stream: mocap", "    stream: gps", "stream: gps", "factors[1].stream",
     "unknown stream 'gps'; the sources provide: mocap, vo"),
    ("    sensor: marker", "    sensor: markr", "sensor: markr", "factors[1].sensor",
     "robot 'cam' has no sensor 'markr'; it has: camera, marker"),
    ("anchor: mocap, scale: vo_scale}\n  - {type: pose.dead", "anchor: mocap, scale: scale}\n  - {type: pose.dead",
     "scale: scale}", "initializers[0].scale", "robot 'cam' has no parameter 'scale'; it has: vo_scale"),
])
def test_references_to_unknown_names_list_the_defined_ones(tmp_path, out, capsys, old, new, at, key, what):
    config = scaled_vo_copy(tmp_path)
    rewrite(config, old, new)
    assert fails(capsys, run(config, out), out=out) == f"{config}:{line_of(config, at)}: {key}: {what}"


# ---------------------------------------------------------------- --set overrides


@pytest.mark.parametrize("assignment, message", [
    ("solver.type", "--set 'solver.type': expected key.path=value"),
    ("solver..type=isam2", "--set 'solver..type': empty key in path (expected e.g. solver.type=isam2)"),
    ("factors.5.sigma.rotation=1", ("--set factors.5.sigma.rotation: index 5 out of range (the list has 2 item(s); "
                                   "indices: 0..1)")),
    ("factors.first.sigma=1", ("--set factors.first.sigma: 'first' is not a list index (the list has 2 item(s); "
                              "indices: 0..1)")),
    ("solver.type=[isam2", "--set 'solver.type=[isam2': value is not valid YAML"),
    ("name.first=x", "--set name.first: parent is not a mapping or list"),
])
def test_bad_override_paths_say_why_the_path_is_invalid(out, capsys, assignment, message):
    assert fails(capsys, run(SCALED_VO, out, *FAST, "--set", assignment), out=out) == message


@pytest.mark.parametrize("assignment, key, what", [
    ("solver.type=isam", "solver.type", "got 'isam'; expected one of: batch, isam2, fixed_lag"),
    ("factors.0.sigma.rotation=abc", "factors[0].sigma.rotation", "got 'abc'; expected a number > 0"),
    ("factors[1].sigma.rotation=", "factors[1].sigma.rotation", "got ''; expected a number > 0"),
    ("solver.typo=1", "solver.typo", ("unknown key 'typo'; accepted keys: a_posteriori_sigmas, absolute_tolerance, damping, factorization, lag, "
                                     "marginals, max_cost_ratio, max_iterations, method, new_states, ordering, refine, relative_tolerance, "
                                     "relinearize_marginal_variables, relinearize_skip, relinearize_threshold, type, updates_per_step, warmup")),
    ("solver.refine={vo: {sigma: 1}}", "solver.refine.vo",
     "no factor entry has label 'vo'; labelled entries: (none: give one a label)"),
    ("solver={type: isam2, refine: {vo: {}}}", "solver.refine",
     "only the batch solver refines (a second solve from the first one's estimate)"),
])
def test_bad_override_values_name_the_set(out, capsys, assignment, key, what):
    assert fails(capsys, run(SCALED_VO, out, *FAST, "--set", assignment), out=out) == \
        f"{SCALED_VO}: {key}: {what} (from --set {assignment})"


@pytest.mark.parametrize("refine, key, what", [
    ("{vo: {sigma: {rotation: -1, translation: 0.01}}}", "solver.refine.vo.sigma.rotation",
     "got -1; expected a number > 0"),
    ("{vo: {type: pose.absolute}}", "solver.refine.vo.type", "refine changes settings, not the entry's type"),
])
def test_bad_refine_settings_are_located(out, capsys, refine, key, what):
    """The refined entry is checked like the entry itself, located under solver.refine.<label>."""
    message = fails(capsys, run(SCALED_VO, out, *FAST, "--set", "factors.0.label=vo", "--set",
                                f"solver.refine={refine}"), out=out)
    assert message.startswith(f"{SCALED_VO}: {key}: {what}"), message


# ---------------------------------------------------------------- 5. CSV and TUM data


def test_csv_with_wrong_columns_for_the_factor_names_the_missing_column(ds, out, capsys):
    config = csv_dataset(ds)
    rewrite(ds / "data" / "mocap.csv", "t,x,y,z,qx,qy,qz,qw", "t,x,y,z,qx,qy,qz,w")
    # the factor needs pose columns: the stream's columns are known from the CSV header before reading data
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{line_of(config, 'stream: mocap')}: factors[1].stream: stream 'mocap' (sources[1]: "
        "data/mocap.csv) lacks column(s) qw; it has x, y, z, qx, qy, qz, w")


def test_csv_missing_declared_columns_are_named_at_the_header_line(ds, out, capsys):
    config = csv_dataset(ds, "t,x,y,z,qx,qy,qz,w\n0,0,0,0,0,0,0,1\n",
                         columns=["x", "y", "z", "qx", "qy", "qz", "qw"])
    csv = ds / "data" / "mocap.csv"
    assert fails(capsys, run(config, out), out=out) == (
        f"{csv}:1: missing column(s) qw; header has t,x,y,z,qx,qy,qz,w, expected at least t,x,y,z,qx,qy,qz,qw")


def test_csv_first_column_not_t_is_refused_at_the_header_line(ds, out, capsys):
    config = csv_dataset(ds, "# exported\ntime,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n")
    assert fails(capsys, run(config, out), out=out) == (
        f"{ds / 'data' / 'mocap.csv'}:2: first column is 'time'; expected 't' (time in seconds), "
        "header was time,x,y,z,qx,qy,qz,qw (static samples without times: `time: row` on a csv source numbers the rows)")


def test_csv_with_nan_counts_the_rows_and_names_the_first_line(ds, out, capsys):
    config = csv_dataset(ds, "t,x,y,z,qx,qy,qz,qw\n# motion capture\n0,0,0,0,0,0,0,1\n2,nan,0,0,0,0,0,1\n"
                             "4,0,0,NaN,0,0,0,1\n")
    assert fails(capsys, run(config, out), out=out) == (
        f"{ds / 'data' / 'mocap.csv'}:4: 2 row(s) contain NaN or infinite values (first at line 4); "
        "expected finite numbers")


def test_csv_timestamps_going_back_count_the_rows_and_name_the_first_line(ds, out, capsys):
    config = csv_dataset(ds, "t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n2,0,0,0,0,0,0,1\n\n1,0,0,0,0,0,0,1\n"
                             "0.5,0,0,0,0,0,0,1\n")
    assert fails(capsys, run(config, out), out=out) == (
        f"{ds / 'data' / 'mocap.csv'}:5: 2 row(s) have timestamps that go back in time (first at line 5); "
        "expected non-decreasing t in seconds")


def test_csv_text_in_a_number_column_names_line_column_and_value(ds, out, capsys):
    config = csv_dataset(ds, "t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n2,0,0,1.2.3,0,0,0,1\n")
    assert fails(capsys, run(config, out), out=out) == \
        f"{ds / 'data' / 'mocap.csv'}:3: column 'z' has '1.2.3'; expected a number"


def test_tum_non_increasing_timestamps_count_the_rows_and_name_the_first_line(ds, out, capsys):
    vo = ds / "data" / "vo.tum"
    lines = vo.read_text().splitlines()
    lines[10] = "0.05" + lines[10][lines[10].index(" "):]  # line 11 goes back in time
    vo.write_text("\n".join(lines) + "\n")
    assert fails(capsys, run(ds / "config.yaml", out), out=out) == (
        f"{vo}:11: 1 row(s) have timestamps that go back in time (first at line 11); expected non-decreasing "
        "t in seconds")


def test_tum_with_missing_field_names_the_line_and_the_field_count(ds, out, capsys):
    mocap = ds / "data" / "mocap.tum"
    lines = mocap.read_text().splitlines()
    lines[2] = " ".join(lines[2].split()[:7])
    mocap.write_text("\n".join(lines) + "\n")
    assert fails(capsys, run(ds / "config.yaml", out), out=out) == \
        f"{mocap}:3: 7 fields; expected 8 (t x y z qx qy qz qw)"


def test_truth_trajectory_with_nan_counts_the_rows_and_names_the_first_line(ds, out, capsys):
    truth = ds / "truth" / "cam.tum"
    lines = truth.read_text().splitlines()
    for i in (5, 6, 7):
        lines[i] = " ".join(lines[i].split()[:1] + ["nan"] + lines[i].split()[2:])
    truth.write_text("\n".join(lines) + "\n")
    assert fails(capsys, run(ds / "config.yaml", out), out=out) == \
        f"{truth}:6: 3 row(s) contain NaN or infinite values (first at line 6); expected finite numbers"


# ---------------------------------------------------------------- 6. unconstrained variables


def _odometry_only(tmp_path: Path) -> Path:
    """The scaled-VO config without motion capture: relative VO only, nothing fixes the first pose."""
    config = scaled_vo_copy(tmp_path)
    data = yaml.safe_load(config.read_text())
    data["factors"] = data["factors"][:1]
    data["initializers"] = []
    data["sources"][0]["params"]["duration"] = 3
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    return config


UNCONSTRAINED = ("the factors leave 6 directions of the 541 unknowns unconstrained (the whitened Jacobian is "
                 "rank-deficient: |R_jj| / ||A e_j|| below 1e-09); moving without changing any residual: "
                 "cam/pose[0..89] (all 90; rx, ry, rz, tx, ty, tz): 6 directions; add a prior or an absolute "
                 "measurement of the first state cam/pose[0] (rx, ry, rz, tx, ty, tz), e.g. a pose.origin or "
                 "pose.absolute factor")


def test_validate_names_the_six_free_directions_of_a_floating_trajectory_without_solving(tmp_path, capsys, monkeypatch):
    import fusionkit.solve
    import fusionkit.solve.batch

    def must_not_solve(*args, **kwargs):
        raise AssertionError("validate must not solve")

    monkeypatch.setattr(fusionkit.solve, "solve", must_not_solve)
    monkeypatch.setattr(fusionkit.solve.batch, "solve_batch", must_not_solve)
    config = _odometry_only(tmp_path)
    message = fails(capsys, ["validate", str(config)])
    assert message.startswith(f"{config}: {UNCONSTRAINED}")


@pytest.mark.parametrize("solver", ["batch", "isam2", "fixed_lag"])
def test_run_names_the_six_free_directions_of_a_floating_trajectory_with_every_solver(tmp_path, out, capsys, solver):
    config = _odometry_only(tmp_path)
    message = fails(capsys, run(config, out, "--set", f"solver.type={solver}"), out=out)
    assert message.startswith(f"{config}: {UNCONSTRAINED}")


def test_origin_prior_makes_the_odometry_only_graph_valid(tmp_path, capsys):
    config = _odometry_only(tmp_path)
    data = yaml.safe_load(config.read_text())
    data["factors"].append({"type": "pose.origin", "robot": "cam", "sigma": {"rotation": 0.001, "translation": 0.001}})
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    assert main(["validate", str(config)]) == 0
    assert "every variable is constrained" in capsys.readouterr().out


# ---------------------------------------------------------------- 7. large residual / divergence


def rejected(capsys, argv: list[str], out: Path) -> str:
    """Run the CLI; assert exit 4 (the chi-square gate refused the solution), one stderr line, and the
    complete outputs written with status: rejected; return the line without its prefix and suffix."""
    code = main(argv)
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 4 and len(lines) == 1, captured.err
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "rejected" and (out / "calibration.yaml").is_file()
    suffix = f"; the outputs were written with status: rejected to inspect ({out}/report.json)"
    assert lines[0].startswith(PREFIX) and lines[0].endswith(suffix)
    assert report["solver"]["rejection"] == lines[0][len(PREFIX):-len(suffix)].split(": ", 1)[1]
    return lines[0][len(PREFIX):-len(suffix)]


def test_overconfident_sigmas_are_rejected_at_chi2_over_100_naming_the_top_factor(out, capsys):
    tiny = [f"factors.{i}.sigma.{axis}=1e-4" for i in (0, 1) for axis in ("rotation", "translation")]
    message = rejected(capsys, run(SCALED_VO, out, *FAST, *[arg for s in tiny for arg in ("--set", s)]), out)
    assert message.startswith(f"{SCALED_VO}: the solver stopped with a large residual: chi-square per degree of "
                              "freedom ")
    ratio = float(message.split("chi-square per degree of freedom ")[1].split(" ")[0])
    assert ratio > 100
    assert "(about 1 is expected; the limit is solver.max_cost_ratio=10)" in message
    assert "largest contributions: factors[0]:pose.scaled_relative (" in message
    assert message.endswith("check the sigmas, the data association, or the initial values")


def test_max_cost_ratio_0_5_rejects_a_run_below_10_and_reports_its_sigma0(out, capsys):
    message = rejected(capsys, run(SCALED_VO, out, *FAST, "--set", "solver.max_cost_ratio=0.5"), out)
    assert "the limit is solver.max_cost_ratio=0.5)" in message
    ratio = float(message.split("chi-square per degree of freedom ")[1].split(" ")[0])
    assert 0.5 < ratio < 10  # the same run passes with the default limit of 10
    solver = json.loads((out / "report.json").read_text())["solver"]
    assert solver["chi2_per_dof"] == pytest.approx(ratio, rel=1e-2)
    assert solver["sigma0"] == pytest.approx(ratio ** 0.5, rel=1e-2)


def test_a_posteriori_sigmas_are_the_plain_ones_times_sigma0(tmp_path, capsys):
    plain, scaled = tmp_path / "plain", tmp_path / "scaled"
    assert main(run(SCALED_VO, plain, *FAST)) == 0
    assert main(run(SCALED_VO, scaled, *FAST, "--set", "solver.a_posteriori_sigmas=true")) == 0
    assert "sigmas below are scaled by sigma0" in capsys.readouterr().out
    a, b = (json.loads((f / "report.json").read_text()) for f in (plain, scaled))
    sigma0 = b["solver"]["sigma0"]
    assert a["solver"]["sigma0"] == pytest.approx(sigma0) and b["solver"]["sigmas_scaled_by_sigma0"] is True
    assert b["parameters"]["cam"]["vo_scale"]["sigma"] == pytest.approx(a["parameters"]["cam"]["vo_scale"]["sigma"]
                                                                        * sigma0, rel=1e-9)


def test_library_estimate_raises_on_a_rejected_solution():
    import fusionkit
    with pytest.raises(SolverError, match="the solver stopped with a large residual"):
        fusionkit.run(SCALED_VO, ["sources.0.params.duration=5", "solver.max_cost_ratio=0.5"])


@pytest.mark.parametrize("initial, final, message", [
    (10.0, float("nan"), "the solver diverged: the cost became non-finite; check initial values and sigmas"),
    (10.0, float("inf"), "the solver diverged: the cost became non-finite; check initial values and sigmas"),
    (10.0, 25.0, "the solver diverged: cost rose from 10 to 25"),
])
def test_non_finite_or_rising_cost_raises_solver_diverged(initial, final, message):
    with pytest.raises(SolverError) as err:
        check_solution(None, None, None, initial, final, 10.0)
    assert str(err.value) == message


# ---------------------------------------------------------------- output folder


def test_out_that_is_a_file_fails_before_solving(tmp_path, capsys):
    target = tmp_path / "result"
    target.write_text("keep me")
    assert fails(capsys, run(SCALED_VO, target, *FAST)) == (
        f"--out {target}: exists and is not a folder; expected a folder path")
    assert target.read_text() == "keep me"
    nested = target / "sub"
    assert fails(capsys, ["simulate", "pose.scaled_vo", "--out", str(nested)]) == (
        f"--out {nested}: is inside {target}, which is a file; expected a folder path")


def test_failed_run_keeps_the_previous_output(tmp_path, capsys):
    target = tmp_path / "result"
    target.mkdir()
    (target / "report.json").write_text("{}")
    fails(capsys, run(SCALED_VO, target, *FAST, "--set", "solver.type=nope"), "solver.type: got 'nope'")
    assert [p.name for p in target.iterdir()] == ["report.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["result"]


# ---------------------------------------------------------------- as a separate process


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-m", "fusionkit.cli.main", *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=300, check=False)


def _one_error_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(PREFIX), proc.stderr
    assert proc.stdout == ""
    return lines[0][len(PREFIX):]


def test_subprocess_missing_config_is_one_line_and_creates_nothing(tmp_path):
    proc = _cli("run", "missing.yaml", "--out", "result", cwd=tmp_path)
    assert _one_error_line(proc) == "missing.yaml: file not found"
    assert list(tmp_path.iterdir()) == []


def test_subprocess_csv_with_infinity_is_one_line_and_creates_nothing(ds, tmp_path):
    csv_dataset(ds, "t,x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n2,0,0,0,0,0,0,inf\n")
    proc = _cli("run", "ds/config.yaml", "--out", "result", cwd=tmp_path)
    assert _one_error_line(proc) == (f"{ds / 'data' / 'mocap.csv'}:3: 1 row(s) contain NaN or infinite values "
                                     "(first at line 3); expected finite numbers")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ds"]


@pytest.mark.slow
def test_subprocess_unconstrained_is_one_line_and_debug_shows_the_traceback(tmp_path):
    config = _odometry_only(tmp_path)
    proc = _cli("run", str(config), "--out", "result", cwd=tmp_path)
    assert _one_error_line(proc).startswith(f"{config}: {UNCONSTRAINED}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["configs", "robots"]
    debug = _cli("--debug", "validate", str(config), cwd=tmp_path)  # --debug shows the traceback
    assert debug.returncode == 1 and "Traceback" in debug.stderr and "SolverError" in debug.stderr


# ---------------------------------------------------------------- pose sigmas: one schema, both keys, > 0

UWB_TV = REPO / "configs" / "uwb_time_varying.yaml"


@pytest.mark.parametrize("value, needle", [
    ("{}", "factors[2].sigma: 'rotation' is required but missing (expected a number > 0)"),
    ("{rotation: 0.01}", "factors[2].sigma: 'translation' is required but missing"),
    ("{rotation: 0, translation: 0.1}", "factors[2].sigma.rotation: got 0; expected a number > 0"),
])
def test_pose_sigma_needs_both_keys_above_zero(tmp_path, capsys, value, needle):
    out = tmp_path / "out"
    assert fails(capsys, ["validate", str(UWB_TV), "--set", f"factors.2.sigma={value}"], needle, out=out) \
        .endswith(f"(from --set factors.2.sigma={value})")


def test_every_pose_sigma_of_every_factor_type_is_the_one_schema_with_at_most_a_default():
    from fusionkit.api import POSE_SIGMA_SCHEMA
    from fusionkit.plugins import registry
    reg = registry()
    for name in reg.names("factor_types"):
        for key, sub in reg.get("factor_types", name).schema.get("properties", {}).items():
            if isinstance(sub, dict) and set(sub.get("properties", {})) == {"rotation", "translation"}:
                assert {k: v for k, v in sub.items() if k != "default"} == POSE_SIGMA_SCHEMA, (name, key)


def test_simulator_noise_override_of_one_key_runs_and_a_negative_one_is_refused(tmp_path, capsys):
    folder = tmp_path / "sim"
    assert main(["simulate", "pose.scaled_vo", "--out", str(folder), "--set", "duration=2",
                 "--set", "vo_sigma.rotation=0.004"]) == 0
    capsys.readouterr()
    assert fails(capsys, ["simulate", "pose.scaled_vo", "--out", str(tmp_path / "b"), "--set",
                          "vo_sigma.rotation=-1"]) == "<simulate pose.scaled_vo>: vo_sigma.rotation: got -1; expected " \
                                                     "a number >= 0"
