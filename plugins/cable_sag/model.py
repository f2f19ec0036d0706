"""What the sag plugin reads from a `cdpr` description: the statics parameters (SagRobot), and
the names of its per-pose variables."""

from __future__ import annotations

import numpy as np

from fusionkit.api import RobotDescription, Spec, cable_robot, robot_description_data

from .statics import N_CABLES, SagRobot

ROBOT_NAME = "cdpr"  # the robot's key in the configs, truth and robots/cdpr.yaml the simulator writes
CORRECTION = "orientation_correction"  # dR_k, rot3 per static pose
FORCE = "reference_force"              # (H_ref, V_ref) per static pose, N
REFERENCE = {"type": "integer", "minimum": 0, "default": 0}  # the reference cable's index (thesis eq. 5.11)


def cable_count(spec: Spec, scope) -> int:
    """The entry's robot must be a `cdpr` (the cable robot model); its number of cables."""
    return cable_robot(scope.require_model(spec, "robot", "cdpr")).n


def length_columns(spec: Spec, n: int) -> list[str]:
    """Stream columns of the cable lengths: `columns:` or l0 .. l{n-1}, as the rigid-cable factors read them."""
    return list(spec.get("columns") or [f"l{i}" for i in range(n)])


def sag_robot_from(extra: dict | RobotDescription, reference: int = 0) -> SagRobot:
    """The statics parameters of a `cdpr` description (its CableRobot; the weight from the mass with the
    description's own gravity: the weight it was given, exactly)."""
    robot = cable_robot(extra)
    return SagRobot(robot.attachments, robot.com, robot.gravity * float(robot.mass), float(robot.weight_per_length),
                    reference)


def sag_robot(desc: RobotDescription, reference: int = 0) -> SagRobot:
    return sag_robot_from(desc, reference)


def refuse_pulley_radius(spec: Spec, robot) -> None:
    """The sag models start each catenary at a fixed exit point (the pulley parameter): a description's
    cables.pulley_radius would be ignored, so it is refused at the entry's robot key."""
    if robot.pulley_radius > 0:
        raise spec.error("robot", f"robot {spec['robot']!r} has cables.pulley_radius {robot.pulley_radius:g} m: the "
                         "sag models start each catenary at a fixed exit point (the pulley parameter) and would ignore "
                         "the radius; remove it here, or use the rigid cable factors (cable.length), which model it")


def check_sag_robot(spec: Spec, scope, n: int) -> None:
    """Four cables, a cable weight, an end-effector mass, a valid reference cable."""
    robot = cable_robot(scope.robots[spec["robot"]])
    if n != N_CABLES:
        raise spec.error("robot", f"the sag statics solve for a 4-cable suspended robot; {spec['robot']!r} has {n}")
    if robot.weight_per_length is None:
        raise spec.error("robot", f"robot {spec['robot']!r} has no cables.weight_per_length (N/m) or "
                         "cables.mass_per_length (kg/m); sagging cables need it")
    if robot.mass is None:
        raise spec.error("robot", f"robot {spec['robot']!r} has no end_effector.mass (kg) or end_effector.weight "
                         "(N); the statics need it")
    refuse_pulley_radius(spec, robot)
    if spec["reference"] >= n:
        raise spec.error("reference", f"cable index {spec['reference']} out of range: the robot has cables 0..{n - 1}")


def shipped_robot(name: str, reference: int = 0) -> tuple[SagRobot, np.ndarray]:
    """(statics parameters, nominal pulleys (n, 3)) of the registered description `name`."""
    desc = robot_description_data(name)
    return sag_robot_from(desc, reference), np.asarray(desc["parameters"]["pulley"]["values"], float)
