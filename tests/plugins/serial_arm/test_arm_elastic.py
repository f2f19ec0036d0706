"""Joint elasticity under gravity (kinematics.compliances): the gravity torques are the gradient of the potential
energy (through a coupling, with a payload) and their derivative is central differences; a simulated UR10 with
compliant joints (a self-consistency check: data made with the estimator's model and noise) has its compliances
recovered within their sigmas and held-out poses at the tracker's floor, where the rigid model fitted to the same
data is not; the exported URDF with its compliance file predicts the deflected pose the calibrated model does; a
compliance on a joint that carries no mass is refused."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.serial_arm.chain import Coupling, SerialChain

from arm_helpers import estimated_parameters, held_out_errors, layouts
from test_arm_couplings import torso_urdf

TRACKER, ENCODER = 1e-4, 1e-5


def potential_energy(chain: SerialChain, payload: tuple, q: np.ndarray) -> float:
    import pinocchio as pin
    model, data = chain._gravity_model(("urdf", chain.model.getFrameId(payload[0]), *payload[1:]) if payload
                                       else ("urdf",))  # the model the torques are computed on
    return float(pin.computePotentialEnergy(model, data, chain._configuration(q)))


@pytest.mark.parametrize("payload", [(), ("tool", 2.5, 0.0, 0.03, 0.02)])
def test_gravity_torques_are_minus_the_potential_energys_gradient_through_the_coupling(tmp_path, payload):
    """tau = -dU/dq (central differences of Pinocchio's potential energy, coupled joint at -(q_a + q_b)) to 1e-6 N m,
    and d tau / d q = central differences of tau to 1e-5."""
    chain = SerialChain.from_urdf(torso_urdf(tmp_path), "base", "tool", ["a", "b", "d"],
                                  (Coupling("c", (("a", -1.0), ("b", -1.0))),))
    q = np.array([0.3, -0.6, 0.9])
    tau, dtau = chain.gravity_torques(q[None], payload, True)
    h = 1e-6
    for i in range(3):
        step = np.eye(3)[i] * h
        dU = (potential_energy(chain, payload, q + step) - potential_energy(chain, payload, q - step)) / (2 * h)
        assert tau[0, i] == pytest.approx(-dU, abs=1e-6)  # the torque gravity exerts: minus the energy's gradient
        numeric = (chain.gravity_torques((q + step)[None], payload)[0] - chain.gravity_torques((q - step)[None],
                                                                                                payload)[0]) / (2 * h)
        assert dtau[0, :, i] == pytest.approx(numeric[0], abs=1e-5)
    assert np.abs(tau).max() > 0.5  # the torso's links weigh 1 kg each: torques of N m


@pytest.fixture(scope="module")
def elastic():
    """ur10_elastic, 60 static configurations, compliances drawn with sigma 5e-5 rad/(N m) (arm.sim's default)."""
    with simulated_config("arm.sim", {"description": "ur10_elastic", "configurations": 60}, seed=2) as config:
        return estimate(config)


def test_simulated_compliances_are_recovered_within_their_sigmas_and_predict_at_the_floor(elastic):
    """Measured (seed 2): the gravity-loaded joints' compliances (shoulder lift, elbow) within 4 sigma of the truth
    with sigmas below 1e-6 rad/(N m) (truths ~5e-5); the pan joint's (a vertical axis: no torque) held as moving
    nothing; 300 held-out poses at 1.2x the tracker's floor, where the same estimate without its compliances is off
    by more than 5x (measured 1.6 mm, 9.5x)."""
    run = elastic
    truth = run.truth.calibration["arm"]["compliance"]["values"]
    est = run.parameters["arm"]["compliance"]
    sigma = np.ravel(est.sigma)
    for j in (1, 2):
        assert sigma[j] < 1e-6 and abs(est.values[j] - truth[j]) < 4 * sigma[j]
    d = run.problem.diagnostics["arm: kinematic identifiability"]
    assert "compliance[shoulder_pan_joint]" in d["held"]
    assert "compliance[shoulder_pan_joint]: moves no measurement; held" in d["verdict"]
    pos, _ = held_out_errors(run, estimated_parameters(run), 300, TRACKER, ENCODER, seed=5)
    assert np.sqrt(np.mean(pos ** 2)) < 1.2 * np.sqrt(3) * TRACKER
    rigid = estimated_parameters(run)
    rigid.compliances = np.zeros_like(rigid.compliances)
    off, _ = held_out_errors(run, rigid, 300, TRACKER, ENCODER, seed=5)
    assert np.sqrt(np.mean(off ** 2)) > 5 * np.sqrt(3) * TRACKER


def test_the_compliance_file_beside_the_urdf_predicts_the_calibrated_deflected_pose(elastic, tmp_path):
    """robots/arm.urdf + robots/arm.compliance.yaml of the run: elastic.deflected_pose at encoder readings equals the
    calibrated model's marker pose to 10 um (measured 2 and 3.5 um: the export's torques use the calibrated link
    placements, the estimate's the nominal ones, a second-order difference), with and without a 5 kg payload; the payload moves the
    marker by more than 0.1 mm."""
    from fusionkit.report.outputs import calibrated_description
    from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses
    from fusionkit_plugins.serial_arm.elastic import deflected_pose
    from fusionkit_plugins.serial_arm.export import urdf_output
    run = elastic
    files = urdf_output("arm", calibrated_description(run, "arm"))
    for name, text in files.items():
        (tmp_path / name.split("/")[-1]).write_text(text)
    assert set(files) == {"robots/arm.urdf", "robots/arm.compliance.yaml"}
    chain, layout, _ = layouts(run.config)
    p = estimated_parameters(run)
    q = np.random.default_rng(8).uniform(-2.5, 2.5, (20, chain.n))
    expected = marker_poses(chain, layout, q, p).T
    got = deflected_pose(tmp_path / "arm.compliance.yaml", q)
    assert np.abs(got[:, :3, 3] - expected[:, :3, 3]).max() < 1e-5
    from dataclasses import replace
    load = ("tool0", 5.0, 0.0, 0.0, 0.05)
    heavy = marker_poses(chain, replace(layout, payload=load), q, p).T
    got_heavy = deflected_pose(tmp_path / "arm.compliance.yaml", q,
                               payload={"mass": 5.0, "center": [0, 0, 0.05], "frame": "tool0"})
    assert np.abs(got_heavy[:, :3, 3] - heavy[:, :3, 3]).max() < 1e-5
    assert np.linalg.norm(heavy[:, :3, 3] - expected[:, :3, 3], axis=1).max() > 1e-4


def test_a_compliance_on_a_joint_carrying_no_mass_is_refused(tmp_path, workspace, capfd):
    from fusionkit.api import robot_description_data
    from fusionkit.cli.main import main
    (tmp_path / "massless.urdf").write_text(torso_urdf(tmp_path).read_text().replace(
        '<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>', ""))
    desc = {"name": "massless", "model": "serial_arm", "urdf": str(tmp_path / "massless.urdf"), "base_frame": "base",
            "tool_frame": "tool", "joints": ["a", "b", "c", "d"],
            "kinematics": {"compliances": [{"parameter": "k", "joints": ["b"]}]},
            "parameters": {"k": {"type": "scalar", "values": [0.0], "sigma": 1e-4}}}
    config = {"name": "m", "robots": {"arm": {"description": desc, "states": {"stream": "joints", "type": "vector4",
                                                                             "family": "joints"}}},
              "sources": [{"type": "csv", "name": "joints", "path": str(tmp_path / "j.csv")}],
              "factors": [{"type": "arm.joint_encoders", "robot": "arm", "stream": "joints", "sigma": 1e-5}]}
    (tmp_path / "j.csv").write_text("t,a,b,c,d\n0,0,0,0,0\n")
    path = workspace.config(config)
    assert main(["validate", str(path)]) == 2
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "kinematics.compliances[0].joints: joint 'b' carries no mass in the URDF" in err
    assert robot_description_data("ur10_elastic")["kinematics"]["compliances"]


def test_lumped_masses_at_the_urdf_centres_of_mass_with_products_c_m_reproduce_the_compliance_model():
    """Gravity torques depend on each link's mass and centre of mass only: unit masses at every link's URDF centre of
    mass, with products P_ji = c_j m_i, deflect the UR10 exactly as compliances c_j with the URDF's inertials (to
    1e-12 m), Jacobian blocks included (the product's block is the compliance's split by link)."""
    from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses
    from fusionkit_plugins.serial_arm.factors import UR_JOINTS
    from fusionkit_plugins.serial_arm.kinematics import Layout, Parameters
    from fusionkit_plugins.serial_arm.model import chain_from
    from fusionkit_plugins.serial_arm.urdf import PREFIX, urdf_path
    from pathlib import Path
    chain = chain_from(urdf_path(PREFIX + "ur10", Path(".")), "base_link", "tool0", UR_JOINTS)
    model = chain.model
    import pinocchio as pin
    lumped, masses = [], []
    for jid in range(1, model.njoints):  # each joint's inertia (its links merged) as a point mass at its COM
        frame = next(f for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == jid)
        lumped.append((frame.name, *frame.placement.actInv(model.inertias[jid].lever)))
        masses.append(model.inertias[jid].mass)
    assert len(masses) == 6 and min(masses) > 0
    c = np.array([0.0, 3e-5, 6e-5, 1e-4, 2e-4, 0.0])
    q = np.random.default_rng(3).uniform(-2.5, 2.5, (25, 6))
    elastic = marker_poses(chain, Layout(compliances=tuple(range(6))), q, Parameters(compliances=c), True)
    lumped_layout = Layout(mass_compliances=tuple(range(6)), lumped=tuple(lumped))
    products = [c[j] * np.array(masses) for j in range(6)]
    by_mass = marker_poses(chain, lumped_layout, q, Parameters(mass_compliances=products), True)
    assert np.abs(by_mass.T - elastic.T).max() < 1e-12
    assert np.abs(by_mass.blocks[0] - elastic.blocks[0]).max() < 1e-12  # the joints' Jacobian
    for j in range(6):  # d/dc_j = sum_i m_i d/dP_ji
        assert np.abs(by_mass.blocks[1 + j] @ np.array(masses) - elastic.blocks[1 + j][:, :, 0]).max() < 1e-9


def test_products_of_compliance_and_lumped_masses_are_calibrated_and_reported_as_identifiable_or_held(tmp_path):
    """A URDF without (trusted) inertials: the simulated ur10_elastic (compliances with the URDF's inertials)
    calibrated with lumped masses at three links instead (self-consistency of the physics, not of the parameters):
    held-out poses at 1.2x the tracker's floor, the identifiability report holds the products that move nothing
    (the shoulder pan's: gravity never turns a vertical axis) and estimates the others, and the exported URDF with
    its compliance file predicts what the fit does (to 10 um)."""
    import yaml
    from fusionkit.config.loader import load_config
    from fusionkit.simulate import write_dataset
    write_dataset("arm.sim", tmp_path, ["description=ur10_elastic", "configurations=60"], seed=2)
    desc_path = tmp_path / "robots" / "arm.yaml"
    desc = yaml.safe_load(desc_path.read_text())
    joints = desc["joints"]
    kin = desc["kinematics"]
    kin.pop("compliances")
    kin["lumped_masses"] = ["forearm_link", "wrist_1_link", {"link": "wrist_3_link", "center": [0.0, 0.0, 0.0]}]
    kin["mass_compliances"] = [{"parameter": "mass_compliance", "joints": joints[:3]}]
    desc["parameters"].pop("compliance")
    desc["parameters"]["mass_compliance"] = {"type": "vector3", "values": [[0.0] * 3] * 3, "sigma": 0.01}
    desc_path.write_text(yaml.safe_dump(desc, sort_keys=False))
    run = estimate(load_config(tmp_path / "config.yaml"))
    d = run.problem.diagnostics["arm: kinematic identifiability"]
    held = set(d["held"])
    assert {f"mass_compliance[shoulder_pan_joint].{m}" for m in ("forearm_link", "wrist_1_link", "wrist_3_link")} <= held
    assert "mass_compliance[shoulder_lift_joint].forearm_link" in d["sigma_from_data"]
    assert run.solution.chi2_per_dof < 1.5
    from fusionkit.api import load_robot_description
    from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses
    from fusionkit_plugins.serial_arm.factors import entry_layout
    from fusionkit_plugins.serial_arm.kinematics import parameters_of
    from fusionkit_plugins.serial_arm.model import arm_of
    from arm_helpers import typed
    truth = yaml.safe_load((tmp_path / "truth" / "calibration.yaml").read_text())["robots"]["arm"]
    true_arm = arm_of(load_robot_description("ur10_elastic"))
    true_layout, true_vars = entry_layout(true_arm, {}, "pose3")
    fitted_arm = arm_of(run.config.robots["arm"].description)
    fitted_layout, fitted_vars = entry_layout(fitted_arm, {}, "pose3")
    q = np.random.default_rng(4).uniform(-np.pi, np.pi, (300, 6))
    measured = marker_poses(true_arm.chain, true_layout, q, parameters_of(
        true_layout, [typed(truth[n], i) for n, i in true_vars])).T[:, :3, 3] + np.random.default_rng(5).normal(
        0, TRACKER, (300, 3))
    predicted = marker_poses(fitted_arm.chain, fitted_layout, q, parameters_of(
        fitted_layout, [run.parameters["arm"][n].values[i or 0] for n, i in fitted_vars])).T[:, :3, 3]
    rms = np.sqrt(np.mean(np.sum((predicted - measured) ** 2, axis=1)))
    assert rms < 1.2 * np.sqrt(3) * TRACKER
    from fusionkit.report.outputs import calibrated_description
    from fusionkit_plugins.serial_arm.elastic import deflected_pose
    from fusionkit_plugins.serial_arm.export import urdf_output
    for name, text in urdf_output("arm", calibrated_description(run, "arm")).items():
        (tmp_path / name.split("/")[-1]).write_text(text)
    exported = deflected_pose(tmp_path / "arm.compliance.yaml", q)[:, :3, 3]
    assert np.abs(exported - predicted).max() < 1e-5  # the export's torques at calibrated link placements


def test_a_positive_compliance_lets_the_outstretched_arm_sag():
    """The UR10 stretched out horizontally (shoulder lift -pi/2 in its URDF convention is up; 0 is horizontal): a
    positive shoulder-lift compliance lowers the flange, by compliance x torque x reach (measured 1.4 mm for
    1e-5 rad/(N m))."""
    from pathlib import Path
    from fusionkit_plugins.serial_arm.vectorized_kinematics import marker_poses
    from fusionkit_plugins.serial_arm.factors import UR_JOINTS
    from fusionkit_plugins.serial_arm.kinematics import Layout, Parameters
    from fusionkit_plugins.serial_arm.model import chain_from
    from fusionkit_plugins.serial_arm.urdf import PREFIX, urdf_path
    chain = chain_from(urdf_path(PREFIX + "ur10", Path(".")), "base_link", "tool0", UR_JOINTS)
    q = np.zeros((1, 6))
    rigid = marker_poses(chain, Layout(), q, Parameters()).T[0, :3, 3]
    sagging = marker_poses(chain, Layout(compliances=(1,)), q, Parameters(compliances=np.array([1e-5]))).T[0, :3, 3]
    assert abs(rigid[2] - 0.0) < 0.2 and np.linalg.norm(rigid[:2]) > 1.0  # outstretched
    assert -2e-3 < sagging[2] - rigid[2] < -5e-4
