"""`static_segments`: the stretches in which one stream stays constant, each averaged into one sample (poses as
poses), with the other files averaged over the same stretches; a recording without a dwell is one located line."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fusionkit.cli.main import main
from fusionkit.data.static_segments import averaged, constant_stretches
from fusionkit.data.stream import POSE_COLUMNS, Stream


def test_stretches_are_the_runs_within_tolerance_that_last_long_enough():
    t = np.arange(20) * 0.5
    v = np.concatenate([np.full(6, 1.0), np.full(2, 2.0), np.full(8, 3.0) + 0.001 * np.arange(8), [9.0] * 4])[:, None]
    # 0-2.5 s at 1.0 (2.5 s), 3-3.5 s at 2.0 (too short), 4-7.5 s at 3.0 drifting 7 mm (within 0.01), 8-9.5 s at 9.0
    assert constant_stretches(t, v, 0.01, 1.0) == [(0.0, 2.5), (4.0, 7.5), (8.0, 9.5)]
    assert constant_stretches(t, v, 0.005, 1.0) == [(0.0, 2.5), (4.0, 6.5), (8.0, 9.5)]


def test_poses_average_to_the_mean_position_and_the_mean_rotation():
    t = np.arange(6) * 0.25
    swing = 0.05 * np.sin(np.arange(6) * np.pi / 3)  # sums to zero
    quats = Rotation.from_rotvec(np.outer(swing, [0.0, 0.0, 1.0]) + [0.1, 0.0, 0.0]).as_quat()
    poses = Stream("p", t, POSE_COLUMNS, np.column_stack([1.0 + swing, np.zeros((6, 2)), quats]))
    out = averaged(poses, [(0.0, 1.25)])
    np.testing.assert_allclose(out.t, [0.625])
    np.testing.assert_allclose(out.values[0, :3], [1.0, 0.0, 0.0], atol=1e-12)
    assert Rotation.from_quat(out.values[0, 3:]).as_rotvec() == pytest.approx([0.1, 0.0, 0.0], abs=1e-4)


def test_pose_columns_in_another_order_and_extra_columns_average_in_place():
    t = np.arange(4) * 0.5
    quats = Rotation.from_rotvec([[0.0, 0.0, a] for a in (0.1, 0.2, 0.3, 0.2)]).as_quat()
    columns = ("qw", "qx", "qy", "qz", "x", "y", "z", "speed")
    values = np.column_stack([quats[:, 3], quats[:, :3], np.arange(4), np.zeros((4, 2)), [1, 2, 3, 2]])
    out = averaged(Stream("p", t, columns, values), [(0.0, 1.5)])
    row = dict(zip(out.columns, out.values[0]))
    assert row["x"] == pytest.approx(1.5) and row["speed"] == pytest.approx(2.0)
    rot = Rotation.from_quat([row["qx"], row["qy"], row["qz"], row["qw"]]).as_rotvec()
    assert rot == pytest.approx([0.0, 0.0, 0.2], abs=1e-3)


def test_a_recording_without_a_dwell_is_one_located_line(workspace, capsys):
    t = np.arange(50) * 0.1
    source = workspace.columns("lengths", t, l0=1.0 + t)  # always moving
    workspace.config({"name": "r"}, "robot.yaml")
    config = {"robots": {"r": {"description": "robot.yaml", "states": {"stream": "lengths"}}},
              "sources": [{"type": "static_segments", "segments_from": {"name": "lengths", "path": source["path"]},
                           "tolerance": 0.001, "min_duration": 1.0}],
              "factors": [{"type": "pose.origin", "robot": "r", "sigma": {"rotation": 0.1, "translation": 0.1}}]}
    path = workspace.config(config)
    assert main(["run", str(path), "--out", str(workspace.folder / "out"), "--no-plots"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "sources[0].segments_from" in err[0] and "no static stretch" in err[0], err
