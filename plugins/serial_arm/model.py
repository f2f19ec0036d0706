"""The `serial_arm` robot model: a serial arm from its URDF, and which description parameters are its
kinematic parameters (docs/reference/robot_description.md#model-serial_arm).

    model: serial_arm
    urdf: example-robot-data:ur10      # or a file relative to the description
    base_frame: base_link              # the URDF frame the arm stands on (FK starts here)
    tool_frame: tool0                  # the flange
    joints: [shoulder_pan_joint, ...]  # the joint-state vector, in this order
    couplings:                         # optional: joints moved by listed ones (a URDF <mimic> is one too)
      - {joint: torso_c, of: {torso_a: -1.0, torso_b: -1.0}, offset: 0.0}   # q_c = offset + sum k q (rad or m)
    locked: {gripper_joint: 0.0}       # optional: joints held at a value (one that moves the tool must be listed,
                                       # coupled or locked; the others are held at their neutral value)
    kinematics:                        # every key optional
      base: base                       # pose3: base_frame in the measurement frame
      tool: marker                     # pose3 (or point3): the marker in the tool frame
      joint_offsets:                   # scalar parameters, one value per listed joint (rad; m if prismatic)
        - {parameter: joint_offsets, joints: [shoulder_pan_joint, ...]}
      placements:                      # vectorN parameters, one value per listed joint, N = len(axes)
        - {parameter: placement, joints: [...], axes: [tx, ty, tz, rx, ry, rz]}
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from fusionkit.api import Lines, Points, RobotDescription, RobotModel

from .chain import ChainError, Coupling, SerialChain
from .urdf import urdf_path

AXIS_NAMES = ("rx", "ry", "rz", "tx", "ty", "tz")  # GTSAM's tangent order of a pose
NAMES = {"type": "array", "items": {"type": "string"}, "minItems": 1, "uniqueItems": True}
COUPLING = {"type": "object",
            "properties": {"joint": {"type": "string"},
                           "of": {"type": "object", "minProperties": 1, "additionalProperties": {"type": "number"}},
                           "offset": {"type": "number", "default": 0.0}},
            "required": ["joint", "of"], "additionalProperties": False}
OFFSET_GROUP = {"type": "object", "properties": {"parameter": {"type": "string"}, "joints": NAMES},
                "required": ["parameter", "joints"], "additionalProperties": False}
PLACEMENT_GROUP = {"type": "object",
                   "properties": {"parameter": {"type": "string"}, "joints": NAMES,
                                  "axes": {"type": "array", "items": {"enum": ["tx", "ty", "tz", "rx", "ry", "rz"]},
                                           "minItems": 1, "uniqueItems": True}},
                   "required": ["parameter", "joints", "axes"], "additionalProperties": False}


@dataclass(frozen=True)
class Group:
    """One kinematic parameter of the description: an offset or placement error per listed joint."""

    parameter: str
    joints: tuple[int, ...]   # indices into the arm's joint list
    axes: tuple[int, ...]     # placement axes in GTSAM's tangent order; () for offsets


@dataclass(frozen=True)
class Arm:
    """A validated serial_arm description: its chain and its kinematic parameters."""

    chain: SerialChain
    base: str | None
    tool: str | None
    offsets: tuple[Group, ...]
    placements: tuple[Group, ...]


@lru_cache(maxsize=32)
def _chain(path: str, mtime: float, base_frame: str, tool_frame: str, joints: tuple[str, ...],
           couplings: tuple[Coupling, ...], locked: tuple[tuple[str, float], ...]) -> SerialChain:
    return SerialChain.from_urdf(Path(path), base_frame, tool_frame, list(joints), couplings, locked)


def chain_from(path: Path, base_frame: str, tool_frame: str, joints, couplings=(), locked=()) -> SerialChain:
    """The chain of a URDF file (loaded once while the file is unchanged)."""
    return _chain(str(path), path.stat().st_mtime, base_frame, tool_frame, tuple(joints), tuple(couplings),
                  tuple(sorted(dict(locked).items())))


def couplings_of(extra: dict) -> tuple[Coupling, ...]:
    """The description's `couplings:` as chain couplings."""
    return tuple(Coupling(c["joint"], tuple((k, float(v)) for k, v in c["of"].items()), float(c.get("offset", 0.0)))
                 for c in extra.get("couplings", ()))


