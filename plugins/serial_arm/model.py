"""The `serial_arm` robot model: a serial arm from its URDF, and which description parameters are its
kinematic parameters (docs/reference/robot_description.md#model-serial_arm).

    model: serial_arm
    urdf: example-robot-data:ur10      # or a file relative to the description
    base_frame: base_link              # the URDF frame the arm stands on (FK starts here)
    tool_frame: tool0                  # the flange; several: [left_hand, right_hand] (entries name theirs)
    joints: [shoulder_pan_joint, ...]  # the joint-state vector, in this order
    couplings:                         # optional: joints moved by listed ones (a URDF <mimic> is one too)
      - {joint: torso_c, of: {torso_a: -1.0, torso_b: -1.0}, offset: 0.0}   # q_c = offset + sum k q (rad or m)
    locked: {gripper_joint: 0.0}       # optional: joints held at a value (one that moves the tool must be listed,
                                       # coupled or locked; the others are held at their neutral value)
    kinematics:                        # every key optional
      base: base                       # pose3: base_frame in the measurement frame
      tool: marker                     # pose3 (or point3): the marker in the tool frame; with several tool
                                       # frames, one per frame: {left_hand: marker_left, right_hand: marker_right}
      joint_offsets:                   # scalar parameters, one value per listed joint (rad; m if prismatic)
        - {parameter: joint_offsets, joints: [shoulder_pan_joint, ...]}
      placements:                      # vectorN parameters, one value per listed joint, N = len(axes)
        - {parameter: placement, joints: [...], axes: [tx, ty, tz, rx, ry, rz]}
      compliances:                     # scalar parameters, one per listed joint: deflection = compliance * gravity
        - {parameter: compliance, joints: [shoulder_lift_joint, elbow_joint]}   # torque (rad per N m; URDF inertials)
      lumped_masses: [forearm_link, {link: wrist_3_link, center: [0, 0, 0.05]}]   # without (right) inertials:
      mass_compliances:                # vectorM parameters, one per listed joint: deflection = sum_i P_i * torque of
        - {parameter: mass_compliance, joints: [shoulder_lift_joint]}   # 1 kg at lumped mass i (P: rad/(N m) x kg)
    payload: {mass: 2.0, center: [0, 0, 0.05], frame: tool0}   # optional known load (kg, m in `frame`, default the
                                                                # first tool frame): adds to the gravity torques
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
LUMPED_MASS = {"oneOf": [{"type": "string"},
                        {"type": "object", "properties": {"link": {"type": "string"},
                                                          "center": {"type": "array", "items": {"type": "number"},
                                                                     "minItems": 3, "maxItems": 3}},
                         "required": ["link"], "additionalProperties": False}]}
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
    """A validated serial_arm description seen from one of its tool frames: the chain computing that frame's pose,
    the base and that frame's marker parameter, every offset and placement group."""

    chain: SerialChain
    base: str | None
    tool: str | None
    offsets: tuple[Group, ...]
    placements: tuple[Group, ...]
    compliances: tuple[Group, ...] = ()
    payload: tuple = ()           # (frame, mass kg, x, y, z m) of a known load, () for none
    mass_compliances: tuple[Group, ...] = ()
    lumped: tuple = ()            # (link, x, y, z m) of each lumped mass


def tool_frames(extra: dict) -> tuple[str, ...]:
    """The description's tool frames (`tool_frame`: one name or a list)."""
    frames = extra["tool_frame"]
    return (frames,) if isinstance(frames, str) else tuple(frames)


def marker_of(extra: dict, frame: str) -> str | None:
    """The description's marker parameter on tool frame `frame` (`kinematics.tool`: one name, or one per frame)."""
    tool = (extra.get("kinematics") or {}).get("tool")
    return tool.get(frame) if isinstance(tool, dict) else tool


@lru_cache(maxsize=32)
def _chain(path: str, mtime: float, base_frame: str, tool_frames: tuple[str, ...], joints: tuple[str, ...],
           couplings: tuple[Coupling, ...], locked: tuple[tuple[str, float], ...]) -> SerialChain:
    return SerialChain.from_urdf(Path(path), base_frame, tool_frames, list(joints), couplings, locked)


