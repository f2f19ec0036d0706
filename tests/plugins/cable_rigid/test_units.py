"""A cdpr description may give the end-effector's weight (N) instead of its mass (kg), and the cables' mass per
metre (kg/m) instead of their weight (N/m), as robots' data sheets do: stored as mass and weight per metre with
the description's gravity; both forms at once are one located line."""

from __future__ import annotations

import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.config.loader import load_config
from fusionkit_plugins.cable_sag.model import sag_robot

ATTACH = [[-0.15, -0.15, 0.05], [0.15, -0.15, 0.05], [0.15, 0.15, 0.05], [-0.15, 0.15, 0.05]]


def config_with(workspace, cables: dict, end_effector: dict, **extra) -> str:
    description = {"name": "cdpr_units", "model": "cdpr", "cables": {"attachments": ATTACH, **cables},
                   "end_effector": end_effector, **extra,
                   "parameters": {"pulley": {"type": "point3", "values": [[-2, -1.5, 3.2], [2, -1.5, 3.2],
                                                                             [2, 1.5, 3.2], [-2, 1.5, 3.2]]},
                                  "offset": {"type": "scalar", "values": [0.0] * 4}}}
    (workspace.folder / "cdpr.yaml").write_text(yaml.safe_dump(description, sort_keys=False))
    return str(workspace.config({"robots": {"cdpr": {"description": "cdpr.yaml", "states": {"stream": "enc"}}},
                                 "sources": [workspace.columns("enc", [0.0, 1.0], l0=[1.0, 1.1], l1=[1.0, 1.1], l2=[1.0, 1.1],
                                                               l3=[1.0, 1.1])],
                                 "factors": [{"type": "cable.length", "robot": "cdpr", "stream": "enc",
                                              "sigma": 0.001}]}))


def test_weight_and_mass_per_metre_are_stored_as_mass_and_weight_per_metre(workspace):
    """The small sagging robot's data (4.4 kg, 0.1034955 N/m) given the other way round: the statics see the
    same end-effector weight and cable weight."""
    config = load_config(config_with(workspace, {"mass_per_length": 0.1034955 / 9.81}, {"weight": 43.164}))
    extra = config.robots["cdpr"].description.extra
    assert extra["end_effector"] == {"mass": pytest.approx(4.4)}
    assert extra["cables"]["weight_per_length"] == pytest.approx(0.1034955)
    robot = sag_robot(config.robots["cdpr"].description)
    assert robot.weight == pytest.approx(43.164) and robot.cable_weight == pytest.approx(0.1034955)
    standard = load_config(config_with(workspace, {"weight_per_length": 0.1}, {"weight": 50.0}, gravity=9.80665))
    assert sag_robot(standard.robots["cdpr"].description).weight == pytest.approx(50.0)  # its own gravity, exactly


def test_a_mass_and_a_weight_at_once_are_one_located_line(workspace, capsys):
    path = config_with(workspace, {"weight_per_length": 0.1}, {"mass": 4.4, "weight": 43.164})
    assert main(["validate", path]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cdpr.yaml" in err[0] and "end_effector.weight" in err[0], err
    assert "give end_effector.mass or end_effector.weight, not both" in err[0]
