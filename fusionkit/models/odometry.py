"""A pose stream against a robot's states: the stream's poses at given times (its own samples, or interpolated),
a sensor's mounting transform, and the stream's poses at consecutive states -- what odometry-like factors
(relative poses, scaled visual odometry) and the initializers that read them share (public in fusionkit.api)."""

from __future__ import annotations

import gtsam
import numpy as np

from ..components import Spec
from ..data.association import interpolate_poses, segment_ids
from ..data.stream import poses_from_array


def stream_poses_at(stream, t: np.ndarray, max_gap: float | None = None) -> tuple[np.ndarray, list[gtsam.Pose3]]:
    """(mask of the times inside the stream's span and not across a gap > max_gap, the stream's poses
    at those times): its own poses when `t` are its stamps (states clocked by it), else interpolated."""
    if np.array_equal(t, stream.t):
        return np.ones(len(t), dtype=bool), stream.poses()
    inside, arr = interpolate_poses(stream.t, stream.pose_array(), t, max_gap)
    return inside, poses_from_array(arr)


def sensor_mount(ctx, spec: Spec) -> gtsam.Pose3:
    """body_T_sensor of the entry's `sensor` (identity when the entry names none)."""
    if "sensor" not in spec.data:
        return gtsam.Pose3()
    return ctx.robot(spec["robot"]).sensors[spec["sensor"]].mount


def odometry_pairs(ctx, spec: Spec, robot: str) -> tuple[np.ndarray, list[gtsam.Pose3], list[gtsam.Pose3]]:
    """Consecutive states (ka, kb = ka + 1) of `robot` with the entry's `stream` body poses at their times:
    (every ka, the body poses at those ka, the body poses at their kb); a `sensor:` entry's poses are moved
    from the sensor to the body frame.

    States outside the stream's time span, or inside a gap longer than the entry's `max_gap`, get none, and
    no pair spans a gap (the count is a note of the run, not silently dropped)."""
    stream = ctx.stream(spec["stream"])
    states = ctx.state_set(robot, spec)
    inside, poses = stream_poses_at(stream, states.t, spec.get("max_gap"))
    idx = np.flatnonzero(inside)
    if len(idx) < len(states):
        ctx.note(f"{spec.label}: {len(states) - len(idx)} of {len(states)} states of {robot!r} lie "
                 f"outside stream {stream.name!r} (or across a gap) and get no factor from it")
    segment = segment_ids(stream.t, states.t[idx], spec.get("max_gap"))
    if "sensor" in spec.data:  # sensor poses -> body poses
        mount_inv = sensor_mount(ctx, spec).inverse()
        poses = [p.compose(mount_inv) for p in poses]
    js = np.flatnonzero((np.diff(idx) == 1) & (segment[1:] == segment[:-1])).tolist()  # consecutive, same stretch
    return idx[js], [poses[j] for j in js], [poses[j + 1] for j in js]
