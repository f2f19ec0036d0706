"""`cable.sag_forces`: initial reference-cable forces and orientation corrections of every
static pose from the current pose and pulley guesses.

By default each pose is put in equilibrium: the static simulator solves the inverse problem at the
pose's position and yaw with the guessed pulleys (static_solver.inverse_pose), so the initial
forces and orientation satisfy the statics and the attachment heights (eq. 5.13) exactly, and only
the lengths disagree while the pulleys and offsets are wrong. Where that has no solution (a cable
would be slack with the guessed pulleys), or with `equilibrium: false`, thesis eqs. 5.15-5.17:

    V0 = m g / 4,   H0 = V0 / tan(alpha),   alpha = elevation of the reference cable's chord,

with the orientation correction at identity. Place it after the initializers that set the poses
(e.g. pose.interpolate) and the pulleys (the description's nominal values, or
cable.multilateration: the rigid model's pulleys).
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import ROT3, Initializer, Spec

from .model import CORRECTION, FORCE, REFERENCE, cable_count, check_sag_robot, sag_robot
from .static_solver import StaticsError, initial_reference_force, inverse_pose


class SagForces(Initializer):
    name = "cable.sag_forces"
    summary = ("initial reference-cable forces and orientation corrections at every static pose: the pose in "
               "equilibrium with the guessed pulleys (fallback: V = m g / 4, H = V / tan(alpha))")
    robot_fields = ("robot",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "reference": REFERENCE,
                             "equilibrium": {"type": "boolean", "default": True}},
              "required": ["robot"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_sag_robot(spec, scope, cable_count(spec, scope))
        scope.require_states(spec, "robot", "pose3")

    def initialize(self, ctx, spec: Spec) -> None:
        name = spec["robot"]
        robot = sag_robot(ctx.robot(name), spec["reference"])
        forces, corrections = ctx.family(name, FORCE), ctx.family(name, CORRECTION)
        if forces is None:
            raise spec.error("robot", f"no cable.sag factor on robot {name!r}: there are no forces to initialize")
        pulleys = np.array([ctx.initial_value(ctx.parameter(name, "pulley", i)) for i in range(robot.n)])
        fallback = 0
        for k in range(len(ctx.state_set(name, spec))):
            has_force, has_correction = ctx.has_variable(forces.key(k)), ctx.has_variable(corrections.key(k))
            if not (has_force or has_correction):
                continue  # no static pose here (the force sensor's and the lengths' samples may pick other states)
            X = ctx.initial_value(ctx.pose_key(name, k))
            R, t = X.rotation().matrix(), np.asarray(X.translation())
            f0, dR = initial_reference_force(R, t, pulleys, robot), ROT3.zero()
            if spec["equilibrium"]:
                try:
                    pose = inverse_pose(t, pulleys, robot, yaw=float(np.arctan2(R[1, 0], R[0, 0])))
                    f0, dR = pose.f_ref, gtsam.Rot3(R.T @ pose.R)
                except StaticsError:
                    fallback += 1
            if has_force:
                ctx.set_initial(forces.key(k), f0)
            if has_correction:
                ctx.set_initial(corrections.key(k), dR)
        if fallback:
            ctx.note(f"{spec.label}: {fallback} pose(s) have no equilibrium with the guessed pulleys; "
                             "their forces start from V = m g / 4, H = V / tan(alpha) "
                             "(docs/models/cable_sag.md#initial-forces)")


INITIALIZERS = [SagForces]
