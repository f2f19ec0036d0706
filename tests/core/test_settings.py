"""Settings declared once per component: the `default` of a schema's key is what an entry that omits
it gets (filled in at load, nested mappings key by key; the document keeps what was written), every
default is valid for its key, `fusionkit plugins` shows them, the reference docs are generated from
them, and the run config's `solver:`, `output:` and `truth:` defaults are applied at load.

Run this file as a script to regenerate the keys tables of docs/reference/factors.md:
    .venv/bin/python tests/core/test_settings.py
"""

from __future__ import annotations

import ast
import json
import re
import sys
from pathlib import Path

import gtsam
import jsonschema
import numpy as np
import pytest
import yaml

import fusionkit
import fusionkit.api
from fusionkit.api import TOLERANCE_SCHEMA, FactorExample, FactorType, Spec, gaussian
from fusionkit.cli.main import main
from fusionkit.config.defaults import key_rows, merged, with_defaults
from fusionkit.config.loader import load_config, solver_settings
from fusionkit.config.schema import CONFIG_SCHEMA, SOLVER_TYPE_DEFAULTS
from fusionkit.config.yamlio import Document
from fusionkit.errors import PluginError
from fusionkit.pipeline import build_problem, read_sources
from fusionkit.plugins import KINDS, registry

REPO = Path(__file__).resolve().parents[2]
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
QUICKSTART = REPO / "configs" / "quickstart.yaml"
FACTORS_DOC = REPO / "docs" / "reference" / "factors.md"
CONFIG_DOC = REPO / "docs" / "reference" / "config.md"
FAST = "sources.0.params.duration=5"
BEGIN, END = "<!-- keys: generated from the schemas by tests/core/test_settings.py -->", "<!-- keys: end -->"
SECTIONS = [("factor_types", "Factor types", "type"), ("initializers", "Initializers", "type"),
            ("sources", "Sources", "type"), ("simulators", "Simulators", "scenario")]


def components():
    """(kind, name, class) of every registered component."""
    reg = registry()
    return [(kind, name, reg.get(kind, name)) for kind in KINDS for name in reg.names(kind)]


def properties(schema: dict, path: tuple = ()):
    """(key path, subschema) of every property of `schema`, nested ones too."""
    for key, sub in schema.get("properties", {}).items():
        yield path + (key,), sub
        if isinstance(sub, dict):
            yield from properties(sub, path + (key,))


# ---------------------------------------------------------------- entries: defaults filled at load


def test_loaded_entries_carry_their_schema_defaults_and_the_document_keeps_what_was_written():
    config = load_config(SCALED_VO, [FAST])
    absolute = config.factors[1]
    assert absolute.type == "pose.absolute" and absolute["tolerance"] == 0.005
    assert "tolerance" not in config.doc.data["factors"][1]
    assert "sensor" in absolute.data and "max_gap" not in config.factors[0].data  # absence means no gap limit
    assert config.sources[0]["seed"] == 7 and config.sources[0]["params"] == {"duration": 5, "rate": 30.0,
                                                                              "scale": 2.5}


def test_a_partial_nested_mapping_keeps_the_defaults_of_its_other_keys():
    index = [e["type"] for e in yaml.safe_load(QUICKSTART.read_text())["initializers"]].index("cable.monte_carlo")
    config = load_config(QUICKSTART, [f"initializers.{index}.vo_sigma={{rotation: 0.003}}"])
    spec = config.initializers[index]
    assert spec["vo_sigma"] == {"rotation": 0.003, "translation": 0.0}
    assert (spec["particles"], spec["seed"], spec["initial_length_spread"]) == (5000, 0, 0.05)


def test_with_defaults_fills_absent_keys_merges_mappings_and_leaves_the_input_alone():
    schema = {"type": "object", "properties": {
        "a": {"type": "number", "default": 1.5},
        "noise": {"type": "object", "default": {"r": 0.1, "t": 0.2},
                  "properties": {"r": {"type": "number"}, "t": {"type": "number"}}},
        "box": {"type": "object", "properties": {"n": {"type": "integer", "default": 3}}},
        "free": {"type": "string"}}}
    given = {"noise": {"r": 0.5}, "box": {}}
    assert with_defaults(schema, given) == {"noise": {"r": 0.5, "t": 0.2}, "box": {"n": 3}, "a": 1.5}
    assert given == {"noise": {"r": 0.5}, "box": {}}
    assert with_defaults(schema, {"noise": 7}) == {"noise": 7, "a": 1.5}  # not a mapping: validation reports it
    assert merged({"x": {"y": 1, "z": 2}}, {"x": {"z": 5}, "w": 0}) == {"x": {"y": 1, "z": 5}, "w": 0}


