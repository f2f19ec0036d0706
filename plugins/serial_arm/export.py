"""The calibrated arm as a URDF (docs/models/serial_arm.md#urdf-export): Pinocchio reloads it to the
forward kinematics of the calibrated parameters, with the encoder readings as joint values.

Each joint that has an offset dq_j or a placement error delta_j gets the origin

    origin'_j = origin_j * Exp(delta_j) * J_j(dq_j)

(J_j: the joint's motion about, or along, its URDF axis), so that origin'_j J_j(q_j) = origin_j
Exp(delta_j) J_j(q_j + dq_j): the URDF's joint value is the encoder reading q_j. Two fixed joints
are added: `measurement_frame` -> the URDF's root link (origin: the base B times root in base_frame)
and the tool frame's link -> `marker` (origin: the marker M). Everything else of the file is kept
(xml.etree: comments kept, unused namespace declarations dropped).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from .lazy_pinocchio import pin

from fusionkit.api import RobotDescription, lie

from .chain import SerialChain
from .factors import entry_layout
from .kinematics import joint_deltas, parameters_of
from .elastic import compliance_document
from .model import arm_of, couplings_of, tool_frames
from .urdf import root_link, urdf_path

MEASUREMENT_FRAME = "measurement_frame"  # the new root link: the frame the tracker measures in
MARKER = "marker"                        # the new link at the marker


def _numbers(text: str | None) -> np.ndarray:
    return np.array([float(x) for x in (text or "0 0 0").split()], float)


def origin_matrix(element: ET.Element) -> np.ndarray:
    """The 4x4 pose of a URDF `<origin xyz rpy>` child of `element` (identity when absent)."""
    origin = element.find("origin")
    T = np.eye(4)
    if origin is not None:
        T[:3, :3] = pin.rpy.rpyToMatrix(*_numbers(origin.get("rpy")))
        T[:3, 3] = _numbers(origin.get("xyz"))
    return T


def set_origin(element: ET.Element, T: np.ndarray) -> None:
    """Write pose T into `element`'s `<origin>` (created after `<child>` when absent), at full precision."""
    origin = element.find("origin")
    if origin is None:
        children = list(element)
        at = next((i + 1 for i, c in enumerate(children) if c.tag == "child"), len(children))
        origin = ET.Element("origin")
        origin.tail = children[at - 1].tail if at else None
        element.insert(at, origin)
    origin.set("xyz", _text(T[:3, 3]))
    origin.set("rpy", _text(pin.rpy.matrixToRpy(T[:3, :3])))


def _text(values) -> str:
    """Numbers as URDF writes them, each to full double precision."""
    return " ".join(format(float(x), ".17g") for x in values)


def _free(name: str, taken: set[str]) -> str:
    """`name`, or `name_1`, `name_2`, ... when the URDF already uses it."""
    out, i = name, 0
    while out in taken:
        i += 1
        out = f"{name}_{i}"
    return out


def _fixed_joint(name: str, parent: str, child: str, T: np.ndarray, indent: str) -> ET.Element:
    """`<joint type="fixed">` from link `parent` to link `child` at pose T, indented as its siblings."""
    joint = ET.Element("joint", name=name, type="fixed")
    joint.text = indent + "  "
    for tag, link in (("parent", parent), ("child", child)):
        ET.SubElement(joint, tag, link=link).tail = indent + "  "
    set_origin(joint, T)
    joint[-1].tail = indent
    return joint


