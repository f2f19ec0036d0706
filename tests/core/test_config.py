"""YAML loading with line numbers, schema messages, `--set` overrides and whole-config validation."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from fusionkit.config.loader import load_config
from fusionkit.config.overrides import apply_override, parse_key_path
from fusionkit.config.schema import CONFIG_SCHEMA, expected, validate_against
from fusionkit.config.yamlio import Document, format_path, load_yaml, parse_yaml
from fusionkit.errors import ConfigError

REPO = Path(__file__).resolve().parents[2]
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
FAST = "sources.0.params.duration=5"


# ---------------------------------------------------------------- YAML with lines


def test_parse_yaml_records_the_line_of_every_key_and_item():
    doc = parse_yaml("name: x\nfactors:\n  - type: a\n    sigma: {rotation: 1, translation: 2}\n  - type: b\n",
                     "c.yaml")
    assert doc.data["factors"][1] == {"type": "b"}
    assert doc.lines[("name",)] == 1
    assert doc.lines[("factors", 0, "type")] == 3
    assert doc.lines[("factors", 0, "sigma", "translation")] == 4
    assert doc.lines[("factors", 1)] == 5
    assert doc.line_of(("factors", 1, "missing", "deeper")) == 5  # closest ancestor with a line
    assert str(doc.error(("factors", 0, "sigma"), "bad")) == "c.yaml:4: factors[0].sigma: bad"


def test_yaml_1_2_exponent_floats_load_as_numbers_and_quoted_ones_as_text():
    doc = parse_yaml("a: 1e-6\nb: 2E3\nc: .5\nd: 1_000\ne: '1e-6'\n")
    assert doc.data == {"a": 1e-6, "b": 2000.0, "c": 0.5, "d": 1000, "e": "1e-6"}
    assert isinstance(doc.data["a"], float) and isinstance(doc.data["d"], int)


def test_format_path_writes_list_indices_in_brackets():
    assert format_path(("factors", 1, "params", "sigma")) == "factors[1].params.sigma"
    assert format_path((0, "a")) == "[0].a"
    assert format_path(()) == ""


@pytest.mark.parametrize("text, line, message", [
    ("a: 1\nb: [1, 2\n", 3, "YAML syntax error: expected ',' or ']', but got '<stream end>'"),
    ("a: 1\n\tb: 2\n", 2, "YAML syntax error: found character '\\t' that cannot start any token"),
    ("robots:\n  cam:\n   x: 1\n  y: 2\n z: 3\n", 5, "YAML syntax error: expected <block end>, but found '<block mapping start>'"),
])
def test_yaml_syntax_error_names_file_and_line(text, line, message):
    with pytest.raises(ConfigError) as err:
        parse_yaml(text, "bad.yaml")
    assert str(err.value) == f"bad.yaml:{line}: {message}"
    assert err.value.line == line and err.value.file == "bad.yaml"


def test_duplicate_keys_are_errors_not_silently_overwritten():
    with pytest.raises(ConfigError) as err:
        parse_yaml("solver:\n  type: batch\n  method: lm\n  type: isam2\n", "c.yaml")
    assert str(err.value) == ("c.yaml:4: solver.type: duplicate key 'type' (first on line 2); "
                              "each key may appear once in a mapping")
    # the same key in different mappings, and YAML merge keys, are fine
    doc = parse_yaml("base: &b {x: 1}\na: {<<: *b, y: 2}\nb: {<<: *b, y: 3}\n")
    assert doc.data["a"] == {"x": 1, "y": 2} and doc.data["b"] == {"x": 1, "y": 3}


def test_load_yaml_refuses_missing_folder_and_non_utf8_files_and_reads_empty_as_empty(tmp_path):
    with pytest.raises(ConfigError) as err:
        load_yaml(tmp_path / "none.yaml")
    assert str(err.value) == f"{tmp_path / 'none.yaml'}: file not found"
    with pytest.raises(ConfigError, match=r"dir\.yaml: cannot read file \(IsADirectoryError"):
        (tmp_path / "dir.yaml").mkdir()
        load_yaml(tmp_path / "dir.yaml")
    (tmp_path / "bin.yaml").write_bytes(b"a: \xff\xfe\n")
    with pytest.raises(ConfigError, match=r"bin\.yaml: cannot read file \(UnicodeDecodeError"):
        load_yaml(tmp_path / "bin.yaml")
    (tmp_path / "empty.yaml").write_text("# nothing\n")
    assert load_yaml(tmp_path / "empty.yaml").data == {}


# ---------------------------------------------------------------- schema messages


def _schema_error(schema: dict, text: str) -> ConfigError:
    doc = parse_yaml(text, "c.yaml")
    with pytest.raises(ConfigError) as err:
        validate_against(doc, schema, doc.data)
    return err.value


def test_unknown_key_is_located_at_its_own_line_and_lists_accepted_keys():
    err = _schema_error(CONFIG_SCHEMA, "robots: {cam: {description: r.yaml}}\nfactors: [{type: a}]\n"
                                       "solver:\n  type: batch\n  metod: lm\n")
    assert str(err) == ("c.yaml:5: solver.metod: unknown key 'metod'; accepted keys: a_posteriori_sigmas, "
                        "absolute_tolerance, damping, "
                        "factorization, lag, marginals, max_cost_ratio, max_iterations, method, new_states, ordering, "
                        "refine, relative_tolerance, "
                        "relinearize_marginal_variables, relinearize_skip, relinearize_threshold, type, updates_per_step, warmup")


@pytest.mark.parametrize("solver, message", [
    ("{type: bach}", "c.yaml:3: solver.type: got 'bach'; expected one of: batch, isam2, fixed_lag"),
    ("{max_iterations: 0}", "c.yaml:3: solver.max_iterations: got 0; expected an integer >= 1"),
    ("{max_cost_ratio: -2}", "c.yaml:3: solver.max_cost_ratio: got -2; expected a number > 0"),
    ("{max_cost_ratio: .nan}", "c.yaml:3: solver.max_cost_ratio: got nan; expected a number > 0"),
    ("{max_cost_ratio: abc}", "c.yaml:3: solver.max_cost_ratio: got 'abc'; expected a number > 0"),
    ("{marginals: 3}", "c.yaml:3: solver.marginals: got 3; expected true or false"),
    ("{updates_per_step: 0}", "c.yaml:3: solver.updates_per_step: got 0; expected an integer >= 1"),
    ("[batch]", ("c.yaml:3: solver: got ['batch']; expected a mapping with keys type, method, damping, factorization, "
                "ordering, max_iterations, "
                "relative_tolerance, absolute_tolerance, lag, warmup, new_states, relinearize_threshold, updates_per_step, "
                "relinearize_skip, relinearize_marginal_variables, max_cost_ratio, marginals, a_posteriori_sigmas, refine")),
])
def test_wrong_values_say_what_is_accepted(solver, message):
    err = _schema_error(CONFIG_SCHEMA, f"robots: {{cam: {{description: r.yaml}}}}\nfactors: [{{type: a}}]\n"
                                       f"solver: {solver}\n")
    assert str(err) == message


def test_missing_required_key_says_what_it_expects():
    schema = {"type": "object", "properties": {"sigma": {"type": "object", "properties": {"rotation": {},
                                                                                          "translation": {}}}},
              "required": ["sigma"]}
    err = _schema_error(schema, "robot: cam\n")
    assert str(err) == "c.yaml:1: 'sigma' is required but missing (expected a mapping with keys rotation, translation)"
    err = _schema_error(CONFIG_SCHEMA, "robots: {cam: {description: r.yaml}}\n")
    assert str(err) == ("c.yaml:1: 'factors' is required but missing (expected a list of at least 1 item "
                        "(each a mapping with keys type))")


def test_one_of_required_keys_and_list_lengths_say_what_is_needed():
    schema = {"type": "object", "properties": {"p": {"oneOf": [{"required": ["value"]}, {"required": ["values"]}],
                                                     "type": "object"},
                                               "mount": {"type": "array", "items": {"type": "number"},
                                                         "minItems": 3, "maxItems": 3}}}
    assert str(_schema_error(schema, "p: {valu: 1}\n")) == "c.yaml:1: p: needs exactly one of the keys value, values"
    assert str(_schema_error(schema, "p: {value: 1, values: [1]}\n")) == \
        "c.yaml:1: p: needs exactly one of the keys value, values"
    assert str(_schema_error(schema, "mount: [0, 0.05]\n")) == "c.yaml:1: mount: got [0, 0.05]; expected a list of 3 numbers"


def test_expected_describes_each_schema_in_words():
    assert expected({"type": "number", "exclusiveMinimum": 0}) == "a number > 0"
    assert expected({"type": "integer", "minimum": 1, "maximum": 9}) == "an integer >= 1 and <= 9"
    assert expected({"type": ["number", "array", "null"]}) == "a number, a list or null"
    assert expected({"enum": ["se3", "sim3"]}) == "one of: se3, sim3"
    assert expected({"type": "array", "items": {"type": "string"}}) == "a list of strings"
    assert expected({}) == "a value"


# ---------------------------------------------------------------- --set overrides


def test_parse_key_path_accepts_dots_and_brackets_and_refuses_empty_keys():
    assert parse_key_path("factors.1.params.sigma") == ("factors", 1, "params", "sigma")
    assert parse_key_path("factors[1].sigma") == ("factors", 1, "sigma")
    with pytest.raises(ConfigError, match=r"--set 'a\.\.b': empty key in path \(expected e\.g\. solver\.type=isam2\)"):
        parse_key_path("a..b")


def test_apply_override_sets_parses_and_creates():
    data = {"solver": {"type": "batch"}, "factors": [{"sigma": {"rotation": 0.1}}], "seed": None}
    assert apply_override(data, "solver.type=isam2") == ("solver", "type")
    assert apply_override(data, "factors.0.sigma.rotation=0.01") == ("factors", 0, "sigma", "rotation")
    apply_override(data, "factors[0].sigma.translation=1e-3")
    apply_override(data, "output.plots=false")
    apply_override(data, "seed=42")
    apply_override(data, "factors.0.robust={kernel: huber, k: 1.5}")
    apply_override(data, "name=")
    apply_override(data, "factors.1={type: cable.pulley_distance, distance: 4.0}")  # one past the end appends
    apply_override(data, "initializers.0={type: pose.interpolate}")  # a missing list is created
    assert data == {"solver": {"type": "isam2"},
                    "factors": [{"sigma": {"rotation": 0.01, "translation": 0.001},
                                 "robust": {"kernel": "huber", "k": 1.5}},
                                {"type": "cable.pulley_distance", "distance": 4.0}],
                    "seed": 42, "output": {"plots": False}, "name": "",
                    "initializers": [{"type": "pose.interpolate"}]}


@pytest.mark.parametrize("assignment, message", [
    ("solver.type", "--set 'solver.type': expected key.path=value"),
    ("=3", "--set '': empty key in path (expected e.g. solver.type=isam2)"),
    ("factors.3.sigma=1", "--set factors.3.sigma: index 3 out of range (the list has 1 item(s); indices: 0..0)"),
    ("factors.x=1", "--set factors.x: 'x' is not a list index (the list has 1 item(s); indices: 0..0, or 1 to append)"),
    ("factors.-1.sigma=1", "--set factors.-1.sigma: '-1' is not a list index (the list has 1 item(s); indices: 0..0)"),
    ("empty.1=1", ("--set empty.1: index 1 out of range (the list has 0 item(s); indices: none: the list is empty, "
                   "or 0 to append)")),
    ("factors.2=1", "--set factors.2: index 2 out of range (the list has 1 item(s); indices: 0..0, or 1 to append)"),
    ("solver.type=[a", "--set 'solver.type=[a': value is not valid YAML"),
    ("name.x=1", "--set name.x: parent is not a mapping or list"),
    ("name.x.y=1", "--set name.x.y: 'x' is not inside a mapping"),
])
def test_apply_override_errors_say_why_the_path_or_value_is_invalid(assignment, message):
    with pytest.raises(ConfigError) as err:
        apply_override({"name": "q", "factors": [{}], "empty": []}, assignment)
    assert str(err.value) == message


# ---------------------------------------------------------------- load_config


def test_scaled_vo_loads_with_overrides_applied():
    config = load_config(SCALED_VO, [FAST, "solver.type=isam2", "factors.0.sigma.rotation=0.01",
                                      "factors[1].sigma.translation=2e-2"])
    assert config.name == "scaled_vo_mocap" and config.seed == 0
    # the solver section with its defaults: the schema's, then iSAM2's factorization and chi-square gate
    assert config.solver == {"type": "isam2", "method": "lm", "damping": "marquardt", "ordering": "auto", "max_iterations": 100,
                             "relative_tolerance": 1e-6, "absolute_tolerance": 1e-9, "lag": 2.0, "warmup": 0,
                             "new_states": "initial", "relinearize_threshold": 0.01, "updates_per_step": 1,
                             "relinearize_skip": 1, "relinearize_marginal_variables": False, "marginals": True, "a_posteriori_sigmas": False,
                             "factorization": "qr", "max_cost_ratio": 10.0}
    assert config.output == {"plots": True, "state_covariances": False}
    assert config.factors[0]["sigma"] == {"rotation": 0.01, "translation": 0.0016}
    assert config.factors[1]["sigma"] == {"rotation": 0.01, "translation": 0.02}
    assert config.sources[0]["params"] == {"duration": 5, "rate": 30.0, "scale": 2.5}
    assert list(config.robots) == ["cam"]
    assert config.robots["cam"].description.parameters["vo_scale"].values == [1.0]
    assert config.stream_columns == {"vo": ("x", "y", "z", "qx", "qy", "qz", "qw"),
                                     "mocap": ("x", "y", "z", "qx", "qy", "qz", "qw")}
    assert config.base_dir == SCALED_VO.parent


def test_errors_in_overridden_values_point_at_the_set_not_at_a_file_line():
    with pytest.raises(ConfigError) as err:
        load_config(SCALED_VO, ["factors.0.sigma.rotation=abc"])
    assert str(err.value) == (f"{SCALED_VO}: factors[0].sigma.rotation: got 'abc'; expected a number > 0 "
                              "(from --set factors.0.sigma.rotation=abc)")
    assert err.value.line is None
    with pytest.raises(ConfigError) as err:
        load_config(SCALED_VO, ["solver.typo=1"])
    assert str(err.value).startswith(f"{SCALED_VO}: solver.typo: unknown key 'typo'; accepted keys: a_posteriori_sigmas, "
                                     "absolute_tolerance")
    assert str(err.value).endswith("(from --set solver.typo=1)")
    # an error elsewhere keeps its file line even when --set was used
    with pytest.raises(ConfigError) as err:
        load_config(SCALED_VO, ["solver.type=isam2", "factors.1.stream=gps"])
    assert str(err.value).startswith(f"{SCALED_VO}: factors[1].stream: unknown stream 'gps'")
    with pytest.raises(ConfigError) as err:
        load_config(SCALED_VO, ["initializers.0.anchor=gps"])
    assert str(err.value) == (f"{SCALED_VO}: initializers[0].anchor: unknown stream 'gps'; the sources provide: "
                              "mocap, vo (from --set initializers.0.anchor=gps)")


def _copy_scaled_vo(tmp_path: Path) -> Path:
    (tmp_path / "configs").mkdir()
    (tmp_path / "robots").mkdir()
    shutil.copy(REPO / "robots" / "pose" / "handheld_camera.yaml", tmp_path / "robots")
    target = tmp_path / "configs" / "scaled_vo_mocap.yaml"
    target.write_text(SCALED_VO.read_text().replace("description: handheld_camera",
                                                    "description: ../robots/handheld_camera.yaml"))
    return target


def test_robot_description_unknown_key_lists_all_accepted_keys(tmp_path):
    config = _copy_scaled_vo(tmp_path)
    robot = tmp_path / "robots" / "handheld_camera.yaml"
    robot.write_text(robot.read_text().replace("frames: [world, body]", "frame: [world, body]"))
    with pytest.raises(ConfigError) as err:
        load_config(config)
    shown = tmp_path / "configs" / ".." / "robots" / "handheld_camera.yaml"  # as the config spells it
    assert str(err.value) == (f"{shown}:6: frame: unknown key 'frame'; accepted keys: frames, model, name, "
                              "parameters, sensors, summary")


def test_truth_file_that_is_a_folder_is_refused_naming_the_set(tmp_path):
    config = _copy_scaled_vo(tmp_path)
    (tmp_path / "configs" / "truth.tum").mkdir()
    with pytest.raises(ConfigError) as err:
        load_config(config, ["truth.trajectories.cam=truth.tum"])
    assert str(err.value) == (f"{config}: truth.trajectories.cam: {tmp_path / 'configs' / 'truth.tum'} is a folder; "
                              "expected a file (from --set truth.trajectories.cam=truth.tum)")


def test_document_error_without_line_or_path_names_only_the_file():
    doc = Document({}, Path("x.yaml"))
    assert str(doc.error((), "expected a mapping")) == "x.yaml: expected a mapping"
