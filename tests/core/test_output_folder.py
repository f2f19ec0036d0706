"""`--out DIR` never loses a user's file: DIR is replaced only when it is absent, empty or an earlier
fusionkit output (marker `.fusionkit-output`), never when it is or holds an input; errors leave no
temporary folder. Only the files the marker lists are ever replaced or removed: a user's file at any
depth stays. Every case checks the user's files byte for byte."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from fusionkit.cli.main import main
from fusionkit.errors import FusionkitError
from fusionkit.report.writer import MARKER, write_output_folder
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
    assert marker["files"] == sorted(name for name in snapshot(here) if name != MARKER)  # every file, at any depth
    assert marker["folders"] == ["trajectories"]


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
    marker["files"].remove("calibration.yaml")
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


# --- files at every depth (issue 31): only files the marker lists are ever replaced or removed -------------

USER_FILES = {  # what a user adds to an earlier output, at depths 0 to 3
    "notes.md": b"# what I saw\n",
    "plots/annotated.png": b"\x89PNG my annotations\x00\xff",
    "plots/mine/deep.txt": b"deep\n",
    "trajectories/robot_aligned.tum": b"0 1 2 3 0 0 0 1\n",
    "trajectories/mine/deeper/deepest.bin": bytes(range(256)),
}


def add_user_files(out: Path) -> None:
    for rel, content in USER_FILES.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(content)


@pytest.fixture(scope="module")
def two_runs(dataset, tmp_path_factory) -> dict:
    """`run --out OUT` with plots, the user's files added (and two of fusionkit's files edited), then
    `run --out OUT` again without plots: the folder after each step."""
    out = tmp_path_factory.mktemp("two_runs") / "out"
    config = str(dataset / "config.yaml")
    assert main(["run", config, "--out", str(out), "-q"]) == 0
    first = snapshot(out)
    add_user_files(out)
    (out / "trajectories" / "cam.tum").write_text("edited\n")
    (out / "report.json").write_text("edited\n")
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    return {"out": out, "first": first, "second": snapshot(out), "marker": json.loads((out / MARKER).read_text())}


def test_a_second_run_keeps_user_files_at_depths_0_to_3_byte_for_byte(two_runs):
    for rel, content in USER_FILES.items():
        assert two_runs["second"][rel] == content, rel


def test_a_second_run_replaces_the_files_it_writes_again(two_runs):
    second = two_runs["second"]
    assert second["trajectories/cam.tum"] == two_runs["first"]["trajectories/cam.tum"]  # the same run again
    assert json.loads(second["report.json"])["name"]


def test_a_second_run_removes_the_files_only_the_first_run_wrote(two_runs):
    first_plots = {rel for rel in two_runs["first"] if rel.startswith("plots/")}
    assert first_plots >= {"plots/residuals.png", "plots/trajectory.png"}
    assert not first_plots & set(two_runs["second"])
    assert sorted(two_runs["second"]) == sorted([MARKER, *two_runs["marker"]["files"], *USER_FILES])
    assert (two_runs["out"] / "plots" / "mine").is_dir()  # plots/ stays: the user's files are in it


def test_the_marker_lists_every_file_of_the_last_run_and_only_those(two_runs):
    marker = two_runs["marker"]
    assert marker["files"] == ["calibration.yaml", "report.html", "report.json", "scene.json", "trajectories/cam.tum"]
    assert marker["folders"] == ["trajectories"]  # plots/ is no longer fusionkit's: only the user's files are left
    assert marker["entries"] == ["calibration.yaml", "report.html", "report.json", "scene.json", "trajectories"]


def test_a_user_file_at_the_path_of_a_new_plot_is_refused_and_nothing_changes(project, tmp_path, capsys):
    out = tmp_path / "result"
    config = str(project / "config.yaml")
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    add_user_files(out)
    (out / "plots" / "residuals.png").write_bytes(b"the user's own residual plot")  # a run with plots writes it
    before = snapshot(tmp_path)
    err = refused(capsys, ["run", config, "--out", str(out), "-q"],
                  "plots/residuals.png in the folder was not written by fusionkit")
    assert "(nothing was changed)" in err
    assert snapshot(tmp_path) == before  # byte for byte, and no temporary folder left


def test_an_old_marker_of_top_level_entries_never_deletes_a_user_file(project, tmp_path, capsys):
    out = tmp_path / "result"
    config = str(project / "config.yaml")
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    (out / "plots").mkdir()
    (out / "plots" / "residuals.png").write_bytes(b"an older fusionkit's plot")
    (out / "old_summary.txt").write_text("an older fusionkit's file\n")
    (out / MARKER).write_text(json.dumps({  # as fusionkit wrote it before markers listed every file
        "written_by": "fusionkit run", "fusionkit_version": "0.0.9",
        "entries": ["calibration.yaml", "old_summary.txt", "plots", "report.html", "report.json", "scene.json",
                    "trajectories"]}))
    add_user_files(out)
    (out / "trajectories" / "cam.tum").write_text("edited\n")
    before = snapshot(out)
    assert main(["run", config, "--out", str(out), *FAST]) == 0
    after = snapshot(out)
    for rel, content in USER_FILES.items():
        assert after[rel] == content, rel
    assert after["plots/residuals.png"] == before["plots/residuals.png"]  # in a listed folder, not known to be
    assert "old_summary.txt" not in after                                # fusionkit's; a listed file is
    assert after["trajectories/cam.tum"] != b"edited\n"  # written again in a listed folder: replaced
    marker = json.loads(after[MARKER])
    assert "trajectories/cam.tum" in marker["files"] and "plots/residuals.png" not in marker["files"]


def test_an_old_marker_folder_the_new_output_does_not_write_keeps_every_file_in_it(tmp_path):
    out = tmp_path / "out"
    (out / "plots" / "mine").mkdir(parents=True)
    (out / "plots" / "residuals.png").write_bytes(b"old plot")
    (out / "plots" / "mine" / "deep.txt").write_bytes(b"deep")
    (out / MARKER).write_text(json.dumps({"written_by": "fusionkit run", "entries": ["plots", "report.json"]}))
    (out / "report.json").write_text("{}")
    write_output_folder(out, "test", {"report.json": "{\"new\": 1}"})
    assert snapshot(out) == {MARKER: (out / MARKER).read_bytes(), "plots/mine/deep.txt": b"deep",
                             "plots/residuals.png": b"old plot", "report.json": b"{\"new\": 1}"}


def test_write_output_folder_removes_its_stale_files_and_then_empty_folders_it_created(tmp_path):
    out = tmp_path / "out"
    write_output_folder(out, "test", {"a/b/c.txt": "1", "a/d.txt": "2", "e/f/g.txt": "3", "top.txt": "4"})
    (out / "a" / "b" / "mine.txt").write_text("the user's")
    (out / "empty_by_user").mkdir()
    write_output_folder(out, "test", {"top.txt": "5", "h/i.txt": "6"})
    assert snapshot(out) == {MARKER: (out / MARKER).read_bytes(), "a/b/mine.txt": b"the user's",
                             "h/i.txt": b"6", "top.txt": b"5"}
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_dir()) == \
        ["a", "a/b", "empty_by_user", "h"]  # e/ and e/f/ were fusionkit's and are empty: removed
    assert json.loads((out / MARKER).read_text())["folders"] == ["h"]


def test_a_fusionkit_folder_holding_only_its_own_files_makes_way_for_a_new_file(tmp_path):
    out = tmp_path / "out"
    write_output_folder(out, "test", {"x/y.txt": "1", "x/z/w.txt": "2"})
    write_output_folder(out, "test", {"x": "now a file"})
    assert snapshot(out) == {MARKER: (out / MARKER).read_bytes(), "x": b"now a file"}


@pytest.mark.parametrize("users, new, clash", [
    ({"data": b"a file"}, {"data/y.txt": "1"}, "data in the folder"),                      # a file where a folder goes
    ({"r/x.txt/mine.txt": b"m"}, {"r/x.txt": "1"}, "r/x.txt/ in the folder"),              # a folder where a file goes
    ({"r/s/t.txt": b"m"}, {"r/s/t.txt": "1", "r/u.txt": "2"}, "r/s/t.txt in the folder"),  # a file at depth 2
])
def test_a_user_path_in_the_way_of_an_output_at_any_depth_is_refused_and_nothing_changes(tmp_path, users, new,
                                                                                           clash):
    out = tmp_path / "out"
    write_output_folder(out, "test", {"r/own.txt": "fusionkit's"})
    for rel, content in users.items():
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        (out / rel).write_bytes(content)
    before = snapshot(tmp_path)
    with pytest.raises(FusionkitError, match=re.escape(clash) + ".* was not written by fusionkit.*nothing was "
                                             "changed") as info:
        write_output_folder(out, "test", new)
    assert "\n" not in str(info.value)
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("listed", ["../outside.txt", "ABSOLUTE", "sub/../../outside.txt", "sub/link/x.txt"])
def test_a_marker_path_outside_the_folder_or_through_a_link_is_never_acted_on(tmp_path, listed):
    out = tmp_path / "out"
    listed = str(tmp_path / "outside.txt") if listed == "ABSOLUTE" else listed
    (out / "sub").mkdir(parents=True)
    (tmp_path / "outside.txt").write_text("outside")
    (tmp_path / "linked").mkdir()
    (tmp_path / "linked" / "x.txt").write_text("through a link")
    (out / "sub" / "link").symlink_to(tmp_path / "linked")
    (out / MARKER).write_text(json.dumps({"entries": ["sub"], "files": [listed], "folders": ["sub"]}))
    before = snapshot(tmp_path)
    write_output_folder(out, "test", {"new.txt": "n"})
    after = snapshot(tmp_path)
    assert after.pop("out/new.txt") == b"n" and after.pop("out/" + MARKER) != before.pop("out/" + MARKER)
    assert after == before


def test_a_failure_while_moving_in_puts_every_earlier_file_back(tmp_path, monkeypatch):
    import os

    out = tmp_path / "out"
    write_output_folder(out, "test", {"a/b.txt": "1", "a/c.txt": "2", "d.txt": "3"})
    (out / "a" / "mine.txt").write_text("the user's")
    before = snapshot(tmp_path)
    rename, failed = os.rename, []

    def fail_on_the_marker(src, dst):  # the last step, after every file was moved: once (putting back works)
        if Path(dst).name == MARKER and not failed:
            failed.append(dst)
            raise OSError(28, "No space left on device", str(dst))
        rename(src, dst)

    monkeypatch.setattr(os, "rename", fail_on_the_marker)
    with pytest.raises(FusionkitError, match="No space left on device"):
        write_output_folder(out, "test", {"a/b.txt": "new", "e/f.txt": "new"})
    monkeypatch.undo()
    assert failed
    assert snapshot(tmp_path) == before
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "a", "d.txt"]  # no e/, no temporary folder
