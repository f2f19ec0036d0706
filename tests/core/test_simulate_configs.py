"""`fusionkit simulate` of every installed scenario: it writes a config.yaml that `fusionkit validate`
accepts, and says how to run it; a scenario that provides no config says it writes none, and
leaves no empty folder behind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fusionkit.api import Simulator, SourceOutput
from fusionkit.cli.main import main
from fusionkit.data.stream import Stream
from fusionkit.plugins import registry

SCENARIOS = registry().names("simulators")


def _empty_folders(root: Path) -> list[Path]:
    return [p for p in root.rglob("*") if p.is_dir() and not any(p.iterdir())]


@pytest.mark.parametrize("scenario", SCENARIOS)
def test_simulated_config_validates_fully_constrained_leaving_no_empty_folder(scenario, tmp_path, capsys):
    out = tmp_path / "data"
    assert main(["simulate", scenario, "--out", str(out)]) == 0
    assert f"run it with: fusionkit run {out / 'config.yaml'}" in capsys.readouterr().out
    assert main(["validate", str(out / "config.yaml")]) == 0
    assert "every variable is constrained" in capsys.readouterr().out
    assert _empty_folders(out) == []


class ConfiglessSimulator(Simulator):
    """One stream of time stamps and a constant: no truth, no robot, no config."""
    name = "test.configless"
    summary = "one stream, nothing else"
    schema = {"type": "object", "additionalProperties": False}

    def stream_columns(self, params):
        return {"level": ("value",)}

    def simulate(self, params, rng):
        t = np.arange(5.0)
        return SourceOutput({"level": Stream("level", t, ("value",), np.ones((5, 1)), "simulated:level")}, {}, {})


def test_scenario_without_config_says_so_and_writes_no_config_robots_or_truth(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(registry().components["simulators"], ConfiglessSimulator.name, ConfiglessSimulator)
    out = tmp_path / "data"
    assert main(["simulate", ConfiglessSimulator.name, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "test.configless writes no config" in printed and "run it with" not in printed
    assert (out / "data" / "level.csv").is_file()
    assert not (out / "config.yaml").exists()
    assert not (out / "robots").exists() and not (out / "truth").exists()
