"""What a config declares but nothing uses is said, not silently dropped: a robot with states and
no factor, a description parameter no factor uses, a --set that adds a key spelled almost like an
existing one. The notes reach `validate`, the run summary and report.json `notes`."""

from __future__ import annotations

import json
from pathlib import Path

from fusionkit.cli.main import main
from fusionkit.config.overrides import new_key_note

REPO = Path(__file__).resolve().parents[2]
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
FAST = ["--set", "sources.0.params.duration=4"]
IDLE_ROBOT = ["--set", "robots.idle={description: handheld_camera, states: {stream: mocap}}"]


def test_robot_with_states_but_no_factor_is_noted_in_validate(capsys):
    assert main(["validate", str(SCALED_VO), *FAST, *IDLE_ROBOT]) == 0
    out = capsys.readouterr().out
    assert "  note: robot 'idle' has 2 states but no factor uses them: they are not estimated" in out
    assert "  note: robot 'idle': parameter(s) vo_scale used by no factor: not estimated, reported nowhere" in out
    assert "robot 'cam'" not in out  # the robot the factors use gets no note


def test_unused_notes_reach_the_summary_and_the_report(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", str(SCALED_VO), *FAST, *IDLE_ROBOT, "--out", str(out), "--no-plots", "-q"]) == 0
    printed = capsys.readouterr().out
    notes = json.loads((out / "report.json").read_text())["notes"]
    idle = [n for n in notes if n.startswith("robot 'idle'")]
    assert len(idle) == 2 and all(f"note: {n}" in printed for n in idle)


def test_set_that_adds_a_key_like_an_existing_one_is_noted():
    data = {"robots": {"cam": {"description": "x.yaml", "states": {"stream": "vo"}}}}
    assert new_key_note(data, ("robots", "cam", "descripton"), "robots.cam.descripton=y.yaml") == (
        "--set robots.cam.descripton=y.yaml: the config had no key 'descripton' there and it was added; did you "
        "mean the existing 'description'?")
    assert new_key_note(data, ("robots", "cam", "overrides"), "robots.cam.overrides=c.yaml") is None  # not a typo
    assert new_key_note(data, ("robots", "cam", "states", "stream"), "robots.cam.states.stream=vo") is None
