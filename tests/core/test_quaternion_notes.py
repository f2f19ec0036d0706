"""Quaternions whose norm is far from 1 are renormalized and counted in a note (file, count, first place) that
reaches the summary, report.json `notes` and `validate`; the estimate is the one of the unit quaternions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fusionkit.cli.main import main
from fusionkit.data.files import read_csv_stream, read_tum, unit_quaternions
from fusionkit.data.rosbag_reader import read_bag

from test_rosbag import POSE_TYPE, POSES, bag_path, write_bag


def scale_quaternions(path: Path, rows: list[int], factor: float) -> list[int]:
    """Multiply qx qy qz qw of the given data rows (0-based) of a TUM file by `factor`; their line numbers."""
    lines = path.read_text().splitlines()
    data = [i for i, line in enumerate(lines) if not line.startswith("#")]
    for r in rows:
        f = lines[data[r]].split()
        lines[data[r]] = " ".join(f[:4] + [f"{float(x) * factor:.9f}" for x in f[4:]])
    path.write_text("\n".join(lines) + "\n")
    return [data[r] + 1 for r in rows]


def test_unit_quaternions_rescales_and_counts_only_rows_beyond_the_tolerance():
    q = np.array([[0, 0, 0, 1.0005], [0, 0, 0, 2.0], [0, 0.6, 0, 0.8 * 0.99], [0, 0, 0, 1.0]])
    note = unit_quaternions(q, "f.tum", lambda i: f"line {i + 10}")
    assert note == "f.tum: 2 of 4 quaternions had a norm off 1 by more than 0.001 (largest 1, first at line 11); " \
                   "renormalized"
    np.testing.assert_array_equal(q[[0, 3]], [[0, 0, 0, 1.0005], [0, 0, 0, 1.0]])  # within 1e-3: as read
    np.testing.assert_allclose(np.linalg.norm(q[[1, 2]], axis=1), 1.0, rtol=0, atol=1e-15)
    assert unit_quaternions(np.array([[0.0, 0, 0, 1]]), "f", str) is None


def test_tum_and_csv_streams_carry_the_note(tmp_path):
    tum = tmp_path / "p.tum"
    tum.write_text("# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n# gap\n1 0 0 0 0 0 0 1.5\n2 0 0 0 0 0 0 1\n")
    s = read_tum(tum, "p")
    assert s.notes == [f"{tum}: 1 of 3 quaternions had a norm off 1 by more than 0.001 (largest 0.5, first at "
                       "line 4); renormalized"]
    assert s.values[1, 6] == 1.0
    csv = tmp_path / "p.csv"
    csv.write_text("t,qw,qx,qy,qz,x,y,z\n0,1,0,0,0,0,0,0\n1,0.9,0,0,0,0,0,0\n")
    s = read_csv_stream(csv, "p")
    assert s.notes == [f"{csv}: 1 of 2 quaternions had a norm off 1 by more than 0.001 (largest 0.1, first at "
                       "line 3); renormalized"]
    assert s.column("qw")[1] == 1.0


@pytest.mark.parametrize("ros", [1, 2])
def test_bag_pose_topic_carries_the_note_located_by_time(tmp_path, ros):
    def edit(topic, k, m):
        if topic == "/mocap" and k in (3, 7):
            msg = m.make(POSE_TYPE, k)
            q = msg.pose.orientation
            msg.pose.orientation = m.T["geometry_msgs/msg/Quaternion"](q.x * 1.1, q.y * 1.1, q.z * 1.1, q.w * 1.1)
            return msg

    bag = write_bag(bag_path(tmp_path, ros), ros, edit=edit)
    s = read_bag(bag, {"/mocap": "mocap"})["mocap"]
    assert len(s.notes) == 1
    assert s.notes[0].startswith(f"{bag} topic /mocap: 2 of 25 quaternions had a norm off 1 by more than 0.001 "
                                 "(largest 0.1, first at t = 1700000000.300")
    np.testing.assert_allclose(s.values[:, 3:7], POSES[:, 3:], rtol=0, atol=1e-12)


def test_run_notes_renormalized_quaternions_and_estimates_as_with_unit_ones(ds, tmp_path, capsys):
    assert main(["run", str(ds / "config.yaml"), "--out", str(tmp_path / "clean"), "--no-plots"]) == 0
    clean = json.loads((tmp_path / "clean" / "report.json").read_text())
    capsys.readouterr()
    lines = scale_quaternions(ds / "data" / "vo.tum", [10, 11, 50, 51, 52], 1.05)
    truth_lines = scale_quaternions(ds / "truth" / "cam.tum", [0], 0.9)
    assert main(["run", str(ds / "config.yaml"), "--out", str(tmp_path / "scaled"), "--no-plots"]) == 0
    out = capsys.readouterr().out
    report = json.loads((tmp_path / "scaled" / "report.json").read_text())
    data_note = (f"{ds / 'data' / 'vo.tum'}: 5 of 180 quaternions had a norm off 1 by more than 0.001 (largest 0.05, "
                 f"first at line {lines[0]}); renormalized")
    truth_note = (f"{ds / 'truth' / 'cam.tum'}: 1 of 180 quaternions had a norm off 1 by more than 0.001 (largest "
                  f"0.1, first at line {truth_lines[0]}); renormalized")
    assert data_note in report["notes"] and truth_note in report["notes"]
    assert f"  note: {data_note}" in out.splitlines() and f"  note: {truth_note}" in out.splitlines()
    scale, clean_scale = report["parameters"]["cam"]["vo_scale"], clean["parameters"]["cam"]["vo_scale"]
    assert scale["value"] == pytest.approx(clean_scale["value"], rel=1e-7)
    ate = report["evaluation"]["trajectories"]["cam"]["ate_rmse_m"]
    assert ate == pytest.approx(clean["evaluation"]["trajectories"]["cam"]["ate_rmse_m"], rel=1e-6)
    assert main(["validate", str(ds / "config.yaml")]) == 0
    assert f"  note: {data_note}" in capsys.readouterr().out.splitlines()