def calibrated_urdf(text: str, chain: SerialChain, joint_errors: dict[int, tuple[float, np.ndarray]], base: np.ndarray,
                    markers: dict[str, np.ndarray], note: str) -> tuple[str, list[str]]:
    """The URDF `text` of `chain` with its calibrated parameters built in (module docstring): `joint_errors` {joint
    id in chain.model: (offset, placement twist)}, the base B, a marker pose M per tool frame; the comment `note`
    (plus the names of the added links) at the top of `<robot>`. Returns the text and the marker links' names."""
    prolog = text[:text.find("<robot")] if "<robot" in text else ""
    robot = ET.fromstring(text, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    joints = {j.get("name"): j for j in robot.findall("joint")}
    links = {link.get("name") for link in robot.findall("link")}
    for jid, (dq, delta) in sorted(joint_errors.items()):
        element = joints[chain.model.names[jid]]
        twist = chain.unit_twist(jid)
        set_origin(element, origin_matrix(element) @ lie.exp(delta) @ lie.exp(dq * twist))
    root = root_link(robot)
    taken = links | set(joints)
    meas = _free(MEASUREMENT_FRAME, taken)
    taken.add(meas)
    meas_joint = _free(f"{meas}_joint", taken)
    taken.add(meas_joint)
    indent = robot.text if robot.text and not robot.text.strip() else "\n  "
    added = [ET.Element("link", name=meas),
             _fixed_joint(meas_joint, meas, root, base @ chain.base_T_universe, indent)]
    said = [f"link {meas} (the measurement frame, parent of {root})"]
    names = []
    for frame, M in markers.items():
        tool_link = frame if frame in links else joints[frame].find("child").get("link")  # a joint's frame: its child's
        marker = _free(MARKER if len(markers) == 1 else f"{MARKER}_{frame}", taken)
        taken.add(marker)
        joint = _free(f"{marker}_joint", taken)
        taken.add(joint)
        added += [ET.Element("link", name=marker), _fixed_joint(joint, tool_link, marker, M, indent)]
        said.append(f"link {marker} (on {tool_link})")
        names.append(marker)
    note += f" Added: {' and '.join(said)}."
    comment = ET.Comment(f" {note.replace('--', '- -')} ")  # "--" may not appear in an XML comment
    robot.insert(0, comment)
    for element in [comment, *added]:
        element.tail = indent
    robot[-1].tail = indent  # the last original element, now followed by the new ones
    robot.extend(added)
    added[-1].tail = "\n"
    return prolog + ET.tostring(robot, encoding="unicode") + "\n", names


def calibrated_errors(calibrated: RobotDescription) -> tuple[SerialChain, dict, np.ndarray, dict[str, np.ndarray], list]:
    """(chain, {joint id: (offset, placement twist)}, base B, {tool frame: marker M}, variables, ({joint: compliance},
    {joint: mass compliances})) of a calibrated
    description, every tool frame's joints together; M = I for a tool frame without a marker parameter. A coupled
    joint moves by its coupling of its leaders' offsets (its value stays the coupling of the readings)."""
    errors: dict[int, tuple[float, np.ndarray]] = {}
    markers, variables, base, compliances, mass_compliances = {}, [], np.eye(4), {}, {}
    for frame in tool_frames(calibrated.extra):
        arm = arm_of(calibrated, frame)
        tool = calibrated.parameters[arm.tool].vartype.name if arm.tool else ""
        layout, names = entry_layout(arm, {}, tool)
        p = parameters_of(layout, [calibrated.parameters[name].values[index or 0] for name, index in names])
        dq, deltas = joint_deltas(layout, p, arm.chain.n)
        for j in set(layout.offsets) | set(deltas):
            errors[arm.chain.jids[j]] = (float(dq[j]), deltas.get(j, np.zeros(6)))
        for jid, row in zip(arm.chain.coupled_jids, arm.chain.coupling):
            if jid in arm.chain.path and row @ dq:
                errors[jid] = (float(row @ dq), np.zeros(6))
        base = np.eye(4) if p.base is None else p.base
        markers[frame] = np.eye(4) if p.tool is None else p.tool
        variables += names
        compliances.update({arm.chain.joint_names[j]: float(c) for j, c in zip(layout.compliances, p.compliances)})
        mass_compliances.update({arm.chain.joint_names[j]: [float(x) for x in v]
                                 for j, v in zip(layout.mass_compliances, p.mass_compliances)})
    return arm.chain, errors, base, markers, list(dict.fromkeys(variables)), (compliances, mass_compliances)


def urdf_output(robot: str, calibrated: RobotDescription) -> dict[str, str]:
    """{`robots/<robot>.urdf`: the description's URDF with its calibrated parameters built in; with compliances
    also `robots/<robot>.compliance.yaml` (elastic.py)}: the serial_arm model's output of `fusionkit run`
    (RobotModel.outputs)."""
    chain, errors, base, markers, variables, compliances = calibrated_errors(calibrated)
    source = urdf_path(str(calibrated.extra["urdf"]), Path(calibrated.doc.file).parent)
    drifting = sorted({name for name, _ in variables if calibrated.parameters[name].time_varying})
    note = (f"fusionkit: robot {robot!r} ({calibrated.name}) calibrated, from {source.name}. Joints with an offset or "
            "a placement error: origin = URDF origin * Exp(placement error) * the joint's motion by its offset, so "
            "the joint value is the encoder reading (a coupled joint's: its coupling of the readings)."
            + (f" Time-varying parameters at their last estimated value: {', '.join(drifting)}." if drifting else ""))
    text, marker_links = calibrated_urdf(source.read_text(encoding="utf-8"), chain, errors, base, markers, note)
    out = {f"robots/{robot}.urdf": text}
    if any(compliances):
        gravity = (base @ chain.base_T_universe)[:3, :3] @ chain.gravity  # the URDF root's gravity, seen from the
        out[f"robots/{robot}.compliance.yaml"] = compliance_document(  # measurement frame (the exported root)
            chain, *compliances, arm_of(calibrated).lumped, gravity, f"{robot}.urdf", marker_links,
            couplings_of(calibrated.extra), calibrated.extra.get("locked", {}), arm_of(calibrated).payload,
            f"robot {robot!r} ({calibrated.name}): joint compliances beside {robot}.urdf; deflected pose = "
            "FK(q + compliance x gravity torque(q)) (fusionkit_plugins.serial_arm.elastic.deflected_pose)")
    return out
