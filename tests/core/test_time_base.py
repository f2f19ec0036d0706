"""Times that are not seconds, and truth on another clock: one located line (exit 2) before solving, never
an internal error; the summary and report.json say how many states the ATE covers."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import fusionkit
from fusionkit.cli.main import main
from fusionkit.data.files import read_csv_stream, read_tum
from fusionkit.data.stream import pose_stream
from fusionkit.errors import DataError
from fusionkit.eval.notes import evaluation_notes
from fusionkit.pipeline import Truth, evaluate
from fusionkit.report.summary import summary_text

from test_rosbag import POSES, T, bag_path, write_bag, write_config

PREFIX = "fusionkit: error: "


def one_error_line(capsys, argv: list[str]) -> str:
    """Run the CLI; assert exit 2 and exactly one stderr line (no traceback, no internal error); return it."""
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(PREFIX), err
    assert "internal error" not in err and "Traceback" not in err
    return lines[0][len(PREFIX):]


def rewrite_tum_times(path: Path, convert) -> None:
    """Replace the time column of a TUM file by convert(t) (a string per time)."""
    out = []
    for line in path.read_text().splitlines():
        if line.startswith("#"):
            out.append(line)
            continue
        t, rest = line.split(" ", 1)
        out.append(f"{convert(float(t))} {rest}")
    path.write_text("\n".join(out) + "\n")


# ---------------------------------------------------------------- times that are not seconds


def tum_text(t: np.ndarray, fmt: str = "{:.0f}") -> str:
    return "# t x y z qx qy qz qw\n" + "".join(f"{fmt.format(x)} 1 2 3 0 0 0 1\n" for x in t)


@pytest.mark.parametrize("t, unit, factor", [
    (np.arange(600) * 33_333_333.0, "nanoseconds", "1e9"),            # from 0, 30 Hz, in ns
    (1.7e18 + np.arange(50) * 1e7, "nanoseconds", "1e9"),              # Unix time in ns
    (1.7e15 + np.arange(50) * 1e4, "microseconds", "1e6"),             # Unix time in us
    (1.7e12 + np.arange(50) * 10.0, "milliseconds", "1e3"),            # Unix time in ms
])
def test_tum_times_that_are_not_seconds_are_refused_naming_the_unit(tmp_path, t, unit, factor):
    path = tmp_path / "mocap.tum"
    path.write_text(tum_text(t))
    with pytest.raises(DataError) as err:
        read_tum(path, "mocap")
    assert str(err.value).startswith(f"{path}:2: timestamps look like {unit} (t = ")
    assert str(err.value).endswith(f"fusionkit expects seconds: divide t by {factor}")


def test_csv_times_in_nanoseconds_are_refused_at_the_first_data_line(tmp_path):
    path = tmp_path / "enc.csv"
    path.write_text("# encoder\nt,l0\n" + "".join(f"{k * 10_000_000},{k * 0.1}\n" for k in range(20)))
    with pytest.raises(DataError) as err:
        read_csv_stream(path, "enc")
    assert str(err.value) == (f"{path}:3: timestamps look like nanoseconds (t = 0 .. 190000000, median step 1e+07); "
                              "fusionkit expects seconds: divide t by 1e9")


@pytest.mark.parametrize("t", [1.7e9 + np.arange(100) * 0.01,       # Unix time in s, 100 Hz
                               np.arange(10) * 3600.0,              # one sample an hour
                               np.array([5.0])])                    # a single pose
def test_times_in_seconds_unix_hourly_or_single_are_read_unchanged(tmp_path, t):
    path = tmp_path / "ok.tum"
    path.write_text(tum_text(t, "{:.3f}"))
    np.testing.assert_allclose(read_tum(path, "ok").t, t, rtol=0, atol=1e-3)


def test_run_with_truth_in_nanoseconds_is_one_line_naming_the_truth_file(ds, tmp_path, capsys):
    rewrite_tum_times(ds / "truth" / "cam.tum", lambda t: f"{round(t * 1e9)}")
    line = one_error_line(capsys, ["run", str(ds / "config.yaml"), "--out", str(tmp_path / "out"), "--no-plots"])
    assert line == (f"{ds / 'truth' / 'cam.tum'}:2: timestamps look like nanoseconds (t = 0 .. 5966666667, median "
                    "step 3.33e+07); fusionkit expects seconds: divide t by 1e9")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- truth on another clock


def test_truth_at_unix_time_for_data_from_zero_is_refused_before_solving(ds, tmp_path, capsys):
    rewrite_tum_times(ds / "truth" / "cam.tum", lambda t: f"{t + 1.7e9:.9f}")
    line = one_error_line(capsys, ["validate", str(ds / "config.yaml")])
    assert line == (f"{ds / 'truth' / 'cam.tum'}: truth of robot 'cam' spans t = 1700000000.000 .. 1700000005.967 s, "
                    "its states (stream 'vo') t = 0.000 .. 5.967 s: the time ranges do not overlap; expected truth "
                    "stamped on the same clock in seconds; one looks like Unix time and the other like time since "
                    "the start of the recording: subtract the recording's start time from the Unix stamps, or add "
                    "it to the others")


@pytest.mark.parametrize("ros", [1, 2])
def test_bag_at_unix_time_with_truth_from_zero_is_one_located_line(tmp_path, capsys, ros):
    bag = write_bag(bag_path(tmp_path, ros), ros)
    cfg = write_config(tmp_path, bag)
    truth = tmp_path / "truth.tum"
    truth.write_text("".join(f"{t - T[0]:.9f} " + " ".join(f"{v:.9f}" for v in p) + "\n" for t, p in zip(T, POSES)))
    config = yaml.safe_load(cfg.read_text())
    config["truth"] = {"trajectories": {"rover": "truth.tum"}}
    cfg.write_text(yaml.safe_dump(config))
    line = one_error_line(capsys, ["run", str(cfg), "--out", str(tmp_path / "out"), "--no-plots"])
    assert line.startswith(f"{truth}: truth of robot 'rover' spans t = 0.000 .. 2.400 s, its states (stream "
                           "'odom') t = 1700000000.000 .. 1700000002.400 s: the time ranges do not overlap;")
    assert "one looks like Unix time and the other like time since the start of the recording" in line


def test_truth_within_the_data_span_but_between_the_states_is_refused(ds, tmp_path, capsys):
    # states every 1/30 s; truth stamps moved 1/60 s later sit 16.7 ms from every state (> 10 ms)
    rewrite_tum_times(ds / "truth" / "cam.tum", lambda t: f"{t + 1 / 60:.9f}")
    line = one_error_line(capsys, ["run", str(ds / "config.yaml"), "--out", str(tmp_path / "out"), "--no-plots"])
    assert line == (f"{ds / 'truth' / 'cam.tum'}: truth of robot 'cam' spans t = 0.017 .. 5.983 s, its "
                    "states (stream 'vo') t = 0.000 .. 5.967 s: no truth pose is within 0.01 s of a state; "
                    "expected truth stamped on the same clock in seconds")


# ---------------------------------------------------------------- how many states the ATE covers


def run_json(capsys, ds: Path, out: Path) -> tuple[str, dict]:
    assert main(["run", str(ds / "config.yaml"), "--out", str(out), "--no-plots"]) == 0
    text = capsys.readouterr().out
    return text, json.loads((out / "report.json").read_text())


def test_summary_prints_matched_states_and_notes_truth_of_part_of_the_run(ds, tmp_path, capsys):
    text, report = run_json(capsys, ds, tmp_path / "full")
    assert "over 180 of 180 states matched to truth (align: none)" in text
    assert report["evaluation"]["trajectories"]["cam"]["states"] == 180
    assert report["evaluation"]["trajectories"]["cam"]["matched_poses"] == 180
    assert not any("truth of cam" in n for n in report["notes"])

    truth = ds / "truth" / "cam.tum"
    lines = truth.read_text().splitlines()
    truth.write_text("\n".join(lines[:1 + 60]) + "\n")  # the header and the first 2 s of 6
    text, report = run_json(capsys, ds, tmp_path / "part")
    note = ("truth of cam: only 60 of 180 states have a truth pose within 0.01 s; the ATE and consistency cover "
            "those alone (check that truth and data share a clock)")
    assert "over 60 of 180 states matched to truth" in text
    assert f"  note: {note}" in text.splitlines()
    assert note in report["notes"]
    assert report["evaluation"]["trajectories"]["cam"]["matched_poses"] == 60


def test_a_robot_whose_estimated_states_miss_the_truth_gets_no_ate_but_a_note(ds):
    """The clock check runs on every state before solving; states the graph gave no pose (outside the span of
    the pose streams) are not estimated, so the truth can still match none of the estimated ones."""
    result = fusionkit.run(ds / "config.yaml")
    late = pose_stream("truth:cam", 100.0 + np.arange(10) * 0.1, np.tile([0, 0, 0, 0, 0, 0, 1.0], (10, 1)))
    ev = evaluate(result.config, result.trajectories, result.position_sigma, {}, Truth({"cam": late}))
    assert ev["trajectories"]["cam"] == {"states": 180, "matched_poses": 0}
    note = ("truth of cam: no truth pose within 0.01 s of any of its 180 states; no ATE (check that truth and data "
            "share a clock)")
    assert evaluation_notes(ev) == [note]
    text = summary_text(dataclasses.replace(result, evaluation=ev)).splitlines()
    assert "  cam: no ATE: 0 of 180 states matched to truth" in text and f"  note: {note}" in text


def test_states_of_a_stream_keep_only_its_samples_between_start_and_end():
    """`states: {stream, start, end}` (with or without `every`): the stream's stamps in [start, end]; without a
    window every stamp (start and end were ignored with a stream clock, so a calibration on half a recording used
    all of it)."""
    import numpy as np
    from fusionkit.data.stream import Stream
    from fusionkit.graph.builder import state_times
    stream = Stream("s", np.arange(10.0), ("x",), np.zeros((10, 1)))
    assert state_times({"stream": "s"}, {"s": stream}).tolist() == list(np.arange(10.0))
    assert state_times({"stream": "s", "start": 2.0, "end": 6.5}, {"s": stream}).tolist() == [2.0, 3.0, 4.0, 5.0, 6.0]
    assert state_times({"stream": "s", "end": 4.0, "every": 2}, {"s": stream}).tolist() == [0.0, 2.0, 4.0]
