"""ROS 1 (.bag) and ROS 2 bag topics -> streams, read with `rosbags`.

Times are header stamps in seconds (sec + nanosec * 1e-9); values in SI units as in the messages
(m, unit quaternion x y z w, m/s, rad/s, m/s^2, joint positions in m or rad)."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from ..errors import DataError
from .files import unit_quaternions
from .stream import POSE_COLUMNS, Stream

TWIST_COLUMNS = ("vx", "vy", "vz", "wx", "wy", "wz")
IMU_COLUMNS = ("ax", "ay", "az", "gx", "gy", "gz")
JOINT_STATE = "sensor_msgs/msg/JointState"


def _xyz(v) -> tuple[float, float, float]:
    return (v.x, v.y, v.z)


def _pose(p) -> tuple[float, ...]:
    return (*_xyz(p.position), *_xyz(p.orientation), p.orientation.w)


def _transform(tf) -> tuple[float, ...]:
    return (*_xyz(tf.translation), *_xyz(tf.rotation), tf.rotation.w)


# message type -> (columns, message -> row)
EXTRACTORS: dict[str, tuple[tuple[str, ...], Callable]] = {
    "geometry_msgs/msg/PoseStamped": (POSE_COLUMNS, lambda m: _pose(m.pose)),
    "geometry_msgs/msg/PoseWithCovarianceStamped": (POSE_COLUMNS, lambda m: _pose(m.pose.pose)),
    "geometry_msgs/msg/TransformStamped": (POSE_COLUMNS, lambda m: _transform(m.transform)),
    "nav_msgs/msg/Odometry": (POSE_COLUMNS + TWIST_COLUMNS,
                              lambda m: (*_pose(m.pose.pose), *_xyz(m.twist.twist.linear),
                                         *_xyz(m.twist.twist.angular))),
    "sensor_msgs/msg/Imu": (IMU_COLUMNS, lambda m: (*_xyz(m.linear_acceleration), *_xyz(m.angular_velocity))),
}
SUPPORTED = (*EXTRACTORS, JOINT_STATE)


@contextmanager
def _open(path: Path) -> Iterator:
    """An open AnyReader; bags without embedded definitions fall back to the ROS 2 Humble types."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if not Path(path).exists():
        raise DataError(f"{path}: bag not found")
    try:
        reader = AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as exc:  # rosbags raises several unrelated types for unreadable bags
        detail = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
        raise DataError(f"{path}: cannot open as a ROS 1 .bag file or ROS 2 bag folder ({detail})") from None
    try:
        yield reader
    finally:
        reader.close()


def _connections(reader, path: Path, topic: str) -> tuple[str, list]:
    """(message type, connections) of a topic; DataError if absent or of an unsupported type."""
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        have = sorted({(c.topic, c.msgtype) for c in reader.connections})
        listing = ", ".join(f"{t} ({m})" for t, m in have) or "(no topics)"
        raise DataError(f"{path}: topic {topic!r} is not in the bag; it has: {listing}")
    types = sorted({c.msgtype for c in conns})
    if len(types) > 1 or types[0] not in SUPPORTED:
        raise DataError(f"{path}: topic {topic!r} has message type {' and '.join(types)}, which is not "
                        f"supported; supported types: {', '.join(SUPPORTED)}")
    return types[0], conns


def _messages(reader, conns: list, origin: str) -> Iterator[tuple[int, object]]:
    """(receive time in ns, message) in bag order."""
    from rosbags.highlevel import AnyReaderError
    try:
        for conn, stamp, raw in reader.messages(connections=conns):
            yield stamp, reader.deserialize(raw, conn.msgtype)
    except AnyReaderError as exc:
        raise DataError(f"{origin}: cannot decode a message ({exc})") from None


def _joints(reader, conns: list, origin: str) -> tuple[tuple[str, ...], bool]:
    """Joint names of the first message, and whether it carries one velocity per joint."""
    first = next(_messages(reader, conns, origin), None)
    if first is None:
        raise DataError(f"{origin}: no messages (the joint names come from the first one)")
    names = tuple(first[1].name)
    if not names:
        raise DataError(f"{origin}: the first message names no joints")
    return names, len(first[1].velocity) == len(names)


