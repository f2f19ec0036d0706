"""Identifiability of the kinematic parameters from the recorded configurations: the rank of the whitened
kinematic regressor (QR with column pivoting), the combinations the data cannot separate, named in the
verdict, held at their nominal values -- and the combination really moves no measurement."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
import yaml

from fusionkit.api import robot_description_data
from fusionkit.pipeline import build_problem, read_sources
from fusionkit.simulate import simulated_config
from fusionkit_plugins.serial_arm.identifiability import analyze
from fusionkit_plugins.serial_arm.kinematics import Parameters, marker_pose

from arm_helpers import layouts, nominal_parameters

DIAGNOSTIC = "arm: kinematic identifiability"


def diagnose(params: dict, seed: int = 0, edit=None):
    with simulated_config("arm.sim", params, seed, edit) as config:
        streams, _ = read_sources(config)
        problem = build_problem(config, streams)
    return config, problem


@pytest.mark.parametrize("description, joints, configurations", [("ur10_tracker", 6, 60), ("panda_tracker", 7, 80)])
def test_a_full_pose_tracker_identifies_4_per_revolute_joint_plus_6_and_holds_the_rest(description, joints,
                                                                                       configurations):
    """Everett, Driels and Mooring (1987): with full-pose measurements an all-revolute arm has 4 R + 6
    independent kinematic parameters. The description has 12 (base, marker) + 7 per joint."""
    config, problem = diagnose({"description": description, "configurations": configurations})
    d = problem.diagnostics[DIAGNOSTIC]
    n = 12 + 7 * joints
    assert (d["rank"], len(d["parameters"]), len(d["held"])) == (4 * joints + 6, n, n - 4 * joints - 6)
    assert d["verdict"][0].startswith(f"{n - 4 * joints - 6} of {n} kinematic parameters are not identifiable from "
                                      f"these {configurations} configurations and are held at their nominal values")
    holds = [r for r in problem.records if r.label.startswith("held:arm/")]
    assert sum(r.factor.dim() for r in holds) == len(d["held"])


def test_the_verdict_names_the_first_joint_offset_with_the_base_yaw():
    """The first joint turns about the base's z axis: its offset and the base yaw are one combination."""
    _, problem = diagnose({"configurations": 60})
    d = problem.diagnostics[DIAGNOSTIC]
    assert "joint_offsets[shoulder_pan_joint]" in d["held"] and "base.rz" not in d["held"]
    assert d["combinations"]["joint_offsets[shoulder_pan_joint]"] == pytest.approx({"base.rz": -1.0}, abs=1e-9)
    assert ("joint_offsets[shoulder_pan_joint]: not identifiable: changing it by d and base.rz by -1 d leaves every "
            "measurement unchanged; held") in d["verdict"]
    # and likewise the last joint's offset with the marker's rotation about the flange axis (at the marker the data
    # put, 0.02 rad from the nominal one: its other axes take a little of it)
    partners = d["combinations"]["joint_offsets[wrist_3_joint]"]
    assert partners["marker.rz"] == pytest.approx(-1.0, abs=1e-3)
    assert max(abs(c) for name, c in partners.items() if name != "marker.rz") < 0.05


def test_the_reported_combination_moves_no_marker_pose_at_any_configuration():
    """Not only to first order: turning the first joint's offset by 0.1 rad and the base by -0.1 rad about its
    z axis gives the same marker poses to 1e-12 m."""
    config, problem = diagnose({"configurations": 20})
    chain, layout, variables = layouts(config)
    p = nominal_parameters(config)
    turned = Parameters(p.base @ gtsam.Pose3(gtsam.Rot3.Yaw(-0.1), np.zeros(3)).matrix(), p.tool,
                        p.offsets + np.eye(len(p.offsets))[0] * 0.1, p.placements)
    for q in np.random.default_rng(1).uniform(-3, 3, (20, chain.n)):
        np.testing.assert_allclose(marker_pose(chain, layout, q, turned)[0], marker_pose(chain, layout, q, p)[0],
                                   atol=1e-12)


def test_a_laser_tracker_cannot_see_the_marker_rotation_and_the_analysis_takes_the_marker_where_the_data_put_it():
    """Positions only: the marker's rotation moves nothing. The analysis linearizes with the base and marker fitted to
    the data (frames.frame_fit): the simulated marker is 4 mm from the last joint's axis, so two of that joint's
    placement axes are estimated (rank 27); at the description's marker, on the axis, they were held (rank 25). The
    last joint's offset needs more than 4 mm of lever with 0.1 mm of noise: still held."""
    def position(config):
        config["factors"][1] = {"type": "arm.tool_position", "robot": "arm", "stream": "tracker", "sigma": 1e-4}
    _, problem = diagnose({"configurations": 60, "measurement": "position"}, edit=position)
    d = problem.diagnostics[DIAGNOSTIC]
    assert {"marker.rx", "marker.ry", "marker.rz", "joint_offsets[wrist_3_joint]"} <= set(d["held"])
    assert "marker.rx: moves no measurement; held" in d["verdict"]
    assert d["rank"] == 27 and {"placement[wrist_3_joint].tx", "placement[wrist_3_joint].rx"} <= set(d["sigma_from_data"])


