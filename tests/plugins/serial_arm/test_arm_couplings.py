"""Coupled and locked joints of a serial arm (issue: a torso joint q_c = -(q_a + q_b)): a description's linear coupling
and a URDF <mimic> move the coupled joint with its leaders (forward kinematics equal to the full model's with the
coupled value given, Jacobian equal to central differences); a joint locked at a stated value is held there; a joint
that moves the tool but is neither listed, coupled nor locked is refused in one line, never locked silently."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit_plugins.serial_arm.chain import ChainError, Coupling, SerialChain

LINK = '<link name="{0}"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>'


def joint(name: str, parent: str, child: str, axis: str, xyz: str, mimic: str = "") -> str:
    return (f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/><limit lower="-3" upper="3" effort="1" velocity="1"/>'
            f'{mimic}</joint>')


def torso_urdf(tmp_path, mimic: str = "", name: str = "torso.urdf"):
    """base -> a (z) -> b (y) -> c (y; the coupled one) -> d (z) -> tool: every joint moves the tool."""
    links = "".join(LINK.format(n) for n in ("base", "la", "lb", "lc", "ld", "tool"))
    joints = (joint("a", "base", "la", "0 0 1", "0 0 0.1") + joint("b", "la", "lb", "0 1 0", "0 0 0.3")
              + joint("c", "lb", "lc", "0 1 0", "0.25 0 0", mimic) + joint("d", "lc", "ld", "0 0 1", "0.2 0 0.05")
              + '<joint name="t" type="fixed"><parent link="ld"/><child link="tool"/><origin xyz="0.1 0.02 0"/></joint>')
    path = tmp_path / name
    path.write_text(f'<robot name="torso">{links}{joints}</robot>')
    return path


def full_pose(path, q_full) -> np.ndarray:
    return SerialChain.from_urdf(path, "base", "tool", ["a", "b", "c", "d"]).flange(np.asarray(q_full)).T


def test_a_linear_coupling_moves_the_joint_with_its_leaders_and_its_jacobian_is_the_chain_rule(tmp_path):
    path = torso_urdf(tmp_path)
    coupled = SerialChain.from_urdf(path, "base", "tool", ["a", "b", "d"],
                                    (Coupling("c", (("a", -1.0), ("b", -1.0)), 0.1),))
    q = np.array([0.3, -0.7, 0.5])
    assert coupled.flange(q).T == pytest.approx(full_pose(path, [0.3, -0.7, 0.1 - (0.3 - 0.7), 0.5]), abs=1e-12)
    J = coupled.flange(q, jacobians=True).joints
    from fusionkit.api import lie
    T = coupled.flange(q).T
    for i in range(3):
        step = np.zeros(3)
        step[i] = 1e-6
        plus, minus = coupled.flange(q + step).T, coupled.flange(q - step).T
        numeric = (lie.log(lie.inverse(T) @ plus) - lie.log(lie.inverse(T) @ minus)) / 2e-6
        assert J[:, i] == pytest.approx(numeric, abs=1e-7)


def test_a_urdf_mimic_joint_follows_its_leader(tmp_path):
    path = torso_urdf(tmp_path, '<mimic joint="b" multiplier="-2.0" offset="0.05"/>')
    chain = SerialChain.from_urdf(path, "base", "tool", ["a", "b", "d"])
    q = np.array([-0.2, 0.4, 1.1])
    plain = torso_urdf(tmp_path, name="plain.urdf")
    assert chain.flange(q).T == pytest.approx(full_pose(plain, [-0.2, 0.4, 0.05 - 0.8, 1.1]), abs=1e-12)


def test_a_locked_joint_is_held_at_its_stated_value(tmp_path):
    path = torso_urdf(tmp_path)
    chain = SerialChain.from_urdf(path, "base", "tool", ["a", "b", "d"], locked=(("c", 0.3),))
    q = np.array([0.1, 0.2, 0.3])
    assert chain.flange(q).T == pytest.approx(full_pose(path, [0.1, 0.2, 0.3, 0.3]), abs=1e-12)


def test_a_joint_moving_the_tool_that_is_not_listed_coupled_or_locked_is_refused(tmp_path):
    with pytest.raises(ChainError, match=r"joint 'c' moves tool_frame 'tool' but is not in `joints`.*locked: \{c: 0.0\}"):
        SerialChain.from_urdf(torso_urdf(tmp_path), "base", "tool", ["a", "b", "d"])
    with pytest.raises(ChainError, match=r"joint 'c' follows 'x', which is not in `joints`"):
        SerialChain.from_urdf(torso_urdf(tmp_path), "base", "tool", ["a", "b", "d"], (Coupling("c", (("x", 1.0),)),))
