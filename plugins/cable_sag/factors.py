"""Factor types of the sagging-cable plugin (docs/models/cable_sag.md; thesis fig. 5.2).

`cable.sag`, one factor per static pose k with the lengths of all four cables, residual (8,):

    e_len_i    = l_C_i[k] + l0_i - z_i[k]        (thesis eq. 5.12; l_C_i the catenary arc length 5.4)
    e_height_i = rise the catenary reaches - (a_i - p_b_i)_z    (eq. 5.13)

over the pose X_k, its orientation correction dR_k (the statics see R_k dR_k: an under-actuated
robot settles into its own orientation), the reference-cable forces F_k = (H_ref, V_ref), the four
pulleys a_i and the four offsets l0_i (z = length + l0, as `cable.length`). The other cables'
forces come from the statics (5.11), so every residual depends on every pulley.

`cable.reference_force`: e = ||F_k|| - f_m[k] (eq. 5.14), the force sensor on the reference cable.
"""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, POSITIVE_SCHEMA as SIGMA, ROT3, Spec, TOLERANCE_SCHEMA, gaussian,
                           parameter_indices, vector_type)

from .model import (CORRECTION, FORCE, REFERENCE, cable_count, check_sag_robot, length_columns, sag_robot,
                    shipped_robot)
from .static_solver import inverse_pose
from .statics import SagRobot, equilibrium

VECTOR2 = vector_type(2)


def sag_residual(robot: SagRobot, z: np.ndarray, X: gtsam.Pose3, dR: gtsam.Rot3, F: np.ndarray,
                 pulleys: np.ndarray, offsets: np.ndarray, H: list | None = None) -> np.ndarray:
    """[e_len (4), e_height (4)] (m); with H, fills the Jacobians w.r.t. X (8x6), dR (8x3),
    F (8x2), each pulley (8x3) and each offset (8x1)."""
    RX, Rd = X.rotation().matrix(), dR.matrix()
    eq = equilibrium(RX @ Rd, np.asarray(X.translation()), F, pulleys, robot, jacobian=H is not None)
    e = np.concatenate([eq.length + offsets - z, eq.height_error])
    if H is not None:
        n = robot.n
        J = np.vstack([eq.d_length, eq.d_height])         # (2n, dim): theta = [dR_eff, dt_world, F, a]
        # R_eff = R_X dR: a right perturbation w of X's rotation is dR^T w of R_eff; X's translation
        # perturbation v moves t by R_X v
        H[0] = np.hstack([J[:, 0:3] @ Rd.T, J[:, 3:6] @ RX])
        H[1] = J[:, 0:3]
        H[2] = J[:, 6:8]
        for i in range(n):
            H[3 + i] = J[:, 8 + 3 * i:11 + 3 * i]
            col = np.zeros((2 * n, 1))
            col[i] = 1.0
            H[3 + n + i] = col
    return e


def _sag_error(robot: SagRobot, z: np.ndarray, this, v: gtsam.Values, H) -> np.ndarray:
    k = this.keys()
    n = robot.n
    pulleys = np.array([v.atPoint3(k[3 + i]) for i in range(n)])
    offsets = np.array([v.atDouble(k[3 + n + i]) for i in range(n)])
    return sag_residual(robot, z, v.atPose3(k[0]), v.atRot3(k[1]), v.atVector(k[2]), pulleys, offsets, H)


def sag_factor(robot: SagRobot, z: np.ndarray, keys: list[int], noise) -> gtsam.CustomFactor:
    """keys: pose, correction, force, pulleys (n), offsets (n)."""
    return gtsam.CustomFactor(noise, keys, partial(_sag_error, robot, np.asarray(z, float)))


def _force_error(f_m: float, this, v: gtsam.Values, H) -> np.ndarray:
    F = v.atVector(this.keys()[0])
    norm = float(np.hypot(F[0], F[1]))
    if H is not None:
        H[0] = (F / norm).reshape(1, 2)
    return np.array([norm - f_m])


def reference_force_factor(key: int, f_m: float, noise) -> gtsam.CustomFactor:
    return gtsam.CustomFactor(noise, [key], partial(_force_error, float(f_m)))


