"""Streams -> one ROS 1 (.bag file) or ROS 2 (bag folder) recording, written with `rosbags`: pose streams as
geometry_msgs/PoseStamped, IMU streams (ax ay az gx gy gz) as sensor_msgs/Imu. Header stamps and receive
times are the samples' times (s); what `rosbag_reader` reads back exactly."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from .rosbag_reader import IMU_COLUMNS
from .stream import Stream

POSE_MSG, IMU_MSG = "geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/Imu"
ROS_VERSIONS = ("ros1", "ros2")


def message_type(stream: Stream) -> str:
    """The message a stream is written as; DataError for streams no ROS message fusionkit writes carries."""
    if stream.is_pose and len(stream.columns) == 7:
        return POSE_MSG
    if tuple(stream.columns) == IMU_COLUMNS:
        return IMU_MSG
    raise DataError(f"stream {stream.name!r} (columns {', '.join(stream.columns)}) has no ROS message fusionkit "
                    "writes (poses: PoseStamped, ax..gz: Imu); write it as CSV instead")


class _Messages:
    """Messages of one typestore (ROS 1 headers carry a seq, ROS 2 ones do not)."""

    def __init__(self, typestore, frame: str):
        self.T = typestore.types
        self.frame = frame
        self.seq = "seq" in self.T["std_msgs/msg/Header"].__dataclass_fields__

    def header(self, k: int, ns: int):
        stamp = self.T["builtin_interfaces/msg/Time"](sec=int(ns // 10**9), nanosec=int(ns % 10**9))
        return self.T["std_msgs/msg/Header"](stamp=stamp, frame_id=self.frame, **({"seq": k} if self.seq else {}))

    def _vector(self, v, kind: str = "geometry_msgs/msg/Vector3"):
        return self.T[kind](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def pose(self, header, row: np.ndarray):
        q = self.T["geometry_msgs/msg/Quaternion"](x=float(row[3]), y=float(row[4]), z=float(row[5]), w=float(row[6]))
        pose = self.T["geometry_msgs/msg/Pose"](position=self._vector(row[:3], "geometry_msgs/msg/Point"), orientation=q)
        return self.T[POSE_MSG](header=header, pose=pose)

    def imu(self, header, row: np.ndarray):
        no_orientation = np.zeros(9)
        no_orientation[0] = -1.0  # REP 145: orientation not estimated
        return self.T[IMU_MSG](header=header, orientation=self.T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                               orientation_covariance=no_orientation, angular_velocity=self._vector(row[3:]),
                               angular_velocity_covariance=np.zeros(9), linear_acceleration=self._vector(row[:3]),
                               linear_acceleration_covariance=np.zeros(9))


def write_bag(path: Path, topics: dict[str, Stream], ros: str, frame: str = "world") -> None:
    """Write `topics` ({topic: stream}) to a new bag at `path` (ros1: a .bag file, ros2: a folder), messages in
    time order. Checks every stream before writing anything."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    if ros not in ROS_VERSIONS:
        raise DataError(f"{path}: unknown bag format {ros!r}; expected one of {', '.join(ROS_VERSIONS)}")
    types = {topic: message_type(stream) for topic, stream in topics.items()}
    for topic, stream in topics.items():
        if len(stream) and stream.t.min() < 0:
            raise DataError(f"stream {stream.name!r}: a ROS stamp cannot be negative (first at t = {stream.t.min()} s)")
    typestore = get_typestore(Stores.ROS1_NOETIC if ros == "ros1" else Stores.ROS2_HUMBLE)
    serialize = typestore.serialize_ros1 if ros == "ros1" else typestore.serialize_cdr
    build = _Messages(typestore, frame)
    # every message's (time ns, topic, row) merged into one time-ordered sequence
    events = sorted((int(round(t * 1e9)), topic, k) for topic, s in topics.items() for k, t in enumerate(s.t))
    with (Writer1(path) if ros == "ros1" else Writer2(path, version=9)) as writer:
        connections = {topic: writer.add_connection(topic, types[topic], typestore=typestore) for topic in topics}
        for ns, topic, k in events:
            header = build.header(k, ns)
            row = topics[topic].values[k]
            msg = build.pose(header, row) if types[topic] == POSE_MSG else build.imu(header, row)
            writer.write(connections[topic], ns, serialize(msg, types[topic]))
