"""ROS 1 and ROS 2 bags written with rosbags are read back exactly, directly and through a config."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

import fusionkit
from fusionkit.cli.main import main
from fusionkit.data.rosbag_reader import read_bag, topic_columns
from fusionkit.data.stream import pose_array_from, poses_from_array
from fusionkit.errors import DataError

N = 25
SEC = 1_700_000_000 + np.arange(N) // 10                   # 10 Hz, epoch-sized stamps
NSEC = (np.arange(N) % 10) * 100_000_000 + 123
T = SEC + NSEC * 1e-9
POS = np.column_stack([0.4 * np.arange(N), np.sin(0.3 * np.arange(N)), 0.02 * np.arange(N)])
QUAT = Rotation.from_euler("zyx", np.column_stack([0.1 * np.arange(N), 0.02 * np.arange(N),
                                                   -0.01 * np.arange(N)])).as_quat()  # x y z w
POSES = np.column_stack([POS, QUAT])
TWIST = np.column_stack([np.full(N, 4.0), 0.1 * np.arange(N), np.zeros(N), np.zeros(N), np.zeros(N),
                         np.full(N, 1.0)])
IMU = np.column_stack([0.01 * np.arange(N), np.zeros(N), np.full(N, 9.81), np.zeros(N), 0.5 * np.ones(N),
                       -0.25 * np.arange(N)])
JOINTS = ("shoulder", "elbow")
JPOS = np.column_stack([0.01 * np.arange(N), -0.5 + 0.02 * np.arange(N)])
JVEL = np.column_stack([np.full(N, 0.1), np.full(N, 0.2)])

POSE_TYPE, ODOM_TYPE = "geometry_msgs/msg/PoseStamped", "nav_msgs/msg/Odometry"
IMU_TYPE, JOINT_TYPE = "sensor_msgs/msg/Imu", "sensor_msgs/msg/JointState"
TOPICS = {"/mocap": POSE_TYPE, "/odom": ODOM_TYPE, "/imu": IMU_TYPE, "/joints": JOINT_TYPE,
          "/status": "std_msgs/msg/String"}


class Msgs:
    """Builds the messages of one typestore (ROS 1 headers have a seq, ROS 2 ones do not)."""

    def __init__(self, ts):
        self.ts, self.T = ts, ts.types
        self.seq = "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__

    def header(self, k: int, sec=None, nsec=None):
        extra = {"seq": k} if self.seq else {}
        stamp = self.T["builtin_interfaces/msg/Time"](sec=int(SEC[k] if sec is None else sec),
                                                      nanosec=int(NSEC[k] if nsec is None else nsec))
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id="world", **extra)

    def vec(self, v, kind="geometry_msgs/msg/Vector3"):
        return self.T[kind](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def pose(self, k: int):
        q = self.T["geometry_msgs/msg/Quaternion"](*map(float, QUAT[k]))
        return self.T["geometry_msgs/msg/Pose"](position=self.vec(POS[k], "geometry_msgs/msg/Point"),
                                                orientation=q)

    def make(self, msgtype: str, k: int, **header):
        T, h, cov = self.T, self.header(k, **header), np.zeros(36)
        if msgtype == POSE_TYPE:
            return T[POSE_TYPE](header=h, pose=self.pose(k))
        if msgtype == ODOM_TYPE:
            twist = T["geometry_msgs/msg/Twist"](linear=self.vec(TWIST[k, :3]), angular=self.vec(TWIST[k, 3:]))
            return T[ODOM_TYPE](header=h, child_frame_id="body",
                                pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(k), covariance=cov),
                                twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov))
        if msgtype == IMU_TYPE:
            return T[IMU_TYPE](header=h, orientation=T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 1.0),
                               orientation_covariance=np.zeros(9), angular_velocity=self.vec(IMU[k, 3:]),
                               angular_velocity_covariance=np.zeros(9),
                               linear_acceleration=self.vec(IMU[k, :3]),
                               linear_acceleration_covariance=np.zeros(9))
        if msgtype == JOINT_TYPE:
            return T[JOINT_TYPE](header=h, name=list(JOINTS), position=JPOS[k].copy(), velocity=JVEL[k].copy(),
                                 effort=np.zeros(0))
        return T[msgtype](data="ok")


def write_bag(path: Path, ros: int, topics=TOPICS, edit=None) -> Path:
    """A bag with N messages per topic; `edit(topic, k, msgs)` may return a replacement message."""
    ts = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    msgs = Msgs(ts)
    writer = Writer1(path) if ros == 1 else Writer2(path, version=9)
    serialize = ts.serialize_ros1 if ros == 1 else ts.serialize_cdr
    with writer as w:
        conns = {topic: w.add_connection(topic, typ, typestore=ts) for topic, typ in topics.items()}
        for k in range(N):
            for topic, typ in topics.items():
                msg = (edit and edit(topic, k, msgs)) or msgs.make(typ, k)
                w.write(conns[topic], 2_000_000_000_000_000_000 + k * 10**8, serialize(msg, typ))
    return path


def bag_path(tmp_path: Path, ros: int) -> Path:
    return tmp_path / ("run.bag" if ros == 1 else "run_ros2")


@pytest.fixture(params=[1, 2], ids=["ros1", "ros2"])
def bag(request, tmp_path: Path) -> Path:
    return write_bag(bag_path(tmp_path, request.param), request.param)


def test_topic_columns_name_the_fields_of_each_message_type(bag: Path) -> None:
    cols = topic_columns(bag, ["/mocap", "/odom", "/imu", "/joints"])
    assert cols == {"/mocap": ("x", "y", "z", "qx", "qy", "qz", "qw"),
                    "/odom": ("x", "y", "z", "qx", "qy", "qz", "qw", "vx", "vy", "vz", "wx", "wy", "wz"),
                    "/imu": ("ax", "ay", "az", "gx", "gy", "gz"),
                    "/joints": ("shoulder", "elbow", "v_shoulder", "v_elbow")}


def test_read_bag_gives_the_exact_values_at_the_header_stamps(bag: Path) -> None:
    s = read_bag(bag, {"/mocap": "mocap", "/odom": "odom", "/imu": "imu", "/joints": "joints"})
    assert set(s) == {"mocap", "odom", "imu", "joints"}
    for stream in s.values():
        np.testing.assert_array_equal(stream.t, T)  # header stamps, not receive times
        assert str(bag) in stream.origin
    assert s["mocap"].name == "mocap" and s["mocap"].is_pose
    np.testing.assert_array_equal(s["mocap"].values, POSES)
    np.testing.assert_array_equal(s["odom"].values, np.column_stack([POSES, TWIST]))
    np.testing.assert_array_equal(s["imu"].values, IMU)
    np.testing.assert_array_equal(s["joints"].values, np.column_stack([JPOS, JVEL]))
    np.testing.assert_array_equal(s["joints"].column("elbow"), JPOS[:, 1])
    np.testing.assert_array_equal(s["joints"].column("v_shoulder"), JVEL[:, 0])


@pytest.mark.parametrize("ros", [1, 2])
def test_other_pose_messages_and_joints_without_velocity_read_exactly(tmp_path: Path, ros: int) -> None:
    topics = {"/pwc": "geometry_msgs/msg/PoseWithCovarianceStamped", "/tf": "geometry_msgs/msg/TransformStamped",
              "/joints": JOINT_TYPE}

    def edit(topic, k, m):
        T, h = m.T, m.header(k)
        if topic == "/pwc":
            return T[topics[topic]](header=h, pose=T["geometry_msgs/msg/PoseWithCovariance"](
                pose=m.pose(k), covariance=np.zeros(36)))
        if topic == "/tf":
            tf = T["geometry_msgs/msg/Transform"](translation=m.vec(POS[k]), rotation=m.pose(k).orientation)
            return T[topics[topic]](header=h, child_frame_id="body", transform=tf)
        return T[JOINT_TYPE](header=h, name=list(JOINTS), position=JPOS[k].copy(), velocity=np.zeros(0),
                             effort=np.zeros(0))

    path = write_bag(bag_path(tmp_path, ros), ros, topics, edit)
    assert topic_columns(path, ["/joints"]) == {"/joints": JOINTS}
    s = read_bag(path, {"/pwc": "a", "/tf": "b", "/joints": "j"})
    for name in "ab":
        np.testing.assert_array_equal(s[name].t, T)
        np.testing.assert_array_equal(s[name].values, POSES)
    np.testing.assert_array_equal(s["j"].values, JPOS)


@pytest.mark.parametrize("ros", [1, 2])
def test_header_stamps_out_of_order_are_sorted(tmp_path: Path, ros: int) -> None:
    swap = {3: 4, 4: 3}  # messages 3 and 4 carry each other's stamps (and data)

    def edit(topic, k, m):
        return m.make(POSE_TYPE, swap.get(k, k))

    path = write_bag(bag_path(tmp_path, ros), ros, {"/mocap": POSE_TYPE}, edit)
    s = read_bag(path, {"/mocap": "mocap"})["mocap"]
    np.testing.assert_array_equal(s.t, T)
    np.testing.assert_array_equal(s.values, POSES)


@pytest.mark.parametrize("ros", [1, 2])
def test_repeated_stamps_are_an_error(tmp_path: Path, ros: int) -> None:
    def edit(topic, k, m):
        return m.make(IMU_TYPE, k, sec=SEC[0], nsec=NSEC[0]) if k in (5, 9) else None

    path = write_bag(bag_path(tmp_path, ros), ros, {"/imu": IMU_TYPE}, edit)
    with pytest.raises(DataError, match=r"topic /imu: 2 of 25 messages repeat an earlier header stamp \(first at "
                                        r"t = 1700000000\.000000 s\)"):
        read_bag(path, {"/imu": "imu"})


@pytest.mark.parametrize("ros", [1, 2])
def test_zero_quaternion_and_nan_are_errors(tmp_path: Path, ros: int) -> None:
    def edit(topic, k, m):
        msg = m.make(topics[topic], k)
        if topic == "/mocap" and k in (2, 3):
            msg.pose.orientation = m.T["geometry_msgs/msg/Quaternion"](0.0, 0.0, 0.0, 0.0)
        if topic == "/imu" and k == 4:
            msg.angular_velocity.z = float("nan")
        return msg

    topics = {"/mocap": POSE_TYPE, "/imu": IMU_TYPE}
    path = write_bag(bag_path(tmp_path, ros), ros, topics, edit)
    with pytest.raises(DataError, match=rf"topic /mocap: 2 of 25 messages have a zero quaternion \(first at "
                                        rf"t = {T[2]:.6f} s\)"):
        read_bag(path, {"/mocap": "mocap"})
    with pytest.raises(DataError, match=r"topic /imu: 1 of 25 messages contain NaN or infinite values"):
        read_bag(path, {"/imu": "imu"})


@pytest.mark.parametrize("ros", [1, 2])
def test_changed_joint_names_are_an_error_naming_the_message(tmp_path: Path, ros: int) -> None:
    def edit(topic, k, m):
        if k == 7:
            return m.T[JOINT_TYPE](header=m.header(k), name=["elbow", "shoulder"], position=JPOS[k].copy(),
                                   velocity=JVEL[k].copy(), effort=np.zeros(0))

    path = write_bag(bag_path(tmp_path, ros), ros, {"/joints": JOINT_TYPE}, edit)
    with pytest.raises(DataError, match=r"topic /joints: message 8 names joints elbow, shoulder; the first "
                                        r"message named shoulder, elbow"):
        read_bag(path, {"/joints": "joints"})


def test_missing_and_unsupported_topics_are_errors_listing_what_is_there(bag: Path) -> None:
    with pytest.raises(DataError) as exc:
        topic_columns(bag, ["/mocap", "/vicon"])
    msg = str(exc.value)
    assert str(bag) in msg and "'/vicon' is not in the bag" in msg
    for topic, typ in TOPICS.items():
        assert f"{topic} ({typ})" in msg
    with pytest.raises(DataError) as exc:
        read_bag(bag, {"/status": "status"})
    msg = str(exc.value)
    assert str(bag) in msg and "'/status' has message type std_msgs/msg/String" in msg
    assert all(t in msg for t in (POSE_TYPE, ODOM_TYPE, IMU_TYPE, JOINT_TYPE))


def test_unreadable_bag_file_or_folder_says_it_cannot_be_opened(tmp_path: Path) -> None:
    bad = tmp_path / "broken.bag"
    bad.write_bytes(b"not a bag at all")
    with pytest.raises(DataError, match=r"broken\.bag: cannot open as a ROS 1 \.bag file or ROS 2 bag folder"):
        topic_columns(bad, ["/mocap"])
    with pytest.raises(DataError, match=r"cannot open"):
        read_bag(tmp_path, {"/mocap": "m"})  # a folder without metadata.yaml


ROBOT = """\
name: rover
model: generic
frames: [world, body]
"""

CONFIG = """\
name: bagrun
robots:
  rover:
    description: rover.yaml
    states: {{stream: odom}}
