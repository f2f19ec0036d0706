"""Forward kinematics of the serial_arm chain: equal to Pinocchio's own on the full URDF (UR10, Panda, with
every other joint at its neutral value), placement errors equal to editing the URDF's joint origins, and a
two-link planar arm against the hand-computed formula."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pinocchio as pin
import pytest

from fusionkit_plugins.serial_arm.chain import SerialChain, exp_twist
from fusionkit_plugins.serial_arm.urdf import urdf_path

ARMS = {"ur10": ("base_link", "tool0", ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                        "wrist_2_joint", "wrist_3_joint"]),
        "panda": ("panda_link0", "panda_link8", [f"panda_joint{i}" for i in range(1, 8)])}

PLANAR = """<robot name="planar">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="tip"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.7 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="l2"/><child link="tip"/><origin xyz="0.4 0 0"/></joint>
</robot>"""


def chain_of(name: str) -> tuple[SerialChain, pin.Model]:
    path = urdf_path(f"example-robot-data:{name}", Path("."))
    base, tool, joints = ARMS[name]
    return SerialChain.from_urdf(path, base, tool, joints), pin.buildModelFromUrdf(str(path))


def pinocchio_flange(model: pin.Model, name: str, q: np.ndarray) -> np.ndarray:
    """base_T_tool by Pinocchio on the full model (the fingers of the Panda at their neutral value)."""
    base, tool, joints = ARMS[name]
    data = model.createData()
    config = pin.neutral(model)
    for joint, value in zip(joints, q):
        config[model.joints[model.getJointId(joint)].idx_q] = value
    pin.framesForwardKinematics(model, data, config)
    return (data.oMf[model.getFrameId(base)].inverse() * data.oMf[model.getFrameId(tool)]).homogeneous


@pytest.mark.parametrize("name", ARMS)
def test_flange_pose_equals_pinocchios_forward_kinematics_of_the_full_urdf(name):
    chain, model = chain_of(name)
    rng = np.random.default_rng(3)
    for q in rng.uniform(-2.5, 2.5, (20, chain.n)):
        np.testing.assert_allclose(chain.flange(q).T, pinocchio_flange(model, name, q), atol=1e-12)


@pytest.mark.parametrize("name", ARMS)
def test_placement_errors_equal_moving_the_joint_origins_in_the_urdf(name):
    """delta_j is a right perturbation of parent_T_joint_j: the same as writing origin * Exp(delta_j)."""
    chain, model = chain_of(name)
    rng = np.random.default_rng(4)
    deltas = {j: rng.normal(0.0, 0.05, 6) for j in range(chain.n)}
    for joint, delta in zip(chain.joint_names, deltas.values()):
        jid = model.getJointId(joint)
        model.jointPlacements[jid] = model.jointPlacements[jid] * exp_twist(delta)
    for q in rng.uniform(-2.5, 2.5, (10, chain.n)):
        np.testing.assert_allclose(chain.flange(q, deltas).T, pinocchio_flange(model, name, q), atol=1e-12)
    np.testing.assert_allclose(chain.flange(q).T, pinocchio_flange(chain_of(name)[1], name, q), atol=1e-12)  # reset


def test_two_link_planar_arm_matches_the_hand_computed_formula(tmp_path):
    """x = 0.7 cos q1 + 0.4 cos(q1 + q2), y = 0.7 sin q1 + 0.4 sin(q1 + q2), z = 0.1, yaw = q1 + q2."""
    (tmp_path / "planar.urdf").write_text(PLANAR)
    chain = SerialChain.from_urdf(tmp_path / "planar.urdf", "base", "tip", ["j1", "j2"])
    for q1, q2 in [(0.0, 0.0), (0.3, -1.1), (2.0, 0.5)]:
        T = chain.flange(np.array([q1, q2])).T
        np.testing.assert_allclose(T[:3, 3], [0.7 * np.cos(q1) + 0.4 * np.cos(q1 + q2),
                                              0.7 * np.sin(q1) + 0.4 * np.sin(q1 + q2), 0.1], atol=1e-12)
        np.testing.assert_allclose(T[:3, :3], gtsam.Rot3.Yaw(q1 + q2).matrix(), atol=1e-12)
    # an offset of 0.2 rad on j2 and a placement error tx = 1 cm of j2 (its origin at 0.71 m): link 1 is longer
    T = chain.flange(np.array([0.3, -1.1 + 0.2]), {1: np.array([0, 0, 0, 0.01, 0, 0])}).T
    np.testing.assert_allclose(T[:2, 3], [0.71 * np.cos(0.3) + 0.4 * np.cos(-0.6),
                                          0.71 * np.sin(0.3) + 0.4 * np.sin(-0.6)], atol=1e-12)


def test_chain_jacobians_equal_central_differences():
    chain, _ = chain_of("panda")
    rng = np.random.default_rng(5)
    q, deltas = rng.uniform(-2, 2, chain.n), {j: rng.normal(0.0, 0.2, 6) for j in (1, 4, 6)}
    f = chain.flange(q, deltas, jacobians=True)

    def twist(T: np.ndarray) -> np.ndarray:
        return gtsam.Pose3.Logmap(gtsam.Pose3(f.T).between(gtsam.Pose3(T)))
    h = 1e-6
    numeric = np.column_stack([(twist(chain.flange(q + h * e, deltas).T) - twist(chain.flange(q - h * e, deltas).T))
                               / (2 * h) for e in np.eye(chain.n)])
    np.testing.assert_allclose(f.joints, numeric, atol=1e-8)
    for j in (0, 4):
        cols = []
        for e in np.eye(6):
            plus, minus = dict(deltas), dict(deltas)
            plus[j], minus[j] = deltas.get(j, np.zeros(6)) + h * e, deltas.get(j, np.zeros(6)) - h * e
            cols.append((twist(chain.flange(q, plus).T) - twist(chain.flange(q, minus).T)) / (2 * h))
        np.testing.assert_allclose(f.placements[j], np.column_stack(cols), atol=1e-8)


@pytest.mark.parametrize("frames, joints, message", [
    (("base_link", "nowhere"), ARMS["ur10"][2], "the URDF has no frame 'nowhere'"),
    (("base_link", "tool0"), ["shoulder_pan_joint", "knee"], "the URDF has no joint 'knee'"),
    (("wrist_1_link", "tool0"), ARMS["ur10"][2], "base_frame 'wrist_1_link' moves with the joints"),
    (("base_link", "upper_arm_link"), ARMS["ur10"][2], "joint 'elbow_joint' does not move tool_frame"),
])
def test_bad_frames_and_joints_are_named(frames, joints, message):
    with pytest.raises(ValueError, match=message):
        SerialChain.from_urdf(urdf_path("example-robot-data:ur10", Path(".")), *frames, joints)
