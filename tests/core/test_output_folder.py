"""`--out DIR` never loses a user's file: DIR is replaced only when it is absent, empty or an earlier
fusionkit output (marker `.fusionkit-output`), never when it is or holds an input; errors leave no
temporary folder. Every case checks the user's files byte for byte."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from fusionkit.cli.main import main
from fusionkit.report.writer import MARKER
from fusionkit.simulate import write_dataset

FAST = ["--no-plots", "-q"]


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under `folder` (hidden ones too) by relative path, with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("sim") / "proj"
    write_dataset("pose.scaled_vo", folder, ["duration=4"], seed=2)
    (folder / MARKER).unlink()  # from here on it is the user's project, not a fusionkit output
    return folder


@pytest.fixture
def project(dataset, tmp_path) -> Path:
    """A fresh copy of a user's project: config.yaml, data/, robots/, truth/ and a notes file."""
    proj = tmp_path / "projdir"
    shutil.copytree(dataset, proj)
    (proj / "notes.txt").write_text("my lab notes\n")
    return proj


def refused(capsys, args: list[str], why: str) -> str:
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and why in err, err
    return err


@pytest.mark.parametrize("out, why", [
    ("data", "the folder holds an input of this run"),             # the data folder
    ("data/mocap.tum", "exists and is not a folder"),               # a data file itself
    ("../projdir", "the folder holds an input of this run"),       # the config's own folder
    (".", "the folder holds an input of this run"),                # the same, as `.`
    ("..", "the folder holds an input of this run"),               # an ancestor of every input
    ("robots", "the folder holds an input of this run"),           # the robot descriptions
    ("truth", "the folder holds an input of this run"),            # the truth files
])
def test_out_that_is_or_holds_an_input_is_refused_and_nothing_changes(project, monkeypatch, capsys, out, why):
    monkeypatch.chdir(project)
    before = snapshot(project.parent)
    refused(capsys, ["run", "config.yaml", "--out", out, *FAST], why)
    assert snapshot(project.parent) == before  # byte for byte, and no hidden temporary folder


def test_out_with_a_file_fusionkit_did_not_write_is_refused(project, capsys):
    results = project.parent / "results"
    results.mkdir()
    (results / "notes.txt").write_text("unrelated\n")
    before = snapshot(project.parent)
    err = refused(capsys, ["run", str(project / "config.yaml"), "--out", str(results), *FAST],
                  "is not empty and was not written by fusionkit")
    assert "choose a new or empty folder" in err
    assert snapshot(project.parent) == before


def test_empty_folder_and_current_folder_receive_the_outputs(project, tmp_path, monkeypatch, capsys):
    here = tmp_path / "empty"
    here.mkdir()
    monkeypatch.chdir(here)
    assert main(["run", str(project / "config.yaml"), "--out", ".", *FAST]) == 0
    assert sorted(p.name for p in here.iterdir()) == [MARKER, "calibration.yaml", "report.html", "report.json",
                                                      "scene.json", "trajectories"]
    marker = json.loads((here / MARKER).read_text())
    assert marker["written_by"] == "fusionkit run"
    assert marker["entries"] == ["calibration.yaml", "report.html", "report.json", "scene.json", "trajectories"]


def test_earlier_output_is_replaced_but_a_file_the_user_added_stays(project, tmp_path, capsys):
    out = tmp_path / "result"
    config = str(project / "config.yaml")
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    (out / "my_comments.txt").write_text("keep me\n")
    (out / "report.json").write_text("edited by fusionkit's earlier run only")
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    assert (out / "my_comments.txt").read_text() == "keep me\n"
    assert json.loads((out / "report.json").read_text())["name"]  # the new report replaced the old one
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "calibration.yaml", "my_comments.txt", "report.html",
                                                     "report.json", "scene.json", "trajectories"]
    assert [p.name for p in tmp_path.iterdir() if p.name != "projdir"] == ["result"]


def test_a_user_file_with_an_output_name_is_never_overwritten(project, tmp_path, capsys):
    out = tmp_path / "result"
    config = str(project / "config.yaml")
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    marker = json.loads((out / MARKER).read_text())
    marker["entries"].remove("calibration.yaml")  # as if the user had put their own calibration.yaml there
    (out / MARKER).write_text(json.dumps(marker))
    (out / "calibration.yaml").write_text("the user's own calibration\n")
    before = snapshot(out)
    refused(capsys, ["run", config, "--out", str(out), *FAST], "calibration.yaml in the folder was not written by "
            "fusionkit")
    assert snapshot(out) == before


def test_a_failure_while_writing_leaves_no_folder_behind(project, tmp_path, capsys, monkeypatch):
    import fusionkit.report.outputs as outputs

    def half_written(result, folder, plots=True):
        (folder / "report.json").write_text("{")
        raise OSError(28, "No space left on device", str(folder / "calibration.yaml"))

    monkeypatch.setattr(outputs, "write_outputs", half_written)
    out = tmp_path / "new" / "deeper" / "result"
    refused(capsys, ["run", str(project / "config.yaml"), "--out", str(out), *FAST], "No space left on device")
    assert not (tmp_path / "new").exists()
    earlier = tmp_path / "earlier"
    monkeypatch.undo()
    assert main(["run", str(project / "config.yaml"), "--out", str(earlier), *FAST]) == 0
    before = snapshot(earlier)
    monkeypatch.setattr(outputs, "write_outputs", half_written)
    refused(capsys, ["run", str(project / "config.yaml"), "--out", str(earlier), *FAST], "No space left on device")
    assert snapshot(earlier) == before  # the earlier output is untouched, no temporary folder inside


def test_simulate_refuses_a_folder_it_did_not_write_and_replaces_its_own(tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("\\section{}\n")
    before = snapshot(tmp_path)
    refused(capsys, ["simulate", "pose.scaled_vo", "--out", str(mine), "--set", "duration=3"],
            "was not written by fusionkit")
    assert snapshot(tmp_path) == before
    sim = tmp_path / "sim"
    for seed in ("1", "2"):
        assert main(["simulate", "pose.scaled_vo", "--out", str(sim), "--set", "duration=3", "--seed", seed]) == 0
    assert sorted(p.name for p in sim.iterdir()) == [MARKER, "config.yaml", "data", "robots", "truth"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine", "sim"]