def load_chain(desc: RobotDescription) -> SerialChain:
    """The description's chain (loaded once per URDF file and frames); errors located at its keys."""
    x = desc.extra
    try:
        path = urdf_path(str(x["urdf"]), Path(desc.doc.file).parent)
    except FileNotFoundError as exc:
        raise desc.error(("urdf",), str(exc)) from None
    try:
        return chain_from(path, x["base_frame"], x["tool_frame"], x["joints"], couplings_of(x), x.get("locked", {}))
    except ChainError as exc:
        raise desc.error((exc.key,), f"{path.name}: {exc}") from None


def kinematic_groups(extra: dict) -> tuple:
    """(base, tool, offset groups, placement groups) of a description's model keys."""
    kin = extra.get("kinematics") or {}
    joints = list(extra["joints"])

    def groups(key: str) -> tuple[Group, ...]:
        return tuple(Group(g["parameter"], tuple(joints.index(j) for j in g["joints"]),
                           tuple(AXIS_NAMES.index(a) for a in g.get("axes", ())))
                     for g in kin.get(key, ()))
    return kin.get("base"), kin.get("tool"), groups("joint_offsets"), groups("placements")


def group_joints(extra: dict, parameter: str) -> list[str] | None:
    """The joints of the kinematic group (joint offsets or placements) whose parameter is `parameter`, in its
    values' order: the names of its elements (`joint_offsets[elbow_joint]`); None if no group has it."""
    kin = extra.get("kinematics") or {}
    for group in [*kin.get("joint_offsets", ()), *kin.get("placements", ())]:
        if group["parameter"] == parameter:
            return list(group["joints"])
    return None


def arm_of(desc: RobotDescription) -> Arm:
    return Arm(load_chain(desc), *kinematic_groups(desc.extra))


def check_pose_parameter(desc: RobotDescription, path: tuple, name: str, types: tuple[str, ...]) -> None:
    param = desc.parameters.get(name)
    if param is None:
        raise desc.error(path, f"no parameter {name!r}; the description has: {', '.join(desc.parameters) or '(none)'}")
    if param.vartype.name not in types or param.indexed:
        raise desc.error(path, f"parameter {name!r} must be one {' or '.join(types)} (`value:`); "
                         f"it is {param.count} {param.vartype.name}")
    if not param.known:
        raise desc.error(("parameters", name), "a kinematic parameter needs its nominal value: give `value:`")


