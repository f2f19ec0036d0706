"""Streams written as ROS 1 / ROS 2 bags read back exactly; streams without a ROS message are refused before
anything is written, and `fusionkit simulate --bag` leaves no folder behind when it refuses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fusionkit.cli.main import main
from fusionkit.data.rosbag_reader import read_bag, topic_columns
from fusionkit.data.rosbag_writer import IMU_MSG, POSE_MSG, message_type, write_bag
from fusionkit.data.stream import POSE_COLUMNS, Stream, pose_stream
from fusionkit.errors import DataError
from scipy.spatial.transform import Rotation

RNG = np.random.default_rng(5)
T_POSE = np.arange(30) / 10 + 1_700_000_000.123   # epoch-sized stamps keep their nanoseconds
QUAT = Rotation.from_rotvec(RNG.normal(size=(30, 3))).as_quat()
POSES = np.column_stack([RNG.normal(size=(30, 3)), QUAT])
T_IMU = np.arange(60) / 20 + 1_700_000_000.123
IMU = RNG.normal(size=(60, 6))


def streams() -> dict[str, Stream]:
    return {"/vo": pose_stream("vo", T_POSE, POSES, "test"),
            "/imu": Stream("imu", T_IMU, ("ax", "ay", "az", "gx", "gy", "gz"), IMU, "test")}


@pytest.mark.parametrize("ros", ["ros1", "ros2"])
def test_written_poses_and_imu_samples_read_back_exactly_at_their_stamps(tmp_path: Path, ros: str):
    path = tmp_path / ("run.bag" if ros == "ros1" else "run")
    write_bag(path, streams(), ros)
    assert topic_columns(path, ["/vo", "/imu"]) == {"/vo": POSE_COLUMNS, "/imu": ("ax", "ay", "az", "gx", "gy", "gz")}
    back = read_bag(path, {"/vo": "vo", "/imu": "imu"})
    np.testing.assert_allclose(back["vo"].t, T_POSE, rtol=0, atol=5e-7)  # a double at 1.7e9 s resolves 0.24 us
    np.testing.assert_allclose(back["imu"].t, T_IMU, rtol=0, atol=5e-7)  # a double at 1.7e9 s resolves 0.24 us
    np.testing.assert_array_equal(back["vo"].values, POSES)
    np.testing.assert_array_equal(back["imu"].values, IMU)


def test_message_types_follow_the_columns_and_other_streams_are_refused():
    s = streams()
    assert message_type(s["/vo"]) == POSE_MSG and message_type(s["/imu"]) == IMU_MSG
    ranges = Stream("ranges", T_POSE, ("r0", "r1"), RNG.normal(size=(30, 2)), "test")
    with pytest.raises(DataError, match=r"stream 'ranges' \(columns r0, r1\) has no ROS message"):
        message_type(ranges)


def test_a_negative_stamp_is_refused_before_the_bag_is_made(tmp_path: Path):
    s = {"/vo": pose_stream("vo", T_POSE - T_POSE[5], POSES, "test")}
    with pytest.raises(DataError, match="cannot be negative"):
        write_bag(tmp_path / "run.bag", s, "ros1")
    assert not (tmp_path / "run.bag").exists()


def test_simulate_to_a_bag_refuses_a_scenario_with_ranges_and_writes_nothing(tmp_path: Path, capsys):
    out = tmp_path / "sim"
    assert main(["simulate", "uwb.sim", "--bag", "ros1", "--out", str(out)]) != 0
    assert "has no ROS message" in capsys.readouterr().err
    assert not out.exists()
