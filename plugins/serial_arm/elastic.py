"""The calibrated elastic arm outside fusionkit (docs/models/serial_arm.md#joint-elasticity-under-gravity): the
joint compliances written beside the calibrated URDF, and the deflected pose they predict.

`robots/<robot>.compliance.yaml` holds what the URDF cannot: each compliant joint's compliance (rad per N m; m per N
if prismatic) and, with lumped masses, each joint's products of compliance and mass with the masses' points, the
gravity vector in the URDF's root frame (the measurement frame the export adds: the base's -z
seen from there), the joint list and couplings (a URDF <mimic> has one leader). The deflected pose at encoder
readings q and a payload is

    T(q) = FK_urdf(q + C tau(q) + sum_i P_i tau_i(q))

with tau the gravity torques of the exported URDF's inertials plus the payload, tau_i those of 1 kg at lumped mass
i (Pinocchio), FK the exported URDF's forward kinematics (joint offsets and placement errors built into its
origins).
"""

from __future__ import annotations

from pathlib import Path

import xml.etree.ElementTree as ET

import numpy as np
import yaml

from .chain import Coupling, SerialChain
from .kinematics import Layout, Parameters, deflected
from .urdf import root_link

FORMAT = "fusionkit serial_arm compliances 1"


def compliance_document(chain: SerialChain, compliances: dict[str, float], mass_compliances: dict[str, list],
                        lumped: tuple, gravity: np.ndarray, urdf: str, frames: list[str], couplings: list[Coupling],
                        locked: dict, payload: tuple, note: str) -> str:
    """The YAML text of `robots/<robot>.compliance.yaml` (module docstring); `frames`: the marker links."""
    doc = {"format": FORMAT, "urdf": urdf, "note": note, "joints": list(chain.joint_names),
           "tool_frames": list(chain.tool_frames),
           "couplings": [{"joint": c.joint, "of": dict(c.leaders), "offset": c.offset} for c in couplings],
           "locked": {name: float(v) for name, v in locked.items()},
           "compliance": {name: float(v) for name, v in compliances.items()},
           "mass_compliance": {name: [float(x) for x in v] for name, v in mass_compliances.items()},
           "lumped_masses": [{"link": m[0], "center": [float(x) for x in m[1:4]]} for m in lumped],
           "gravity": [float(x) for x in gravity], "frames": list(frames),
           "payload": {"frame": payload[0], "mass": payload[1], "center": list(payload[2:5])} if payload else None}
    return yaml.safe_dump(doc, sort_keys=False)


def deflected_pose(compliance_file: str | Path, q, frame: str | None = None, payload: dict | None = None) -> np.ndarray:
    """The pose (4x4) of `frame` (default: the document's first marker frame) in the exported URDF's root (the
    measurement frame) at encoder readings q (n,) or (N, n), with its joints deflected under gravity and
    `payload` ({mass: kg, center: [x, y, z] m, frame: name, default the robot's first tool frame}; default the one
    the calibration used); (N, 4, 4) for several configurations."""
    path = Path(compliance_file)
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a fusionkit compliance file (expected format: {FORMAT!r})")
    couplings = tuple(Coupling(c["joint"], tuple((k, float(v)) for k, v in c["of"].items()), float(c["offset"]))
                      for c in doc["couplings"])
    urdf = path.parent / doc["urdf"]
    chain = SerialChain.from_urdf(urdf, root_link(ET.parse(urdf).getroot()), tuple(doc["frames"]), doc["joints"], couplings,
                                  tuple(doc["locked"].items()))
    chain = chain.for_tool(frame or doc["frames"][0])
    chain.gravity = np.asarray(doc["gravity"], float)
    load = payload if payload is not None else doc.get("payload")
    carried = (load.get("frame", doc["tool_frames"][0]), float(load["mass"]), *map(float, load.get("center", (0, 0, 0)))) \
        if load else ()
    layout = Layout(compliances=tuple(doc["joints"].index(name) for name in doc["compliance"]), payload=carried,
                    mass_compliances=tuple(doc["joints"].index(name) for name in doc["mass_compliance"]),
                    lumped=tuple((m["link"], *m["center"]) for m in doc["lumped_masses"]))
    p = Parameters(compliances=np.array(list(doc["compliance"].values())),
                   mass_compliances=[np.asarray(v, float) for v in doc["mass_compliance"].values()])
    single = np.ndim(q) == 1
    q_eff, _, _, _ = deflected(chain, layout, np.atleast_2d(np.asarray(q, float)), p)
    T = np.array([chain.flange(qi).T for qi in q_eff])
    return T[0] if single else T