class SerialArmModel(RobotModel):
    name = "serial_arm"
    summary = "serial arm from a URDF (Pinocchio): joint-vector states, base, tool, joint offsets, placement errors"
    schema = {"type": "object",
              "properties": {"urdf": {"type": "string"}, "base_frame": {"type": "string"},
                             "tool_frame": {"type": "string"}, "joints": NAMES,
                             "couplings": {"type": "array", "items": COUPLING},
                             "locked": {"type": "object", "additionalProperties": {"type": "number"}},
                             "kinematics": {"type": "object",
                                            "properties": {"base": {"type": "string"}, "tool": {"type": "string"},
                                                           "joint_offsets": {"type": "array", "items": OFFSET_GROUP},
                                                           "placements": {"type": "array", "items": PLACEMENT_GROUP}},
                                            "additionalProperties": False}},
              "required": ["urdf", "base_frame", "tool_frame", "joints"], "additionalProperties": False}

    def check_description(self, desc: RobotDescription) -> None:
        """The URDF loads with the frames and joints named; every kinematic parameter exists with the
        type and number of values its group needs; no joint (axis) belongs to two groups."""
        load_chain(desc)
        kin = desc.extra.get("kinematics") or {}
        if "base" in kin:
            check_pose_parameter(desc, ("kinematics", "base"), kin["base"], ("pose3",))
        if "tool" in kin:
            check_pose_parameter(desc, ("kinematics", "tool"), kin["tool"], ("pose3", "point3"))
        joints = desc.extra["joints"]
        taken: set = set()
        for key in ("joint_offsets", "placements"):
            for i, group in enumerate(kin.get(key, ())):
                path = ("kinematics", key, i)
                dim = len(group.get("axes", [None]))
                self._check_group(desc, path, group, joints, "scalar" if key == "joint_offsets" else f"vector{dim}")
                for j in group["joints"]:
                    for axis in group.get("axes", ["offset"]):
                        if (key, j, axis) in taken:
                            raise desc.error(path + ("joints",), f"joint {j!r}{'' if axis == 'offset' else ' ' + axis} "
                                             f"is already in another {key} group")
                        taken.add((key, j, axis))

    def element_names(self, desc: RobotDescription, parameter: str) -> list[str] | None:
        """A kinematic group's parameter has one element per joint: named by the joint."""
        return group_joints(desc.extra, parameter)

    def axis_names(self, desc: RobotDescription, parameter: str) -> list[str] | None:
        """A placement group's vector components are the axes its description lists (`tx`, ..., `rz`)."""
        kin = desc.extra.get("kinematics") or {}
        return next((list(g["axes"]) for g in kin.get("placements", ()) if g["parameter"] == parameter), None)

    def geometry(self, robot: str, calibrated: RobotDescription, state: dict) -> list:
        """The arm as a polyline through its joints' origins to the tool frame, at the state's joint vector plus
        the calibrated joint offsets, placed by the calibrated base pose (nominal link placements)."""
        arm = arm_of(calibrated)
        q = next((np.asarray(v, float) for k, v in state.items() if k != "pose" and np.size(v) == arm.chain.n), None)
        if q is None:
            return []
        q = q.copy()
        for group in arm.offsets:
            q[list(group.joints)] += np.asarray(calibrated.parameters[group.parameter].values, float).ravel()
        p = arm.chain.joint_positions(q)
        if arm.base is not None:
            base = calibrated.parameters[arm.base]
            p = base.vartype.from_list(base.values[0]).transformFrom(p.T).T
        return [Lines(f"{robot} links", np.stack([p[:-1], p[1:]], axis=1), "#8c564b", 3.0),
                Points(f"{robot} joints", p[:-1], "#8c564b", 5.0), Points(f"{robot} tool", p[-1:], "#e377c2", 6.0)]

    def outputs(self, robot: str, calibrated: RobotDescription) -> dict[str, str]:
        """`robots/<robot>.urdf`: the URDF with the calibrated parameters built in (export.py)."""
        from .export import urdf_output
        return urdf_output(robot, calibrated)

    @staticmethod
    def _check_group(desc: RobotDescription, path: tuple, group: dict, joints: list[str], vartype: str) -> None:
        unknown = [j for j in group["joints"] if j not in joints]
        if unknown:
            raise desc.error(path + ("joints",), f"{unknown[0]!r} is not one of the arm's joints: {', '.join(joints)}")
        name = group["parameter"]
        param = desc.parameters.get(name)
        if param is None:
            raise desc.error(path + ("parameter",), f"no parameter {name!r}; the description has: "
                             f"{', '.join(desc.parameters) or '(none)'}")
        n = len(group["joints"])
        if param.vartype.name != vartype or not param.indexed or param.count != n:
            raise desc.error(("parameters", name), f"expected a {vartype} with `values:` for each of the {n} joints "
                             f"of {'/'.join(map(str, path))}; got {param.count} {param.vartype.name} value(s)")
        if not param.known:
            raise desc.error(("parameters", name), "a kinematic parameter needs its nominal values: give `values:`")
