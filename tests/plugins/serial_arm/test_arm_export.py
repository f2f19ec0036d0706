"""The calibrated arm as a URDF: Pinocchio reloads the exported file to the forward kinematics of the
calibrated parameters -- the marker in `measurement_frame` at the encoder readings equals
batch.marker_poses / kinematics.marker_pose to 1e-9 -- for the UR10 with every kind of parameter and for
a small arm with a prismatic joint, an unaligned axis and link names already taken; `fusionkit run`
writes it (robots/<robot>.urdf), and on a real UR10 recording it puts the marker at the recorded poses
with the calibration's own error."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import gtsam
import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

from fusionkit.api import load_robot_description
from fusionkit.cli.main import main
from fusionkit.config.loader import load_config
from fusionkit.report.outputs import calibrated_description
from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses
from fusionkit_plugins.serial_arm.export import urdf_output
from fusionkit_plugins.serial_arm.kinematics import marker_pose

from arm_helpers import layouts, nominal_parameters
from research import ur10_figaroh
from research.external_data import external_data, missing_reason

REPO_CONFIG = str(Path(__file__).resolve().parents[3] / "configs" / "arm_calibration.yaml")

SMALL_URDF = """<?xml version="1.0"?>
<robot name="small">
  <!-- a revolute joint about an unaligned axis, a prismatic one, a fixed flange; "marker" is taken -->
  <link name="base"/><link name="l1"/><link name="l2"/><link name="flange"/><link name="marker"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.2" rpy="0.1 0 0"/>
    <axis xyz="0.6 0 0.8"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1"/><child link="l2"/><origin xyz="0.5 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-0.3" upper="0.3" effort="1" velocity="1"/></joint>
  <joint name="flange_joint" type="fixed"><parent link="l2"/><child link="flange"/><origin xyz="0.1 0 0"/></joint>
  <joint name="other" type="fixed"><parent link="flange"/><child link="marker"/></joint>
</robot>
"""

SMALL_DESCRIPTION = """name: small
model: serial_arm
urdf: small.urdf
base_frame: base
tool_frame: flange_joint
joints: [j1, j2]
kinematics:
  tool: reflector
  joint_offsets: [{parameter: offsets, joints: [j1, j2]}]
  placements: [{parameter: placement, joints: [j2], axes: [tx, rz, ry]}]
parameters:
  reflector: {type: point3, value: [0.02, 0.0, 0.05], sigma: 0.01}
  offsets: {type: scalar, values: [0.0, 0.0], sigma: 0.01}
  placement: {type: vector3, values: [[0.0, 0.0, 0.0]], sigma: 0.01}
"""


def perturbed(desc, rng: np.random.Generator, size: float = 0.05):
    """The description with every kinematic parameter moved by a random amount (what a calibration gives)."""
    def move(param):
        values = []
        for v in param.values:
            if isinstance(v, gtsam.Pose3):
                values.append(v.compose(gtsam.Pose3.Expmap(rng.normal(0.0, size, 6))))
            elif np.ndim(v) == 0:
                values.append(float(v) + rng.normal(0.0, size))
            else:
                values.append(np.asarray(v, float) + rng.normal(0.0, size, len(v)))
        return replace(param, values=values)
    return replace(desc, parameters={name: move(p) for name, p in desc.parameters.items()})


def urdf_marker_poses(text: str, joints: list[str], q: np.ndarray, measurement: str = "measurement_frame",
                      marker: str = "marker") -> np.ndarray:
    """The marker in the measurement frame by Pinocchio on the exported URDF, joints at q (others neutral)."""
    model = pin.buildModelFromXML(text)
    data = model.createData()
    out = []
    for row in q:
        config = pin.neutral(model)
        for name, value in zip(joints, row):
            config[model.joints[model.getJointId(name)].idx_q] = value
        pin.framesForwardKinematics(model, data, config)
        out.append((data.oMf[model.getFrameId(measurement)].inverse() * data.oMf[model.getFrameId(marker)]).homogeneous)
    return np.array(out)


class Described:
    """A description's layout helpers without a config (arm_helpers.layouts wants config.robots)."""

    def __init__(self, desc):
        self.robots = {"arm": type("Setup", (), {"description": desc})()}


def test_the_exported_ur10_reloads_to_the_calibrated_marker_pose_at_the_encoder_readings():
    """Base, marker pose, six offsets and six 6-D placement errors, all moved by ~0.05: Pinocchio's FK of the
    exported file equals the calibrated model (batched and per sample) to 1e-9 at 20 random readings."""
    rng = np.random.default_rng(3)
    calibrated = perturbed(load_robot_description("ur10_tracker"), rng)
    text = urdf_output("arm", calibrated)["robots/arm.urdf"]
    chain, layout, _ = layouts(Described(calibrated))
    p = nominal_parameters(Described(calibrated))
    q = rng.uniform(-3.0, 3.0, (20, chain.n))
    exported = urdf_marker_poses(text, chain.joint_names, q)
    np.testing.assert_allclose(exported, marker_poses(chain, layout, q, p).T, atol=1e-9)
    np.testing.assert_allclose(exported[0], marker_pose(chain, layout, q[0], p)[0], atol=1e-9)
    assert "the joint value is the encoder reading" in text and "xacro" in text  # the note; the file's own comments


