"""Bad serial-arm descriptions and entries stop `fusionkit validate` with one located line (file, line, key
path, what was expected) and exit code 2, never a traceback. The descriptions are inline in the config: a
description's key paths are its own (`urdf`, `kinematics.base`), on the config's lines."""

from __future__ import annotations

import pytest

from fusionkit.api import robot_description_data
from fusionkit.cli.main import main
from fusionkit_plugins.serial_arm.simulators import ROBOTS


def config(description: dict, factors: list | None = None, states: dict | None = None) -> dict:
    return {"name": "bad_arm",
            "robots": {"arm": {"description": description,
                               "states": states or {"stream": "joints", "type": "vector6", "family": "joints"}}},
            "sources": [{"type": "simulate", "scenario": "arm.sim", "params": {"configurations": 5}}],
            "factors": factors or [{"type": "arm.joint_encoders", "robot": "arm", "stream": "joints", "sigma": 1e-5},
                                   {"type": "arm.tool_pose", "robot": "arm", "stream": "tracker",
                                    "sigma": {"rotation": 1e-4, "translation": 1e-4}}]}


def edit_description(change):
    def make(tmp_path) -> dict:
        desc = robot_description_data("ur10_tracker")
        change(desc, tmp_path)
        return config(desc)
    return make


def edit_config(change):
    def make(tmp_path) -> dict:
        c = config(robot_description_data("ur10_tracker"))
        change(c)
        return c
    return make


def garbage_urdf(desc, tmp_path):
    (tmp_path / "broken.urdf").write_text("<robot name='x'><link name='a'></robot>")
    desc["urdf"] = "broken.urdf"


CASES = {
    "missing URDF": (edit_description(lambda d, _: d.update(urdf="arm.urdf")),
                     "urdf: URDF file not found: "),
    "unknown packaged robot": (edit_description(lambda d, _: d.update(urdf="example-robot-data:ur11")),
                               "urdf: example-robot-data has no robot 'ur11'"),
    "unreadable URDF": (edit_description(garbage_urdf), "urdf: broken.urdf: not a URDF Pinocchio can read: "),
    "unknown joint": (edit_description(lambda d, _: d["joints"].__setitem__(2, "knee")),
                      "joints: ur10_robot.urdf: the URDF has no joint 'knee'"),
    "a joint moving the tool left out": (edit_description(lambda d, _: d.update(joints=d["joints"][:5])),
                                         "joints: ur10_robot.urdf: joint 'wrist_3_joint' moves tool_frame 'tool0' but "
                                         "is not in `joints`"),
    "coupling of an unknown joint": (
        edit_description(lambda d, _: d.update(couplings=[{"joint": "knee", "of": {"elbow_joint": 1.0}}])),
        "couplings: ur10_robot.urdf: the URDF has no joint 'knee' to couple"),
    "unknown tool frame": (edit_description(lambda d, _: d.update(tool_frame="flange")),
                           "tool_frame: ur10_robot.urdf: the URDF has no frame 'flange'"),
    "group joint not in the arm": (
        edit_description(lambda d, _: d["kinematics"]["joint_offsets"][0]["joints"].__setitem__(0, "knee")),
        "kinematics.joint_offsets[0].joints: 'knee' is not one of the arm's joints"),
    "placement of the wrong size": (
        edit_description(lambda d, _: d["kinematics"]["placements"][0].update(axes=["tx", "tz"])),
        "parameters.placement: expected a vector2 with `values:` for each of the 6 joints"),
    "base not a pose": (edit_description(lambda d, _: d["kinematics"].update(base="joint_offsets")),
                        "kinematics.base: parameter 'joint_offsets' must be one pose3"),
    "joint in two offset groups": (
        edit_description(lambda d, _: (d["kinematics"]["joint_offsets"].append(
            {"parameter": "extra", "joints": ["elbow_joint"]}),
            d["parameters"].update(extra={"type": "scalar", "values": [0.0], "sigma": 0.01}))),
        "kinematics.joint_offsets[1].joints: joint 'elbow_joint' is already in another "
        "joint_offsets group"),
    "unknown axis": (edit_description(lambda d, _: d["kinematics"]["placements"][0].update(axes=["tx", "tw"])),
                     "kinematics.placements[0].axes[1]: got 'tw'; expected one of: tx, ty, tz, rx, ry, rz"),
    "states of the wrong size": (
        lambda _: config(robot_description_data("ur10_tracker"), states={"stream": "joints", "type": "vector7",
                                                                         "family": "joints"}),
        "factors[0].robot: robot 'arm' has vector7 states; this needs vector6"),
    "encoder columns miscounted": (edit_config(lambda c: c["factors"][0].update(columns=["a", "b"])),
                                   "factors[0].columns: 2 given; the arm has 6 joints"),
    "tool not a pose": (edit_config(lambda c: c["factors"][1].update(tool="joint_offsets")),
                        "factors[1].tool: parameter 'joint_offsets' is scalar; a tool is one pose3"),
    "point tool for a pose tracker": (
        edit_description(lambda d, _: d["parameters"].update(marker={"type": "point3", "value": [0, 0, 0.06]})),
        "factors[1].robot: the description's kinematics.tool 'marker' is a point3; arm.tool_pose needs a pose3"),
}