class SagCable(FactorType):
    name = "cable.sag"
    summary = ("heavy sagging cables at static poses: catenary length + offset = encoder (thesis eq. 5.12) and the "
               "catenary reaches the attachment height (5.13), forces through the reference cable (5.11)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"}, "sigma": SIGMA,
                             "height_sigma": SIGMA, "reference": REFERENCE,  # height_sigma: `sigma` if absent
                             "orientation_sigma": SIGMA,
                             "columns": {"type": "array", "items": {"type": "string"}},
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def separation_hint(self, spec: Spec, parameters: list[str]) -> str | None:
        """A pulley and its cable's offset trade off as for straight cables, more so with few static poses."""
        if parameter_indices(parameters, spec["robot"], "pulley") & parameter_indices(parameters, spec["robot"], "offset"):
            return ("to separate a pulley from its cable's offset: more static poses, spread over the workspace "
                    "(the cable's direction at the pulley must vary)")
        return None

    def check(self, spec: Spec, scope) -> None:
        n = cable_count(spec, scope)
        check_sag_robot(spec, scope, n)
        scope.require_states(spec, "robot", "pose3")
        scope.require_columns(spec, "stream", tuple(length_columns(spec, n)))

    def build(self, ctx, spec: Spec) -> None:
        robot_name = spec["robot"]
        robot = sag_robot(ctx.robot(robot_name), spec["reference"])
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot_name, spec)
        sigma = float(spec["sigma"])
        noise = ctx.noise([sigma] * robot.n + [float(spec.get("height_sigma", sigma))] * robot.n, spec)
        z_all = np.column_stack([stream.column(c) for c in length_columns(spec, robot.n)])
        pulleys = [ctx.parameter(robot_name, "pulley", i) for i in range(robot.n)]
        offsets = [ctx.parameter(robot_name, "offset", i) for i in range(robot.n)]
        tilt = gaussian([float(spec["orientation_sigma"])] * 3) if "orientation_sigma" in spec.data else None
        for k, row in zip(assoc.state, assoc.row):
            k = int(k)
            keys = [ctx.pose_key(robot_name, k), ctx.state_variable(robot_name, CORRECTION, ROT3, k),
                    ctx.state_variable(robot_name, FORCE, VECTOR2, k), *pulleys, *offsets]
            ctx.add(sag_factor(robot, z_all[row], keys, noise), spec, ctx.state_time(robot_name, k))
            if tilt is not None:  # the measured orientation enters: the statics' own turn dR_k held near identity
                ctx.add(gtsam.PriorFactorRot3(keys[1], gtsam.Rot3(), tilt), spec, ctx.state_time(robot_name, k),
                        part="orientation prior")

    @classmethod
    def example(cls, rng):
        robot, pulleys = shipped_robot("cdpr_large")
        pose = inverse_pose(rng.uniform([-20, -20, 0], [20, 20, 20]), pulleys, robot, yaw=rng.normal(0, 0.02))
        dR = gtsam.Rot3.Expmap(rng.normal(size=3) * 0.02)
        X = gtsam.Pose3(gtsam.Rot3(pose.R @ dR.matrix().T), pose.t)
        offsets = rng.normal(size=robot.n)
        values = gtsam.Values()
        values.insert(0, X)
        values.insert(1, dR)
        values.insert(2, pose.f_ref)
        for i in range(robot.n):
            values.insert(3 + i, pulleys[i])
            values.insert(3 + robot.n + i, float(offsets[i]))
        z = pose.state.length + offsets
        noise = gaussian([1.0] * 2 * robot.n)  # unit sigmas: central differences of metre-scale residuals stay exact
        # 3 degrees of tilt redistribute the forces of the 250 m robot enough to slacken a cable:
        # check the Jacobians a few milliradians (and millimetres, millinewtons) away instead
        return FactorExample(sag_factor(robot, z, list(range(3 + 2 * robot.n)), noise), values, perturbation=0.003)


class ReferenceForce(FactorType):
    name = "cable.reference_force"
    summary = "force sensor on the reference cable: ||(H_ref, V_ref)|| = f_m (thesis eq. 5.14)"
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "stream": {"type": "string"},
                             "column": {"type": "string", "default": "f"}, "sigma": SIGMA,
                             "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        cable_count(spec, scope)
        scope.require_states(spec, "robot", "pose3")
        scope.require_columns(spec, "stream", (spec["column"],))

    def build(self, ctx, spec: Spec) -> None:
        robot_name = spec["robot"]
        stream = ctx.stream(spec["stream"])
        assoc = ctx.associate(stream, robot_name, spec)
        f_m = stream.column(spec["column"])
        noise = ctx.noise([spec["sigma"]], spec)
        for k, row in zip(assoc.state, assoc.row):
            key = ctx.state_variable(robot_name, FORCE, VECTOR2, int(k))
            ctx.add(reference_force_factor(key, f_m[row], noise), spec, ctx.state_time(robot_name, int(k)))

    @classmethod
    def example(cls, rng):
        F = rng.uniform([100, 10], [800, 200])
        values = gtsam.Values()
        values.insert(0, F)
        return FactorExample(reference_force_factor(0, float(np.hypot(*F)), gaussian([1.0])), values)


FACTOR_TYPES = [SagCable, ReferenceForce]