def chain_from(path: Path, base_frame: str, tool_frames, joints, couplings=(), locked=()) -> SerialChain:
    """The chain of a URDF file (loaded once while the file is unchanged), computing the first tool frame's pose."""
    frames = (tool_frames,) if isinstance(tool_frames, str) else tuple(tool_frames)
    return _chain(str(path), path.stat().st_mtime, base_frame, frames, tuple(joints), tuple(couplings),
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
        return chain_from(path, x["base_frame"], tool_frames(x), x["joints"], couplings_of(x), x.get("locked", {}))
    except ChainError as exc:
        raise desc.error((exc.key,), f"{path.name}: {exc}") from None


def kinematic_groups(extra: dict, frame: str | None = None) -> tuple:
    """(base, the marker of tool frame `frame` (default: the first), offset groups, placement groups) of a
    description's model keys."""
    kin = extra.get("kinematics") or {}
    joints = list(extra["joints"])

    def groups(key: str) -> tuple[Group, ...]:
        return tuple(Group(g["parameter"], tuple(joints.index(j) for j in g["joints"]),
                           tuple(AXIS_NAMES.index(a) for a in g.get("axes", ())))
                     for g in kin.get(key, ()))
    load = extra.get("payload")
    payload = (load.get("frame", tool_frames(extra)[0]), float(load["mass"]),
               *map(float, load.get("center", (0.0, 0.0, 0.0)))) if load else ()
    lumped = tuple((m, 0.0, 0.0, 0.0) if isinstance(m, str) else (m["link"], *map(float, m.get("center", (0, 0, 0))))
                   for m in kin.get("lumped_masses", ()))
    return kin.get("base"), marker_of(extra, frame or tool_frames(extra)[0]), groups("joint_offsets"), \
        groups("placements"), groups("compliances"), payload, groups("mass_compliances"), lumped


def group_joints(extra: dict, parameter: str) -> list[str] | None:
    """The joints of the kinematic group (joint offsets or placements) whose parameter is `parameter`, in its
    values' order: the names of its elements (`joint_offsets[elbow_joint]`); None if no group has it."""
    kin = extra.get("kinematics") or {}
    for group in [*kin.get("joint_offsets", ()), *kin.get("placements", ()), *kin.get("compliances", ()),
                  *kin.get("mass_compliances", ())]:
        if group["parameter"] == parameter:
            return list(group["joints"])
    return None


def arm_of(desc: RobotDescription, frame: str | None = None) -> Arm:
    """The description seen from tool frame `frame` (default: its first)."""
    chain = load_chain(desc)
    return Arm(chain.for_tool(frame) if frame else chain, *kinematic_groups(desc.extra, frame))


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
                             "tool_frame": {"oneOf": [{"type": "string"}, NAMES]}, "joints": NAMES,
                             "couplings": {"type": "array", "items": COUPLING},
                             "locked": {"type": "object", "additionalProperties": {"type": "number"}},
                             "payload": {"type": "object",
                                         "properties": {"mass": {"type": "number", "minimum": 0},
                                                        "center": {"type": "array", "items": {"type": "number"},
                                                                   "minItems": 3, "maxItems": 3},
                                                        "frame": {"type": "string"}},
                                         "required": ["mass"], "additionalProperties": False},
                             "kinematics": {"type": "object",
                                            "properties": {"base": {"type": "string"},
                                                           "tool": {"oneOf": [{"type": "string"},
                                                                              {"type": "object", "minProperties": 1,
                                                                               "additionalProperties":
                                                                                   {"type": "string"}}]},
                                                           "joint_offsets": {"type": "array", "items": OFFSET_GROUP},
                                                           "compliances": {"type": "array", "items": OFFSET_GROUP},
                                                           "lumped_masses": {"type": "array", "minItems": 1,
                                                                             "items": LUMPED_MASS},
                                                           "mass_compliances": {"type": "array",
                                                                                "items": OFFSET_GROUP},
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
        tool = kin.get("tool")
        if isinstance(tool, dict):
            frames = tool_frames(desc.extra)
            for frame, name in tool.items():
                if frame not in frames:
                    raise desc.error(("kinematics", "tool", frame), f"{frame!r} is not one of the tool frames "
                                     f"(tool_frame: {', '.join(frames)})")
                check_pose_parameter(desc, ("kinematics", "tool", frame), name, ("pose3", "point3"))
        elif tool is not None:
            if len(tool_frames(desc.extra)) > 1:
                raise desc.error(("kinematics", "tool"), "the robot has several tool frames: give one marker "
                                 "parameter per frame ({frame: parameter}), or none and name it in each entry (`tool:`)")
            check_pose_parameter(desc, ("kinematics", "tool"), tool, ("pose3", "point3"))
        joints = desc.extra["joints"]
        taken: set = set()
        lumped = len(kin.get("lumped_masses", ()))
        if kin.get("mass_compliances") and not lumped:
            raise desc.error(("kinematics", "mass_compliances"), "mass compliances need `lumped_masses:` (the links "
                             "whose masses they multiply)")
        for key in ("joint_offsets", "placements", "compliances", "mass_compliances"):
            for i, group in enumerate(kin.get(key, ())):
                path = ("kinematics", key, i)
                dim = len(group["axes"]) if key == "placements" else lumped
                self._check_group(desc, path, group, joints, f"vector{dim}" if key in ("placements", "mass_compliances")
                                  else "scalar")
                for j in group["joints"]:
                    for axis in group.get("axes", ["offset"]):
                        if (key, j, axis) in taken:
                            raise desc.error(path + ("joints",), f"joint {j!r}{'' if axis == 'offset' else ' ' + axis} "
                                             f"is already in another {key} group")
                        taken.add((key, j, axis))
        self._check_gravity(desc, kin)

    def element_names(self, desc: RobotDescription, parameter: str) -> list[str] | None:
        """A kinematic group's parameter has one element per joint: named by the joint."""
        return group_joints(desc.extra, parameter)

    def axis_names(self, desc: RobotDescription, parameter: str) -> list[str] | None:
        """A placement group's vector components are the axes its description lists (`tx`, ..., `rz`); a mass
        compliance's, the lumped masses' links."""
        kin = desc.extra.get("kinematics") or {}
        if any(g["parameter"] == parameter for g in kin.get("mass_compliances", ())):
            return [m if isinstance(m, str) else m["link"] for m in kin["lumped_masses"]]
        return next((list(g["axes"]) for g in kin.get("placements", ()) if g["parameter"] == parameter), None)

    def geometry(self, robot: str, calibrated: RobotDescription, state: dict) -> list:
        """The arm as polylines through the joints' origins to each tool frame, at the state's joint vector plus
        the calibrated joint offsets, placed by the calibrated base pose (nominal link placements)."""
        arm = arm_of(calibrated)
        q = next((np.asarray(v, float) for k, v in state.items() if k != "pose" and np.size(v) == arm.chain.n), None)
        if q is None:
            return []
        q = q.copy()
        for group in arm.offsets:
            q[list(group.joints)] += np.asarray(calibrated.parameters[group.parameter].values, float).ravel()
        paths = [arm.chain.for_tool(frame).joint_positions(q) for frame in tool_frames(calibrated.extra)]
        if arm.base is not None:
            base = calibrated.parameters[arm.base]
            paths = [base.vartype.from_list(base.values[0]).transformFrom(p.T).T for p in paths]
        links = np.concatenate([np.stack([p[:-1], p[1:]], axis=1) for p in paths])
        joints = np.concatenate([p[:-1] for p in paths])  # a torso's joints appear once per tool
        return [Lines(f"{robot} links", links, "#8c564b", 3.0), Points(f"{robot} joints", joints, "#8c564b", 5.0),
                Points(f"{robot} tool", np.array([p[-1] for p in paths]), "#e377c2", 6.0)]

    def outputs(self, robot: str, calibrated: RobotDescription) -> dict[str, str]:
        """`robots/<robot>.urdf`: the URDF with the calibrated parameters built in (export.py)."""
        from .export import urdf_output
        return urdf_output(robot, calibrated)

    @staticmethod
    def _check_gravity(desc: RobotDescription, kin: dict) -> None:
        """A payload's frame is in the URDF; a compliant joint carries mass (else its torque, and what its compliance
        moves, is zero: the URDF has no inertials there)."""
        chain = load_chain(desc)
        load = desc.extra.get("payload")
        if load and not chain.model.existFrame(load.get("frame", tool_frames(desc.extra)[0])):
            raise desc.error(("payload", "frame"), f"the URDF has no frame {load['frame']!r}")
        for i, mass in enumerate(kin.get("lumped_masses", ())):
            link = mass if isinstance(mass, str) else mass["link"]
            if not chain.model.existFrame(link):
                raise desc.error(("kinematics", "lumped_masses", i), f"the URDF has no link {link!r}")
        for i, group in enumerate(kin.get("compliances", ())):
            for name in group["joints"]:
                jid = chain.model.getJointId(name)
                beyond = set(chain.model.subtrees[jid])
                carried = load and chain.model.frames[chain.model.getFrameId(load.get("frame", tool_frames(
                    desc.extra)[0]))].parentJoint in beyond and load["mass"] > 0
                if not carried and sum(chain.model.inertias[j].mass for j in beyond) <= 0:
                    raise desc.error(("kinematics", "compliances", i, "joints"), f"joint {name!r} carries no mass in "
                                     "the URDF (no <inertial> beyond it): its gravity torque is 0, a compliance would "
                                     "move nothing; give the links their inertials or a payload")

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
