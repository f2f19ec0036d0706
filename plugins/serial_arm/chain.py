"""Forward kinematics of a serial arm from its URDF (Pinocchio), with kinematic parameter errors, and
its Jacobians on SE(3) (docs/models/serial_arm.md).

Conventions: a pose is a 4x4 homogeneous matrix a_T_b; a twist is in GTSAM's tangent order
[rotation (rad), translation (m)] and perturbs a pose on the right, T' = T Exp(xi) (Pinocchio's
LOCAL frame; Pinocchio orders its twists [linear, angular]).

The chain's model: the URDF reduced to the listed joints, the joints coupled to them (a URDF <mimic>, or a
description's linear coupling q_c = offset + sum_i k_i q_i of listed joints) and nothing else: a joint that moves
a tool frame must be listed, coupled or locked at a stated value; one that does not is locked at its neutral value.
Its configuration is one value per listed joint (rad, or m for a prismatic joint). A robot may have several tool
frames (two hands on one torso): every listed joint moves at least one of them, and each tool's pose depends on the
joints on its path from the root only:

    base_T_tool(q) = base_T_universe * prod_{j on the path} [ parent_T_joint_j Exp(delta_j) * M_j(v_j) ] * joint_T_tool

with v_j = q_j + dq_j for a listed joint (dq_j its offset), v_j = offset + sum_i k_i (q_i + dq_i) for a coupled one,
delta_j the placement error of listed joint j (a twist in joint j's frame before it moves); zero errors give the
URDF's own forward kinematics.
"""

from __future__ import annotations

import copy
import os
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import gtsam
import numpy as np
from .lazy_pinocchio import pin

from fusionkit.api import lie

PIN_TO_GTSAM = [3, 4, 5, 0, 1, 2]  # rows of a Pinocchio twist [v, w] in GTSAM's order [w, v]


def exp_twist(xi: np.ndarray) -> pin.SE3:
    """Exp of a GTSAM-order twist as a Pinocchio SE3."""
    return pin.exp6(pin.Motion(np.asarray(xi[3:], float), np.asarray(xi[:3], float)))


@contextmanager
def _captured_stderr():
    """The C++ URDF parser prints its errors to the process's stderr (fd 2): keep them for the one-line error."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lambda: (tmp.seek(0), tmp.read().decode(errors="replace"))[1]
        finally:
            os.dup2(saved, 2)
            os.close(saved)


class ChainError(ValueError):
    """A frame or joint the URDF lacks or that does not fit a serial arm; `key`: the description key at fault."""

    def __init__(self, key: str, message: str):
        super().__init__(message)
        self.key = key


@dataclass
class Flange:
    """base_T_tool and, when asked for, its Jacobians (local twist of the tool frame, GTSAM order)."""

    T: np.ndarray                              # 4x4 base_T_tool
    joints: np.ndarray | None = None           # 6 x n: d twist / d q (the offsets have the same columns)
    placements: list[np.ndarray] | None = None  # per joint, 6 x 6: d twist / d delta_j (delta a plain vector)


@dataclass(frozen=True)
class Coupling:
    """A joint moved by listed joints: q_joint = offset + sum(factor * q_leader) (rad, or m)."""

    joint: str
    leaders: tuple[tuple[str, float], ...]
    offset: float = 0.0


def moving_joints(model: pin.Model, frame: str) -> list[str]:
    """The names of the joints that move `frame` (from the root out; none for a frame the model lacks)."""
    if not model.existFrame(frame):
        return []
    return [model.names[j] for j in model.supports[model.frames[model.getFrameId(frame)].parentJoint] if j != 0]


def urdf_mimics(path: Path) -> list[Coupling]:
    """The URDF's <mimic> joints as couplings: q = multiplier * q_leader + offset."""
    import xml.etree.ElementTree as ET
    out = []
    for joint in ET.parse(path).getroot().iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            out.append(Coupling(joint.get("name"), ((mimic.get("joint"), float(mimic.get("multiplier", 1.0))),),
                                float(mimic.get("offset", 0.0))))
    return out


