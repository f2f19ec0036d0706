"""cable.sag under a time offset (issue: per-pose variables must follow the states that exist): the statics'
per-pose variables (orientation correction, reference force) belong to the real state a sample is paired with,
the sag forces initializer sets those that exist, and a sample the offset's initial value moves past the last state
is left out with the per-pose variables only it used, instead of stopping the run with `appears in no factor`."""

from __future__ import annotations

import yaml

from fusionkit.api import Initializer, hookimpl
from fusionkit.config.loader import load_config
from fusionkit.pipeline import build_problem, read_sources
from fusionkit.simulate import write_dataset


class SetLag:
    """A test plugin: an initializer that sets a robot's `lag` (as time.offset_guess would, from the data)."""

    class Initializer(Initializer):
        name = "test.set_lag"
        summary = "sets the lag"
        robot_fields = ("robot",)
        schema = {"type": "object", "properties": {"robot": {"type": "string"}, "value": {"type": "number"}},
                  "required": ["robot", "value"], "additionalProperties": False}

        def initialize(self, ctx, spec):
            ctx.set_initial(ctx.parameter(spec["robot"], "lag"), float(spec["value"]))

    @staticmethod
    @hookimpl
    def register_initializers():
        return [SetLag.Initializer]


def test_a_sample_shifted_past_the_last_state_leaves_with_its_per_pose_variables(tmp_path, use_plugins):
    use_plugins(SetLag)
    folder = tmp_path / "ds"
    write_dataset("cable.sag_static", folder, ["robot=cdpr_small", "poses=8"], seed=1)  # states at t = 0 .. 7 s
    robot = yaml.safe_load((folder / "robots" / "cdpr.yaml").read_text())
    robot["parameters"]["lag"] = {"type": "scalar", "value": 0.0, "sigma": 1.0, "unit": "s"}
    (folder / "robots" / "cdpr.yaml").write_text(yaml.safe_dump(robot, sort_keys=False))
    config = yaml.safe_load((folder / "config.yaml").read_text())
    sag = next(f for f in config["factors"] if f["type"] == "cable.sag")
    sag["time_offset"] = {"parameter": "lag"}
    config["initializers"].insert(1, {"type": "test.set_lag", "robot": "cdpr", "value": 0.2})  # after the poses
    (folder / "late.yaml").write_text(yaml.safe_dump(config, sort_keys=False))

    loaded = load_config(folder / "late.yaml")
    problem = build_problem(loaded, read_sources(loaded)[0])
    names = {problem.keys.name_of(k) for k in problem.initial.keys()}
    # the lengths of t = 7 s now lie at 7.2 s, past the last state: their factor and orientation correction left out
    assert "cdpr/orientation_correction[7]" not in names
    assert {f"cdpr/orientation_correction[{k}]" for k in range(7)} <= names
    assert "cdpr/reference_force[7]" in names  # the force sensor's own factor still measures it
    assert any("1 sample(s) lie outside the states" in n for n in problem.notes), problem.notes
    assert any("per-state variable(s) (orientation_correction) used only by those samples were left out" in n
               for n in problem.notes), problem.notes
    used = {k for r in problem.records for k in r.factor.keys()}
    assert all(k in used for k in problem.initial.keys())  # no variable appears in no factor


def test_a_pulley_radius_is_refused_in_one_located_line_not_silently_ignored(tmp_path, capsys):
    """cable.sag starts each catenary at a fixed exit point: a description with cables.pulley_radius gave the same
    calibration byte for byte as without it; now `validate` stops at the entry's robot key."""
    from fusionkit.cli.main import main
    folder = tmp_path / "ds"
    write_dataset("cable.sag_static", folder, ["robot=cdpr_small", "poses=8"], seed=1)
    robot = yaml.safe_load((folder / "robots" / "cdpr.yaml").read_text())
    robot["cables"]["pulley_radius"] = 0.05
    (folder / "robots" / "cdpr.yaml").write_text(yaml.safe_dump(robot, sort_keys=False))
    assert main(["validate", str(folder / "config.yaml")]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "config.yaml:" in error
    assert "robot: robot 'cdpr' has cables.pulley_radius 0.05 m: the sag models start each catenary at a fixed" in error
