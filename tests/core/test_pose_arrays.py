"""Pose lists <-> (N, 7) arrays in bulk give exactly the numbers of gtsam's own per-pose calls."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.data.quaternions import quaternions_xyzw
from fusionkit.data.stream import Stream, pose_array_from, poses_from_array, POSE_COLUMNS


def rotations(rng, n: int) -> list[gtsam.Rot3]:
    """Random rotations and the cases that take each branch of the conversion: trace > 0, and trace <= 0
    with the largest diagonal element first, second or third, ties between them, and angles next to pi."""
    q = rng.normal(size=(n, 4))
    out = [gtsam.Rot3.Quaternion(*r) for r in q / np.linalg.norm(q, axis=1, keepdims=True)]
    axes = [np.eye(3)[i] for i in range(3)] + [np.ones(3) / np.sqrt(3), np.array([1.0, 1.0, 0.0]) / np.sqrt(2)]
    for axis in axes:
        for angle in (np.pi, np.pi - 1e-9, -np.pi + 1e-12, np.pi / 2, 2.0, 1e-12, 0.0):
            out.append(gtsam.Rot3.AxisAngle(axis, angle))
    return out


def test_quaternions_of_rotation_matrices_equal_rot3_to_quaternion_bit_for_bit():
    rots = rotations(np.random.default_rng(7), 20000)
    expected = np.array([[q.x(), q.y(), q.z(), q.w()] for q in (r.toQuaternion() for r in rots)])
    got = quaternions_xyzw(np.array([r.matrix() for r in rots]))
    trace = np.array([np.trace(r.matrix()) for r in rots])
    assert (trace > 0).sum() > 1000 and (trace <= 0).sum() > 1000  # both branches are exercised
    assert got.tobytes() == expected.tobytes()


def test_pose_array_from_equals_the_per_pose_translation_and_quaternion():
    rng = np.random.default_rng(8)
    poses = [gtsam.Pose3(r, rng.normal(size=3) * 10.0) for r in rotations(rng, 2000)]
    expected = np.array([[*p.translation(), q.x(), q.y(), q.z(), q.w()]
                         for p in poses for q in [p.rotation().toQuaternion()]])
    assert pose_array_from(poses).tobytes() == expected.tobytes()
    assert pose_array_from([]).shape == (0, 7)


def test_poses_from_array_build_the_pose3_of_each_row_and_a_stream_converts_once():
    rng = np.random.default_rng(9)
    a = np.column_stack([rng.normal(size=(50, 3)), rng.normal(size=(50, 4))])
    a[:, 3:] /= np.linalg.norm(a[:, 3:], axis=1, keepdims=True)
    poses = poses_from_array(a)
    for row, p in zip(a, poses):
        expected = gtsam.Pose3(gtsam.Rot3.Quaternion(row[6], row[3], row[4], row[5]), row[:3])
        assert p.equals(expected, 0.0)
    stream = Stream("s", np.arange(50.0), POSE_COLUMNS, a)
    first, second = stream.poses(), stream.poses()
    assert first is not second
    assert all(p.equals(q, 0.0) and q.equals(r, 0.0)
               for p, q, r in zip(first, second, poses_from_array(stream.pose_array())))
    first.clear()  # a caller's list is its own
    assert len(stream.poses()) == 50