class SerialChain:
    """A URDF arm between `base_frame` and its tool frame(s), moved by `joints` (in that order), with `couplings`
    (joints moved by listed ones) and `locked` ({joint: value} held at a stated value). It computes the pose of one
    tool frame (the first of `tool_frames`); `for_tool(frame)` is the same chain computing another's."""

    def __init__(self, model: pin.Model, base_frame: str, tool_frames: str | tuple[str, ...], joints: list[str],
                 couplings: tuple[Coupling, ...] = (), locked: tuple[tuple[str, float], ...] = ()):
        tool_frames = (tool_frames,) if isinstance(tool_frames, str) else tuple(tool_frames)
        for key, frame in (("base_frame", base_frame),) + tuple(("tool_frame", f) for f in tool_frames):
            if not model.existFrame(frame):
                raise ChainError(key, f"the URDF has no frame {frame!r}")
        missing = [j for j in joints if not model.existJointName(j)]
        if missing:
            raise ChainError("joints", f"the URDF has no joint {missing[0]!r}; its joints: "
                             f"{', '.join(list(model.names)[1:])}")
        reference = self._check_couplings_and_locks(model, tool_frames, joints, couplings, dict(locked))
        kept = set(joints) | {c.joint for c in couplings}
        lock = [jid for jid in range(1, model.njoints) if model.names[jid] not in kept]
        self.model = pin.buildReducedModel(model, lock, reference) if lock else model
        self.data = self.model.createData()
        self.joint_names = list(joints)
        self.tool_frames = tool_frames
        self.jids = [self.model.getJointId(j) for j in joints]
        wrong = [(j, self.model.joints[jid].nv) for j, jid in zip(joints, self.jids) if self.model.joints[jid].nv != 1]
        if wrong:
            raise ChainError("joints", f"joint {wrong[0][0]!r} has {wrong[0][1]} degrees of freedom; a serial arm's "
                             "joints have one each")
        self.idx_v = [self.model.joints[jid].idx_v for jid in self.jids]
        # coupled joints: their ids and velocity index, their rows of dq_coupled / dq (n), and their offsets
        self.coupled_jids = [self.model.getJointId(c.joint) for c in couplings]
        self.coupled_v = [self.model.joints[jid].idx_v for jid in self.coupled_jids]
        self.coupling = np.array([[dict(c.leaders).get(j, 0.0) for j in joints] for c in couplings]).reshape(-1, len(joints))
        self.coupling_offset = np.array([c.offset for c in couplings], float)
        moving = set().union(*(moving_joints(self.model, f) for f in tool_frames))
        moving |= {lead for c in couplings if c.joint in moving for lead, _ in c.leaders}
        unmoved = [j for j in joints if j not in moving]
        if unmoved:
            what = f"tool_frame {tool_frames[0]!r}" if len(tool_frames) == 1 else \
                f"any tool frame ({', '.join(tool_frames)})"
            raise ChainError("joints", f"joint {unmoved[0]!r} does not move {what}")
        base_id = self.model.getFrameId(base_frame)
        if self.model.frames[base_id].parentJoint != 0:
            raise ChainError("base_frame", f"base_frame {base_frame!r} moves with the joints; it must come before "
                             "the first one")
        self.nominal = [self.model.jointPlacements[jid].copy() for jid in self.jids]
        self._perturbed: set[int] = set()  # shared with for_tool's chains: they share the model
        self._plain = self.model.nq == self.model.nv  # no continuous (cos, sin) joints: q is the angles
        pin.forwardKinematics(self.model, self.data, pin.neutral(self.model))
        self.universe_T_base = pin.updateFramePlacement(self.model, self.data, base_id).homogeneous
        self.base_T_universe = lie.inverse(self.universe_T_base)
        self.prismatic = [self.model.joints[jid].shortname().startswith("JointModelP") for jid in self.jids]
        self.lower = np.array([self.model.lowerPositionLimit[self.model.joints[j].idx_q] for j in self.jids])
        self.upper = np.array([self.model.upperPositionLimit[self.model.joints[j].idx_q] for j in self.jids])
        self.gravity = np.array([0.0, 0.0, -9.81])  # m/s^2 in the URDF's root frame
        self._gravity: dict[tuple, tuple] = {}  # payload -> (model, data) with the URDF's nominal placements
        # d v / d q: the reduced model's joint velocities per listed joint value (listed: one; coupled: the coupling)
        self.dv_dq = np.zeros((self.model.nv, self.n))
        self.dv_dq[self.idx_v, np.arange(self.n)] = 1.0
        if self.coupled_v:
            self.dv_dq[self.coupled_v] = self.coupling
        self._tools: dict[str, SerialChain] = {}
        self._select(tool_frames[0])

    def _select(self, frame: str) -> None:
        """Compute `frame`'s pose: its id, the joints on its path from the root (reduced model's ids, root first),
        and the listed joints that move it (`active`: on the path, or leading a coupled joint on it)."""
        self.tool_frame = frame
        self.tool_id = self.model.getFrameId(frame)
        self.path = [int(j) for j in self.model.supports[self.model.frames[self.tool_id].parentJoint] if j != 0]
        on_path = set(self.path)
        leads = self.coupling[[c for c, jid in enumerate(self.coupled_jids) if jid in on_path]]
        self.active = tuple(i for i, jid in enumerate(self.jids) if jid in on_path or np.any(leads[:, i] != 0))
        self._batch = None
        self._tools[frame] = self

    def for_tool(self, frame: str) -> "SerialChain":
        """The chain computing tool frame `frame` (one of `tool_frames`), sharing this one's model."""
        if frame not in self._tools:
            if frame not in self.tool_frames:
                raise ChainError("tool_frame", f"{frame!r} is not one of the robot's tool frames: "
                                 f"{', '.join(self.tool_frames)}")
            copy.copy(self)._select(frame)
        return self._tools[frame]

    def gravity_torques(self, q: np.ndarray, payload: tuple = (), jacobians: bool = False):
        """The torque gravity exerts on each listed joint (N, n; N m, or N for a prismatic joint; the opposite of
        Pinocchio's generalized gravity, which holds the arm up) at joint values q (N, n) from the URDF's inertials (`gravity`: -9.81 m/s^2 along the URDF root's z unless set) plus `payload` (frame,
        mass kg, x, y, z m in that frame), a coupled joint's torque carried to its leaders (virtual work:
        tau = -V^T g); with `jacobians` also d tau / d q (N, n, n), else None: a positive compliance lets the joint
        give way to gravity."""
        key = ("urdf", self.model.getFrameId(payload[0]), *payload[1:]) if payload else ("urdf",)
        return self._torques(self._gravity_model(key), q, jacobians)

    def unit_mass_torques(self, q: np.ndarray, points: tuple, jacobians: bool = False):
        """The gravity torque on each listed joint of 1 kg at each point (frame, x, y, z m in that frame) alone, the
        URDF's inertials left out: (N, M, n) N m per kg, and with `jacobians` d / d q (N, M, n, n)."""
        out = [self._torques(self._gravity_model(("unit", self.model.getFrameId(point[0]), 1.0, *point[1:])), q,
                             jacobians) for point in points]
        tau = np.stack([t for t, _ in out], axis=1)
        return tau, np.stack([d for _, d in out], axis=1) if jacobians else None

    def _torques(self, model_data: tuple, q: np.ndarray, jacobians: bool):
        model, data = model_data
        q = np.atleast_2d(np.asarray(q, float))
        tau = np.empty(q.shape)
        dtau = np.empty(q.shape + (self.n,)) if jacobians else None
        V = self.dv_dq
        for i, qi in enumerate(q):
            config = self._configuration(qi)
            tau[i] = -V.T @ pin.computeGeneralizedGravity(model, data, config)  # Pinocchio's: the torque holding up
            if jacobians:
                dtau[i] = -V.T @ pin.computeGeneralizedGravityDerivatives(model, data, config) @ V
        return tau, dtau

    def _gravity_model(self, key: tuple) -> tuple:
        """The model gravity torques are computed on, with the URDF's nominal placements (placement errors change
        torques by their own small fraction). key ("urdf",): the URDF's inertials; ("urdf", frame id, mass, x, y,
        z): plus a payload there; ("unit", frame id, 1, x, y, z): only 1 kg there. Cached per key and gravity."""
        cached = key + tuple(self.gravity)
        if cached not in self._gravity:
            model = pin.Model(self.model)
            model.gravity = pin.Motion(self.gravity, np.zeros(3))
            for j, jid in enumerate(self.jids):
                model.jointPlacements[jid] = self.nominal[j]
            if key[0] == "unit":
                for jid in range(model.njoints):
                    model.inertias[jid] = pin.Inertia.Zero()
            if len(key) > 1:
                frame = model.frames[key[1]]
                at = frame.placement.act(np.asarray(key[3:6], float))
                model.inertias[frame.parentJoint] += pin.Inertia(float(key[2]), at, np.zeros((3, 3)))
            self._gravity[cached] = (model, model.createData())
        return self._gravity[cached]

    def unit_twist(self, jid: int) -> np.ndarray:
        """The motion axis of joint `jid` (reduced model) as a unit twist in GTSAM order (rotation, translation)."""
        return np.asarray(self.data.joints[jid].S).ravel()[PIN_TO_GTSAM]

    @staticmethod
    def _check_couplings_and_locks(model: pin.Model, tool_frames: tuple[str, ...], joints: list[str], couplings,
                                   locked: dict):
        """ChainError unless every coupled or locked joint exists, is not listed, couples one-degree-of-freedom
        listed leaders, and every joint that moves a tool frame is listed, coupled or locked. Returns the reference
        configuration the other joints are held at (neutral, locked ones at their values)."""
        for c in couplings:
            if not model.existJointName(c.joint):
                raise ChainError("couplings", f"the URDF has no joint {c.joint!r} to couple")
            if c.joint in joints or c.joint in locked:
                raise ChainError("couplings", f"joint {c.joint!r} is coupled and also listed or locked: one of them")
            if model.joints[model.getJointId(c.joint)].nv != 1:
                raise ChainError("couplings", f"joint {c.joint!r} has more than one degree of freedom: it cannot "
                                 "be coupled")
            unlisted = [lead for lead, _ in c.leaders if lead not in joints]
            if unlisted:
                raise ChainError("couplings", f"joint {c.joint!r} follows {unlisted[0]!r}, which is not in `joints` "
                                 "(a coupling's leaders are listed joints)")
        for name in locked:
            if not model.existJointName(name) or name in joints:
                raise ChainError("locked", f"{name!r} is not a joint of the URDF outside `joints`")
        free = {c.joint for c in couplings} | set(joints) | set(locked)
        silent = [(name, f) for f in tool_frames for name in moving_joints(model, f) if name not in free]
        if silent:
            raise ChainError("joints", f"joint {silent[0][0]!r} moves tool_frame {silent[0][1]!r} but is not in `joints`: "
                             "list it, couple it (`couplings:`, or a <mimic> in the URDF), or hold it at a stated "
                             f"value (`locked: {{{silent[0][0]}: 0.0}}`)")
        reference = pin.neutral(model)
        for name, value in locked.items():
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 1:
                reference[joint.idx_q] = float(value)
            elif joint.nq == 2:  # continuous: (cos, sin)
                reference[joint.idx_q:joint.idx_q + 2] = np.cos(value), np.sin(value)
        return reference

    @classmethod
    def from_urdf(cls, path: Path, base_frame: str, tool_frames: str | tuple[str, ...], joints: list[str],
                  couplings: tuple[Coupling, ...] = (), locked: tuple[tuple[str, float], ...] = ()) -> "SerialChain":
        """ChainError("urdf", ...) when Pinocchio cannot read the file (with what its parser printed). The URDF's
        <mimic> joints that move the tool are couplings unless the description lists, couples or locks them."""
        with _captured_stderr() as printed:
            try:
                model = pin.buildModelFromUrdf(str(path))
            except (ValueError, RuntimeError) as exc:
                said = " ".join(printed().split())
                raise ChainError("urdf", f"not a URDF Pinocchio can read: {str(exc).strip()}"
                                 + (f" ({said})" if said else "")) from None
        given = {c.joint for c in couplings} | set(dict(locked)) | set(joints)
        frames = (tool_frames,) if isinstance(tool_frames, str) else tuple(tool_frames)
        moving = {j for f in frames for j in moving_joints(model, f)}  # a mimic moving no tool (a finger) is held
        mimics = tuple(c for c in urdf_mimics(path) if c.joint not in given and c.joint in moving)
        return cls(model, base_frame, frames, joints, tuple(couplings) + mimics, locked)

    @property
    def n(self) -> int:
        return len(self.jids)

    def _configuration(self, q: np.ndarray) -> np.ndarray:
        v = np.zeros(self.model.nv)
        v[self.idx_v] = q
        if self.coupled_v:
            v[self.coupled_v] = self.coupling_offset + self.coupling @ q
        return v if self._plain else pin.integrate(self.model, pin.neutral(self.model), v)

    def _set_placements(self, placements: dict[int, np.ndarray]) -> None:
        for j in self._perturbed - placements.keys():
            self.model.jointPlacements[self.jids[j]] = self.nominal[j]
        for j, delta in placements.items():
            self.model.jointPlacements[self.jids[j]] = self.nominal[j] * exp_twist(delta)
        self._perturbed.clear()
        self._perturbed.update(placements)

    def joint_positions(self, q: np.ndarray) -> np.ndarray:
        """Origins of the joints on the tool's path and of the tool frame (len(path) + 1, 3) in the base frame (m),
        nominal placements, at joint values q."""
        self._set_placements({})
        pin.forwardKinematics(self.model, self.data, self._configuration(np.asarray(q, float)))
        universe = [self.data.oMi[jid].homogeneous for jid in self.path]
        universe.append(pin.updateFramePlacement(self.model, self.data, self.tool_id).homogeneous)
        return np.array([(self.base_T_universe @ T)[:3, 3] for T in universe])

    def flange(self, q: np.ndarray, placements: dict[int, np.ndarray] | None = None,
               jacobians: bool = False) -> Flange:
        """base_T_tool at joint values q (offsets already added), with placement errors {joint index:
        delta (6, GTSAM order)}; with `jacobians`, d twist/d q and d twist/d delta_j for every joint."""
        self._set_placements(placements or {})
        config = self._configuration(np.asarray(q, float))
        model, data = self.model, self.data
        if not jacobians:
            pin.forwardKinematics(model, data, config)
            return Flange(self.base_T_universe @ pin.updateFramePlacement(model, data, self.tool_id).homogeneous)
        pin.computeJointJacobians(model, data, config)
        universe_T_tool = pin.updateFramePlacement(model, data, self.tool_id).homogeneous
        full = pin.getFrameJacobian(model, data, self.tool_id, pin.LOCAL)[PIN_TO_GTSAM]
        J = full[:, self.idx_v] + (full[:, self.coupled_v] @ self.coupling if self.coupled_v else 0.0)
        tool_T_universe = lie.inverse(universe_T_tool)
        blocks = []
        on_path = set(self.path)
        for j, jid in enumerate(self.jids):  # joint j's frame before it moves: universe_T_parent * parent_T_joint
            if jid not in on_path:  # it does not move this tool
                blocks.append(np.zeros((6, 6)))
                continue
            before = (data.oMi[model.parents[jid]] * model.jointPlacements[jid]).homogeneous
            block = lie.adjoint(tool_T_universe @ before)  # d twist / d (right perturbation of the placement)
            if j in self._perturbed:  # Exp(delta + d) = Exp(delta) Exp(Jr(delta) d)
                block = block @ gtsam.Pose3.ExpmapDerivative(np.asarray(placements[j], float))
            blocks.append(block)
        return Flange(self.base_T_universe @ universe_T_tool, J, blocks)