sources:
  - type: rosbag
    path: {bag}
    topics: {{{mocap_topic}: mocap, /odom: odom, /imu: imu, /joints: joints}}
factors:
  - type: pose.absolute
    robot: rover
    stream: mocap
    sigma: {{rotation: 0.01, translation: 0.01}}
  - type: pose.relative
    robot: rover
    stream: odom
    sigma: {{rotation: 0.001, translation: 0.001}}
solver: {{type: batch, method: lm}}
"""


def write_config(folder: Path, bag: Path, mocap_topic: str = "/mocap") -> Path:
    (folder / "rover.yaml").write_text(ROBOT)
    cfg = folder / "config.yaml"
    cfg.write_text(CONFIG.format(bag=bag.name, mocap_topic=mocap_topic))
    return cfg


@pytest.mark.parametrize("ros", [1, 2])
def test_config_run_recovers_the_bag_poses_to_1e_6_with_odometry_in_its_own_frame(tmp_path: Path, ros: int) -> None:
    """Mocap gives world poses; odometry the same motion in its own frame (only increments agree)."""
    odom_frame = gtsam.Pose3(gtsam.Rot3.Ypr(0.7, 0.1, -0.2), np.array([5.0, -2.0, 1.0]))
    odom_poses = pose_array_from([odom_frame.compose(p) for p in poses_from_array(POSES)])

    def edit(topic, k, m):
        if topic == "/odom":
            msg = m.make(ODOM_TYPE, k)
            msg.pose.pose.position = m.vec(odom_poses[k, :3], "geometry_msgs/msg/Point")
            msg.pose.pose.orientation = m.T["geometry_msgs/msg/Quaternion"](*map(float, odom_poses[k, 3:]))
            return msg

    bag = write_bag(bag_path(tmp_path, ros), ros, edit=edit)
    assert not np.allclose(read_bag(bag, {"/odom": "o"})["o"].values[:, :7], POSES)
    cfg = write_config(tmp_path, bag)
    config = fusionkit.load_config(cfg)
    assert config.stream_columns["joints"] == ("shoulder", "elbow", "v_shoulder", "v_elbow")
    assert config.stream_columns["imu"] == ("ax", "ay", "az", "gx", "gy", "gz")
    result = fusionkit.run(cfg)
    est = result.trajectories["rover"]
    np.testing.assert_array_equal(est.t, T)
    arr = est.pose_array()
    arr[:, 3:] *= np.sign(arr[:, 6:7] * QUAT[:, 3:4])  # q and -q are the same rotation
    np.testing.assert_allclose(arr[:, :3], POS, atol=1e-6)
    np.testing.assert_allclose(arr[:, 3:], QUAT, atol=1e-6)


def test_validate_lists_the_bag_streams_and_the_joint_columns(bag: Path, capsys) -> None:
    cfg = write_config(bag.parent, bag)
    assert main(["validate", str(cfg)]) == 0
    out = capsys.readouterr().out
    assert f"stream mocap: {N} samples" in out and "columns shoulder, elbow, v_shoulder, v_elbow" in out


@pytest.mark.parametrize("topic, expected", [
    ("/vicon", ["'/vicon' is not in the bag; it has: ", "/mocap (geometry_msgs/msg/PoseStamped)"]),
    ("/status", ["'/status' has message type std_msgs/msg/String, which is not supported; supported types: ",
                 POSE_TYPE, JOINT_TYPE]),
])
def test_validate_bag_topic_errors_are_one_line_naming_the_bag(bag: Path, capsys, topic: str,
                                                              expected: list[str]) -> None:
    cfg = write_config(bag.parent, bag, mocap_topic=topic)
    assert main(["validate", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fusionkit: error: ")
    assert str(bag) in err and all(e in err for e in expected)
