"""Round-robin ranging logs stamp several readings alike: a long-format range stream (t, anchor id, range) with
four rows per stamp loads, pairs with the states like the wide stream it came from (the same estimate), and is
refused -- one located line -- where strictly increasing stamps are needed (one state per sample)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """uwb.sim (20 s, constant biases) written to files, plus its ranges in long format: one row per range,
    the four ranges of an epoch sharing its stamp."""
    folder = tmp_path_factory.mktemp("uwb")
    assert main(["simulate", "uwb.sim", "--out", str(folder / "sim"), "--set", "duration=20",
                 "--set", "bias_model=constant"]) == 0
    wide = np.loadtxt(folder / "sim" / "data" / "ranges_a.csv", delimiter=",", skiprows=1)
    rows = [(t, i, r) for t, *ranges in wide for i, r in enumerate(ranges)]
    (folder / "sim" / "data" / "ranges_long.csv").write_text(
        "t,id,range\n" + "".join(f"{t:.6f},{i},{r:.8f}\n" for t, i, r in rows))
    return folder / "sim"


def long_config(folder, states: dict) -> str:
    config = yaml.safe_load((folder / "config.yaml").read_text())
    config["sources"][0] = {"type": "csv", "name": "ranges_long", "path": "data/ranges_long.csv"}
    config["robots"]["a"]["states"] = {**states, "type": "pose2"}
    for entry in config["factors"][:1] + config["initializers"]:
        entry.update(stream="ranges_long", anchor_column="id", range_column="range")
    path = folder / f"long_{len(states)}.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    return str(path)


def test_a_long_format_stream_with_repeated_stamps_gives_the_wide_streams_estimate(recording):
    wide = estimate(load_config(recording / "config.yaml"))
    long = estimate(load_config(long_config(recording, {"stream": "ranges_long", "rate": 10.0})))
    a, b = wide.trajectories["a"], long.trajectories["a"]
    assert len(a) == len(b) == 200
    assert np.abs(a.pose_array() - b.pose_array()).max() < 1e-6


def test_repeated_stamps_as_a_state_clock_are_one_located_line(recording, capsys):
    path = long_config(recording, {"stream": "ranges_long"})
    assert main(["run", path, "--out", str(recording / "never"), "--no-plots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "robots.a.states.stream" in err[0], err
    assert "stamps 600 sample(s) like the one before (first at t = 0.000000 s)" in err[0]
    assert "one state per sample needs strictly increasing stamps" in err[0]
    assert not (recording / "never").exists()


def test_an_entry_that_integrates_a_stream_with_repeated_stamps_is_refused_at_its_key(recording, capsys):
    """A wheel-speed row logged twice: odometry.diff_drive integrates the speeds over time."""
    lines = (recording / "data" / "wheels_a.csv").read_text().splitlines(keepends=True)
    (recording / "data" / "wheels_twice.csv").write_text("".join(lines[:11] + lines[10:]))
    config = yaml.safe_load((recording / "config.yaml").read_text())
    config["sources"][1]["path"] = "data/wheels_twice.csv"
    path = recording / "bad.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False))
    code = main(["run", str(path), "--out", str(recording / "never"), "--no-plots"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "factors[1].stream" in err[0] and "stamps 1 sample(s) like the one before (first at t = 0.900000 s)" in err[0]
    assert "odometry.diff_drive integrates, interpolates or pairs up the samples of `stream`" in err[0], err