def test_the_frame_fit_puts_a_marker_given_at_the_flange_origin_where_the_data_put_it():
    """Positions of a point marker 4 mm from the last axis, from a UR10 with a known base: started at the flange
    origin (the URDF's tool origin) and a base 5 cm / 0.05 rad off, the fit lands on both to 1e-9."""
    from fusionkit_plugins.serial_arm.factors import example_arm
    from fusionkit_plugins.serial_arm.frames import frame_fit
    from fusionkit_plugins.serial_arm.kinematics import Layout
    rng = np.random.default_rng(2)
    chain, _, _ = example_arm(rng, "point3")
    layout = Layout(True, "point3")
    tool = np.eye(4)
    tool[:3, 3] = [-0.0039, 0.0004, 0.0522]
    truth = Parameters(gtsam.Pose3.Expmap(np.array([0.1, -0.2, 0.6, 1.2, 0.4, -0.3])).matrix(), tool)
    q = rng.uniform(-2.5, 2.5, (40, 6))
    measured = np.array([marker_pose(chain, layout, qi, truth)[0][:3, 3] for qi in q])
    start = Parameters(truth.base @ gtsam.Pose3.Expmap(np.array([0.05, -0.03, 0.02, 0.05, 0.02, -0.04])).matrix(),
                       np.eye(4))
    fitted = frame_fit(chain, layout, start, q, measured, "position")
    assert fitted.tool[:3, 3] == pytest.approx(tool[:3, 3], abs=1e-9)
    assert fitted.base == pytest.approx(truth.base, abs=1e-9)


def test_three_configurations_identify_at_most_18_parameters():
    _, problem = diagnose({"configurations": 3})
    d = problem.diagnostics[DIAGNOSTIC]
    assert d["rank"] == 18 and len(d["held"]) == 54 - 18
    assert d["verdict"][0].startswith("36 of 54 kinematic parameters are not identifiable from these 3 configurations")


def test_a_minimal_parameter_set_is_all_identifiable_and_a_tight_prior_is_named_weak(workspace):
    """Base, marker and the offsets of joints 2-5 (16 parameters, the FIGAROH UR10 example's set): all
    identifiable from 10 configurations; the wrist_1 offset's prior (1e-7 rad) is tighter than what the data
    give, and the verdict says so."""
    desc = robot_description_data("ur10_tracker")
    desc["kinematics"] = {"base": "base", "tool": "marker",
                          "joint_offsets": [{"parameter": "joint_offsets", "joints": desc["joints"][1:5]}]}
    desc["parameters"]["joint_offsets"] = {"type": "scalar", "values": [0.0] * 4, "sigma": [0.01, 0.01, 1e-7, 0.01]}
    del desc["parameters"]["placement"]
    (workspace.folder / "arm.yaml").write_text(yaml.safe_dump(desc))

    def minimal(config):
        config["robots"]["arm"]["description"] = str(workspace.folder / "arm.yaml")
    _, problem = diagnose({"configurations": 10}, edit=minimal)
    d = problem.diagnostics[DIAGNOSTIC]
    assert (d["rank"], d["held"]) == (16, [])
    assert d["verdict"][0].startswith("all 16 kinematic parameters are identifiable from 10 configurations")
    weak = [line for line in d["verdict"] if "weakly identified" in line]
    assert len(weak) == 1 and weak[0].startswith("joint_offsets[wrist_1_joint]: weakly identified: the data alone give")
    assert not [r for r in problem.records if r.label.startswith("held:")]


def test_analyze_finds_the_rank_and_the_null_vector_of_a_small_regressor():
    """Columns a, b, a + 2 b, c: rank 3; the last column of the dependent set (a + 2 b) is held, and its
    combination is -1 x a, -2 x b (scaled columns report physical units)."""
    rng = np.random.default_rng(2)
    a, b, c = rng.normal(size=(3, 20))
    A = np.column_stack([a, b, a + 2 * b, c])
    result = analyze(A, np.ones(4))
    assert (result.rank, result.held) == (3, [2])
    assert dict(result.combinations[2]) == pytest.approx({0: -1.0, 1: -2.0})
    scaled = analyze(A / [1.0, 1.0, 10.0, 1.0], np.array([1.0, 1.0, 10.0, 1.0]))  # column 2 in other units
    assert dict(scaled.combinations[2]) == pytest.approx({0: -0.1, 1: -0.2})