# ---------------------------------------------------------------- every component's defaults


@pytest.mark.parametrize("kind, name, cls", components(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_default_is_valid_for_its_key_and_no_required_key_has_one(kind, name, cls):
    for path, sub in [((), cls.schema), *properties(cls.schema)]:
        if not isinstance(sub, dict):
            continue
        if "default" in sub:
            assert jsonschema.Draft202012Validator(sub).is_valid(sub["default"]), (path, sub["default"])
        defaulted_but_required = [k for k in sub.get("required", ()) if "default" in sub["properties"].get(k, {})]
        assert defaulted_but_required == [], path
    if kind == "simulators":
        assert set(cls.defaults) <= set(cls.schema.get("properties", {})), "a default for an undeclared key"
        assert jsonschema.Draft202012Validator(cls.schema).is_valid(cls.defaults)


def keys_read(path: Path) -> list[tuple[int, str]]:
    """(line, key) of every `spec["key"]`, `spec.get("key", ...)` and `"key" in spec.data` in a module."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) and node.value.id == "spec" \
                and isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, str):
            out.append((node.lineno, node.slice.value))
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get" \
                and isinstance(node.func.value, ast.Name) and node.func.value.id == "spec" and node.args \
                and isinstance(node.args[0], ast.Constant):
            out.append((node.lineno, node.args[0].value))
        elif isinstance(node, ast.Compare) and isinstance(node.left, ast.Constant) \
                and isinstance(node.ops[0], ast.In) and ast.unparse(node.comparators[0]) == "spec.data":
            out.append((node.lineno, node.left.value))
    return out


def test_plugin_code_reads_only_keys_its_family_declares():
    """A key read in build or check code that no schema of the plugin family declares is a drift
    between schema and code (it would be an internal KeyError, or a setting nobody can give)."""
    declared: dict[str, set[str]] = {}
    for kind, name, cls in components():
        family = cls.__module__.split(".")[1]  # fusionkit_plugins.<family>.module
        declared.setdefault(family, {"type", "label", "robust"}).update(cls.schema.get("properties", {}))
    undeclared = [f"{p.relative_to(REPO)}:{line}: {key}" for p in sorted((REPO / "plugins").glob("*/*.py"))
                  for line, key in keys_read(p) if key not in declared[p.parent.name]]
    assert undeclared == []


def test_simulator_defaults_show_in_its_schema_and_resolve_merges_nested_ones():
    sim = registry().get("simulators", "pose.scaled_vo")
    assert sim.schema["properties"]["vo_sigma"]["default"] == {"rotation": 0.002, "translation": 0.0016}
    doc = Document({}, Path("<test>"))
    params = sim.resolve({"vo_sigma": {"rotation": 0.01}}, doc)
    assert params["vo_sigma"] == {"rotation": 0.01, "translation": 0.0016} and params["duration"] == 25.0
    assert sim.defaults["vo_sigma"] == {"rotation": 0.002, "translation": 0.0016}  # the class's own: unchanged


# ---------------------------------------------------------------- what users see


def test_plugins_json_shows_each_default_in_the_components_schema(capsys):
    assert main(["plugins", "--json"]) == 0
    listing = json.loads(capsys.readouterr().out)
    schemas = {(kind, item["name"]): item["schema"] for provided in listing.values()
               for kind, items in provided.items() for item in items if "schema" in item}
    assert schemas[("factor_types", "pose.absolute")]["properties"]["tolerance"]["default"] == 0.005
    assert schemas[("initializers", "cable.monte_carlo")]["properties"]["particles"]["default"] == 5000
    assert schemas[("simulators", "uwb.sim")]["properties"]["range_sigma"]["default"] == 0.05
    assert "default" not in schemas[("factor_types", "pose.relative")]["properties"]["max_gap"]


def test_plugins_name_prints_the_keys_required_defaulted_and_optional(capsys):
    assert main(["plugins", "pose.absolute"]) == 0
    assert capsys.readouterr().out.splitlines() == [
        "factor type pose.absolute (pose): absolute pose measurements of a robot (motion "
        "capture, GNSS+heading): native prior",
        "  robot      required  a string",
        "  stream     required  a string",
        "  sensor     optional  a string",
        "  sigma      required  a mapping with keys rotation, translation",
        "  tolerance  0.005     a number >= 0",
        "  (every entry also accepts: label, robust {kernel, k}, noise_scale (a number or estimate), "
        "time_offset {robot, parameter, rate, velocities})"]


def test_plugins_name_lists_time_offset_only_for_factor_types_that_pair_samples_by_stamp(capsys):
    """cable.sag pairs lengths with states by stamp (a tolerance): its time offset and noise scale are listed;
    pose.origin pairs nothing: noise_scale only."""
    assert main(["plugins", "cable.sag"]) == 0
    assert capsys.readouterr().out.splitlines()[-1].endswith(
        "noise_scale (a number or estimate), time_offset {robot, parameter, rate, velocities})")
    assert main(["plugins", "pose.origin"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        "  (every entry also accepts: label, robust {kernel, k}, noise_scale (a number or estimate))")


def test_plugins_name_of_nothing_installed_is_one_located_line_and_exit_2(capsys):
    assert main(["plugins", "pose.absolut"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err == ("fusionkit: error: nothing installed is called 'pose.absolut'; `fusionkit plugins` "
                            "lists every name\n")


@pytest.mark.parametrize("config, assignment, key, message", [
    (SCALED_VO, "factors.1.tolerance=-1", "factors[1].tolerance", "got -1; expected a number >= 0"),
    (QUICKSTART, "initializers.{mc}.vo_sigma.rotation=-1", "initializers[{mc}].vo_sigma.rotation",
     "got -1; expected a number >= 0"),
    (SCALED_VO, "solver.max_iterations=0", "solver.max_iterations", "got 0; expected an integer >= 1"),
])
def test_a_set_into_a_defaulted_key_is_reported_as_coming_from_the_set(capsys, config, assignment, key, message):
    mc = [e["type"] for e in yaml.safe_load(QUICKSTART.read_text())["initializers"]].index("cable.monte_carlo")
    assignment, key = assignment.format(mc=mc), key.format(mc=mc)
    assert main(["validate", str(config), "--set", assignment]) == 2
    assert capsys.readouterr().err == f"fusionkit: error: {config}: {key}: {message} (from --set {assignment})\n"


# ---------------------------------------------------------------- association tolerance


def offset_mocap_config(workspace, extra: dict | None = None, factor_type: str = "pose.absolute") -> Path:
    """VO at 10 Hz and motion capture 3 ms after each VO stamp."""
    t = np.arange(11) * 0.1
    poses = [gtsam.Pose3(gtsam.Rot3(), np.array([x, 0.0, 0.0])) for x in t]
    return workspace.config({
        "robots": {"cam": {"description": "handheld_camera", "states": {"stream": "vo"}}},
        "sources": [workspace.poses("vo", t, poses), workspace.poses("mocap", t + 0.003, poses)],
        "factors": [{"type": factor_type, "robot": "cam", "stream": "mocap",
                     "sigma": {"rotation": 0.01, "translation": 0.01}, **(extra or {})}]})


@pytest.mark.parametrize("extra, matched", [({}, 11), ({"tolerance": 0.002}, 0)])
def test_associate_pairs_samples_within_the_entrys_tolerance_or_its_default(workspace, extra, matched):
    config = load_config(offset_mocap_config(workspace, extra))
    problem = build_problem(config, read_sources(config)[0])
    assert len(problem.records) == matched
    unmatched = [n for n in problem.notes if "had no state within" in n]
    assert unmatched == ([] if matched else ["factors[0]:pose.absolute: 11 of 11 samples of stream 'mocap' had "
                                             "no state within 0.002 s and were not used"])


class UndeclaredTolerance(FactorType):
    """A plugin bug: associates by nearest stamp without declaring `tolerance`."""

    name = "test.no_tolerance"
    summary = "absolute poses, associated without a declared tolerance"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object", "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                                               "sigma": {"type": "object"}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def build(self, ctx, spec: Spec) -> None:
        ctx.associate(ctx.stream(spec["stream"]), spec["robot"], spec)

    @classmethod
    def example(cls, rng):
        values = gtsam.Values()
        values.insert(0, 1.0)
        return FactorExample(gtsam.PriorFactorDouble(0, 1.0, gaussian([0.1])), values)


class UndeclaredPlugin:
    @fusionkit.api.hookimpl
    def register_factor_types(self):
        return [UndeclaredTolerance]


def test_associate_without_a_declared_tolerance_is_a_plugin_error_naming_the_fix(workspace, use_plugins):
    use_plugins(UndeclaredPlugin())
    config = load_config(offset_mocap_config(workspace, factor_type="test.no_tolerance"))
    with pytest.raises(PluginError) as err:
        build_problem(config, read_sources(config)[0])
    assert str(err.value) == ("factors[0]:test.no_tolerance: test.no_tolerance associates samples by nearest "
                              "stamp but its schema declares no `tolerance` (plugin bug: add \"tolerance\": "
                              "TOLERANCE_SCHEMA)")
    assert TOLERANCE_SCHEMA["default"] == 0.005


# ---------------------------------------------------------------- the run config's sections


@pytest.mark.parametrize("kind", sorted(SOLVER_TYPE_DEFAULTS))
def test_solver_settings_get_the_schema_defaults_and_those_of_their_type(kind):
    settings = solver_settings({"type": kind})
    assert settings["factorization"] == ("cholesky" if kind == "batch" else "qr")
    assert settings["max_cost_ratio"] == (np.inf if kind == "fixed_lag" else 10.0)
    assert (settings["max_iterations"], settings["relative_tolerance"], settings["lag"]) == (100, 1e-6, 2.0)
    assert solver_settings({"type": kind, "factorization": "qr", "max_cost_ratio": 3.0})["max_cost_ratio"] == 3.0
    assert solver_settings({})["type"] == "batch"


def test_truth_align_defaults_to_none_at_load():
    config = load_config(SCALED_VO, [FAST])
    assert config.truth == {"align": "none"}


def yaml_example(doc: Path) -> dict:
    """The first ```yaml block of a doc, parsed."""
    return yaml.safe_load(re.search(r"```yaml\n(.*?)```", doc.read_text(), re.S).group(1))


def test_config_reference_example_states_the_solver_output_and_align_defaults():
    """docs/reference/config.md lists every solver and output setting, and truth.align, at its default."""
    example = yaml_example(CONFIG_DOC)
    for section, resolved in (("solver", solver_settings({"type": example["solver"]["type"]})),
                              ("output", with_defaults(CONFIG_SCHEMA["properties"]["output"], {}))):
        stated = {k: v for k, v in example[section].items() if k != "refine"}
        assert stated == resolved, section
    assert example["truth"]["align"] == CONFIG_SCHEMA["properties"]["truth"]["properties"]["align"]["default"]


# ---------------------------------------------------------------- the reference docs


def keys_tables() -> str:
    """The keys of every built-in factor type, initializer, source and simulator, from their schemas."""
    reg = registry()
    lines = [BEGIN]
    for kind, title, column in SECTIONS:
        lines += ["", f"### {title}", "", f"| {column} | required keys | optional keys: default |", "| --- | --- | --- |"]
        for name in reg.names(kind):
            cls = reg.get(kind, name)
            if not cls.__module__.startswith(("fusionkit.", "fusionkit_plugins.")):
                continue  # installed from elsewhere
            rows = key_rows(cls.schema)
            required = ", ".join(f"`{key}`" for key, status, _ in rows if status == "required")
            optional = ", ".join(f"`{key}`" if status == "optional" else f"`{key}: {status}`"
                                 for key, status, _ in rows if status != "required")
            lines.append(f"| `{name}` | {required or '-'} | {optional or '-'} |")
    return "\n".join(lines + ["", END])


def documented_tables(text: str) -> str:
    start, end = text.index(BEGIN), text.index(END) + len(END)
    return text[start:end]


def test_reference_keys_tables_are_generated_from_the_schemas():
    assert documented_tables(FACTORS_DOC.read_text()) == keys_tables(), \
        "regenerate with: .venv/bin/python tests/core/test_settings.py"


if __name__ == "__main__":
    text = FACTORS_DOC.read_text()
    FACTORS_DOC.write_text(text.replace(documented_tables(text), keys_tables()))
    sys.exit(0)