def test_a_prismatic_joint_an_unaligned_axis_and_a_taken_link_name_export_exactly(tmp_path):
    """Offsets of a revolute (axis 0.6 0 0.8) and a prismatic joint, a 3-axis placement error, a point marker
    on a tool frame given by a fixed joint's name, no base: the marker link is `marker_1` (the URDF has a
    `marker`), the measurement frame is the root's, and the FK matches to 1e-9."""
    (tmp_path / "small.urdf").write_text(SMALL_URDF)
    (tmp_path / "small.yaml").write_text(SMALL_DESCRIPTION)
    rng = np.random.default_rng(4)
    calibrated = perturbed(load_robot_description(tmp_path / "small.yaml"), rng)
    text = urdf_output("small", calibrated)["robots/small.urdf"]
    chain, layout, _ = layouts(Described(calibrated))
    p = nominal_parameters(Described(calibrated))
    q = np.column_stack([rng.uniform(-3, 3, 10), rng.uniform(-0.3, 0.3, 10)])
    exported = urdf_marker_poses(text, chain.joint_names, q, marker="marker_1")
    np.testing.assert_allclose(exported, marker_poses(chain, layout, q, p).T, atol=1e-9)
    assert "Added: link measurement_frame (the measurement frame, parent of base) and link marker_1 (on flange)" in text


def test_fusionkit_run_writes_the_calibrated_urdf_of_its_estimates(tmp_path, capsys):
    """`fusionkit run` on 15 simulated UR10 configurations writes robots/arm.urdf; reloaded, it gives the
    marker poses of the estimates in calibration.yaml (loaded back as description overrides) to 1e-9."""
    out = tmp_path / "out"
    assert main(["run", REPO_CONFIG, "--out", str(out), "--no-plots", "-q",
                 "--set", "sources.0.params.configurations=15"]) == 0
    assert "robots/" in capsys.readouterr().out
    config = load_config(REPO_CONFIG, [f"robots.arm.overrides={out / 'calibration.yaml'}"])
    chain, layout, _ = layouts(config)
    calibrated = nominal_parameters(config)
    assert np.abs(calibrated.offsets).max() > 1e-4  # the estimates, not the description's zeros
    q = np.random.default_rng(5).uniform(-3.0, 3.0, (10, chain.n))
    exported = urdf_marker_poses((out / "robots" / "arm.urdf").read_text(), chain.joint_names, q)
    np.testing.assert_allclose(exported, marker_poses(chain, layout, q, calibrated).T, atol=1e-9)


def test_a_time_varying_offset_is_exported_at_its_last_estimated_value_and_named_in_the_note():
    """The run's estimates of a drifting offset (one value per state) reach the robot model as their last
    value (report.outputs.calibrated_description): the exported FK uses it, and the file says so."""
    desc = load_robot_description("ur10_tracker")
    drifting = replace(desc, parameters={**desc.parameters,
                                         "joint_offsets": replace(desc.parameters["joint_offsets"], time_varying=True)})
    series = {f"joint_offsets[{i}]": SimpleNamespace(values=[0.0, 0.001 * i, 0.002 * (i + 1)], sigma=None)
              for i in range(6)}
    result = SimpleNamespace(config=SimpleNamespace(robots={"arm": SimpleNamespace(description=drifting)}),
                             parameters={"arm": series})
    calibrated = calibrated_description(result, "arm")
    assert calibrated.parameters["joint_offsets"].values == [0.002 * (i + 1) for i in range(6)]
    text = urdf_output("arm", calibrated)["robots/arm.urdf"]
    assert "Time-varying parameters at their last estimated value: joint_offsets." in text
    chain, layout, _ = layouts(Described(calibrated))
    q = np.random.default_rng(6).uniform(-3.0, 3.0, (5, chain.n))
    np.testing.assert_allclose(urdf_marker_poses(text, chain.joint_names, q),
                               marker_poses(chain, layout, q, nominal_parameters(Described(calibrated))).T, atol=1e-9)


@pytest.mark.skipif(not external_data(ur10_figaroh.DATASET).is_dir(),
                    reason=missing_reason(ur10_figaroh.DATASET, "FIGAROH's UR10 recording"))
def test_the_urdf_run_writes_for_the_real_ur10_puts_the_marker_at_its_23_recorded_poses(tmp_path, capsys):
    """FIGAROH's real UR10 recording (configs/arm_ur10_real.yaml): Pinocchio places `marker` in
    `measurement_frame` of the exported URDF at the recorded poses with 2.97 mm / 0.345 deg RMSE at the
    encoder readings -- the calibration's own in-sample error (FIGAROH's full model: 2.98 mm / 0.337 deg)."""
    joints, tracker = ur10_figaroh.write_streams(tmp_path / "data")
    out = tmp_path / "out"
    assert main(["run", str(ur10_figaroh.CONFIG), *[f"--set={a}" for a in ur10_figaroh.overrides(joints, tracker)],
                 "--out", str(out), "--no-plots", "-q"]) == 0
    q, measured = ur10_figaroh.read_recording()
    exported = urdf_marker_poses((out / "robots" / "arm.urdf").read_text(), list(ur10_figaroh.JOINTS), q)
    position = np.linalg.norm(exported[:, :3, 3] - measured[:, :3, 3], axis=1)
    angle = Rotation.from_matrix(np.swapaxes(measured[:, :3, :3], 1, 2) @ exported[:, :3, :3]).magnitude()
    assert 2.9e-3 < np.sqrt(np.mean(position ** 2)) < 3.05e-3
    assert 0.33 < np.degrees(np.sqrt(np.mean(angle ** 2))) < 0.36