def _joint_columns(names: tuple[str, ...], with_vel: bool) -> tuple[str, ...]:
    return names + (tuple(f"v_{n}" for n in names) if with_vel else ())


def topic_columns(path: Path, topics: list[str]) -> dict[str, tuple[str, ...]]:
    """Column names of the stream each topic gives (reads metadata; JointState: its first message)."""
    out = {}
    with _open(path) as reader:
        for topic in topics:
            msgtype, conns = _connections(reader, path, topic)
            out[topic] = _joint_columns(*_joints(reader, conns, f"{path} topic {topic}")) \
                if msgtype == JOINT_STATE else EXTRACTORS[msgtype][0]
    return out


def _joint_row(names: tuple[str, ...], with_vel: bool, msg, k: int, origin: str) -> list[float]:
    if tuple(msg.name) != names:
        raise DataError(f"{origin}: message {k + 1} names joints {', '.join(msg.name)}; the first message "
                        f"named {', '.join(names)} (expected the same joints in the same order)")
    if len(msg.position) != len(names) or (with_vel and len(msg.velocity) != len(names)):
        raise DataError(f"{origin}: message {k + 1} has {len(msg.position)} positions and {len(msg.velocity)} "
                        f"velocities for {len(names)} joints")
    return [*msg.position, *msg.velocity] if with_vel else list(msg.position)


def _reject(origin: str, t: np.ndarray, bad: np.ndarray, what: str) -> None:
    """DataError counting the messages flagged in `bad` (one flag per stamp in t)."""
    if bad.any():
        raise DataError(f"{origin}: {int(bad.sum())} of {len(t)} messages {what} (first at t = "
                        f"{t[int(np.argmax(bad))]:.6f} s)")


def _read_topic(reader, path: Path, topic: str, name: str) -> Stream:
    msgtype, conns = _connections(reader, path, topic)
    origin = f"{path} topic {topic}"
    if msgtype == JOINT_STATE:
        names, with_vel = _joints(reader, conns, origin)
        columns = _joint_columns(names, with_vel)
        row_of = lambda m, k: _joint_row(names, with_vel, m, k, origin)  # noqa: E731
    else:
        columns, extract = EXTRACTORS[msgtype]
        row_of = lambda m, k: extract(m)  # noqa: E731
    stamps, rows = [], []
    for k, (recv_ns, msg) in enumerate(_messages(reader, conns, origin)):
        header = getattr(msg, "header", None)
        stamps.append((header.stamp.sec, header.stamp.nanosec) if header is not None else divmod(recv_ns, 10**9))
        rows.append(row_of(msg, k))
    if not rows:
        raise DataError(f"{origin}: no messages")
    st = np.asarray(stamps, dtype=np.int64)
    t = st[:, 0] + st[:, 1] * 1e-9
    values = np.asarray(rows, dtype=float).reshape(len(t), len(columns))
    order = np.argsort(t, kind="stable")  # header stamps may arrive slightly out of order
    t, values = t[order], values[order]
    _reject(origin, t, np.r_[False, np.diff(t) <= 0], "repeat an earlier header stamp")
    _reject(origin, t, ~np.all(np.isfinite(values), axis=1), "contain NaN or infinite values")
    notes = []
    if columns[:7] == POSE_COLUMNS:
        _reject(origin, t, np.linalg.norm(values[:, 3:7], axis=1) < 1e-9, "have a zero quaternion")
        note = unit_quaternions(values[:, 3:7], origin, lambda i: f"t = {t[i]:.6f} s")
        notes += [note] if note else []
    return Stream(name, t, columns, values, origin, notes)


def read_bag(path: Path, topics: dict[str, str]) -> dict[str, Stream]:
    """Streams named by `topics` (topic -> stream name), sorted by header stamp."""
    with _open(path) as reader:
        return {name: _read_topic(reader, path, topic, name) for topic, name in topics.items()}