def upper_body(change):
    """The shipped two-hand description and the config of configs/upper_body_calibration.yaml, changed."""
    def make(tmp_path) -> dict:
        desc = robot_description_data("upper_body_mocap")
        desc["urdf"] = str(ROBOTS / desc["urdf"])  # inline: the shipped URDF where it is installed
        hands = [{"type": "arm.tool_position", "robot": "arm", "stream": "tracker", "tool_frame": hand,
                  "columns": [f"{hand}_{a}" for a in "xyz"], "sigma": 2e-4} for hand in ("l_hand", "r_hand")]
        c = config(desc, [{"type": "arm.joint_encoders", "robot": "arm", "stream": "joints", "sigma": 1e-5}, *hands],
                   {"stream": "joints", "type": "vector13", "family": "joints"})
        c["sources"][0]["params"] = {"description": "upper_body_mocap", "measurement": "position",
                                     "configurations": 5}
        change(c, desc)
        return c
    return make


CASES.update({
    "two hands, entry names none": (upper_body(lambda c, _: c["factors"][1].pop("tool_frame")),
                                    "factors[1].robot: robot 'arm' has several tool frames (l_hand, r_hand): name the "
                                    "one this entry measures (`tool_frame:`)"),
    "two hands, entry names another frame": (upper_body(lambda c, _: c["factors"][2].update(tool_frame="chest")),
                                             "factors[2].tool_frame: 'chest' is not a tool frame of robot 'arm': l_hand, r_hand"),
    "two hands, one marker for both": (upper_body(lambda _, d: d["kinematics"].update(tool="marker_left")),
                                       "kinematics.tool: the robot has several tool frames: give one marker parameter "
                                       "per frame"),
    "two hands, marker of an unknown frame": (
        upper_body(lambda _, d: d["kinematics"].update(tool={"l_hand": "marker_left", "head": "marker_right"})),
        "kinematics.tool.head: 'head' is not one of the tool frames (tool_frame: l_hand, r_hand)"),
    "point markers without a base": (
        upper_body(lambda c, d: (d["kinematics"].pop("base"),
                                 c.update(initializers=[{"type": "arm.point_markers", "robot": "arm"}]))),
        "initializers[0].robot: robot 'arm' has no pose3 base (kinematics.base): nothing for arm.point_markers to "
        "start"),
    "a listed joint moving no tool frame": (
        upper_body(lambda _, d: d.update(tool_frame=["l_hand"])),
        "joints: upper_body.urdf: joint 'r_shoulder_pitch' does not move tool_frame 'l_hand'"),
})


@pytest.mark.parametrize("case", CASES)
def test_bad_arm_input_is_one_located_line(tmp_path, workspace, capfd, case):
    make, needle = CASES[case]
    path = workspace.config(make(tmp_path))
    assert main(["validate", str(path)]) == 2
    err = capfd.readouterr().err  # at the file descriptor: what the C++ URDF parser prints counts too
    assert err.count("\n") == 1 and needle in err and str(path) in err, err
