"""Several recordings in one config (a csv or tum source given a list of files): read as one stream with each
file's span, refused when they overlap in time or differ in columns, never linked by a factor in the graph, and
held out one at a time by `fusionkit crossval` (--by file, the default then)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.config.loader import load_config
from fusionkit.crossval.folds import Plan
from fusionkit.crossval.run import crossval
from fusionkit.pipeline import build_problem, read_sources
from fusionkit.simulate import write_dataset

SPLIT = 10.0  # s: the simulated run cut here into two recordings


@pytest.fixture(scope="module")
def two_recordings(tmp_path_factory):
    """A 20-s simulated wheels run with camera poses, written as two recordings (two files per stream)."""
    folder = tmp_path_factory.mktemp("recordings")
    write_dataset("wheels.sim", folder / "sim", ["duration=20", "path=square"], seed=1)
    wheels = np.genfromtxt(folder / "sim" / "data" / "wheels.csv", delimiter=",", names=True)
    table = np.column_stack([wheels[n] for n in wheels.dtype.names])
    camera = np.loadtxt(folder / "sim" / "data" / "camera.tum")
    for k, part in enumerate((table[:, 0] < SPLIT, table[:, 0] >= SPLIT)):
        np.savetxt(folder / f"wheels{k}.csv", table[part], delimiter=",", header=",".join(wheels.dtype.names),
                   comments="", fmt="%.12g")
        np.savetxt(folder / f"camera{k}.tum", camera[(camera[:, 0] < SPLIT) == (k == 0)], fmt="%.12g")
    config = yaml.safe_load((folder / "sim" / "config.yaml").read_text())
    config["robots"]["robot"]["description"] = "sim/robots/robot.yaml"
    config["sources"] = [{"type": "csv", "name": "wheels", "path": ["wheels0.csv", "wheels1.csv"]},
                         {"type": "tum", "name": "camera", "path": ["camera0.tum", "camera1.tum"]}]
    config["factors"].append({"type": "pose.absolute", "robot": "robot", "stream": "camera",
                              "sigma": {"rotation": 0.02, "translation": 0.0028}})
    config.pop("truth")
    (folder / "two.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return folder / "two.yaml"


def test_a_source_given_two_files_reads_one_stream_with_each_files_span(two_recordings):
    streams, _ = read_sources(load_config(two_recordings))
    wheels = streams["wheels"]
    assert [p[0].rsplit("/", 1)[1] for p in wheels.parts] == ["wheels0.csv", "wheels1.csv"]
    assert wheels.parts[0][2] < SPLIT <= wheels.parts[1][1]
    assert len(wheels) == sum(len(np.loadtxt(p[0], delimiter=",", skiprows=1)) for p in wheels.parts)


def test_no_factor_links_the_states_of_two_recordings(two_recordings):
    config = load_config(two_recordings)
    streams, _ = read_sources(config)
    problem = build_problem(config, streams)
    end, start = streams["wheels"].parts[0][2], streams["wheels"].parts[1][1]
    for r in problem.records:
        times = [problem.key_time[k] for k in r.factor.keys() if problem.key_time[k] != float("-inf")]
        assert not times or max(times) <= end or min(times) >= start
    assert any("that would link the states of two recordings (starting at t = 10" in n for n in problem.notes)


def test_crossval_holds_out_one_recording_at_a_time_by_default(two_recordings):
    out = crossval(str(two_recordings), [], Plan("auto", leave_one_out=True), ["wheels"])
    assert out.plan.by == "file" and len(out.folds) == 2
    assert out.plan.describe() == "leave one recording (file) out"
    camera = "factors[5]:pose.absolute"
    assert [f["anchored_by"] for f in out.folds] == [[], [camera]]  # the first starts at the origin prior
    assert 0 < out.pooled[camera]["parts"]["position"]["rmse"] < 0.02


@pytest.mark.parametrize("name, second, says", [
    ("early.csv", "t,left,right,passive,gyro\n5.0,0,0,0,0\n", "early.csv: starts at t = 5.000000 s, before"),
    ("short.csv", "t,left,right\n30.0,0,0\n", "short.csv: columns left, right; the first recording of stream"),
])
def test_recordings_that_overlap_or_differ_in_columns_are_one_line_errors(two_recordings, capsys, name, second, says):
    (two_recordings.parent / name).write_text(second)
    assert main(["validate", str(two_recordings), "--set", f"sources.0.path=[wheels0.csv, {name}]"]) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and len(err.splitlines()) == 1


def test_untimed_files_of_a_csv_source_with_time_row_are_numbered_on_across_files(tmp_path):
    """`time: row`: rows of files without a `t` column are numbered 0, 1, ... and the next file's continue after
    the previous file's last sample; a file with its own `t` keeps it."""
    from fusionkit.components import Spec
    from fusionkit.data.builtin_sources import CsvSource
    (tmp_path / "a.csv").write_text("x\n1\n2\n3\n")
    (tmp_path / "b.csv").write_text("x\n4\n5\n")
    (tmp_path / "c.csv").write_text("t,x\n7.5,6\n8.0,7\n")
    (tmp_path / "d.csv").write_text("x\n8\n")
    from fusionkit.config.yamlio import Document
    spec = Spec({"name": "s", "path": ["a.csv", "b.csv", "c.csv", "d.csv"], "time": "row"},
                Document({}, tmp_path / "config.yaml"), ("sources", 0))
    stream = CsvSource().read(spec, tmp_path).streams["s"]
    assert stream.t.tolist() == [0, 1, 2, 3, 4, 7.5, 8.0, 9]
    assert stream.column("x").tolist() == [1, 2, 3, 4, 5, 6, 7, 8]
