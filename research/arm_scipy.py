"""The obvious scipy baseline of a serial arm's kinematic calibration (what FIGAROH and most scripts do):
`scipy.optimize.least_squares` over Pinocchio's forward kinematics, the joints at their readings, the
Jacobian by finite differences (scipy's default `2-point`).

Same model, parameters, priors and data as fusionkit's graph (docs/models/serial_arm.md): the marker pose
T = B F(q + dq; delta) M with the residual Log(z^-1 T) (GTSAM's order [rotation, translation]) divided by
the tracker's sigmas; a Gaussian prior on each parameter with one (a pose: Log(prior^-1 X)); the axes the
identifiability analysis holds are left at their values (fusionkit holds them with a 1e-9 prior). The
unknowns are tangent steps from the start values: X = X0 Exp(d) for poses, x0 + d otherwise. Pinocchio
only: no fusionkit code runs inside the residual.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import gtsam
import numpy as np
import pinocchio as pin
from scipy.optimize import least_squares

from fusionkit.threads import one_blas_thread


@dataclass
class Variable:
    """One kinematic parameter: its role ("base", "tool", "offset", "placement"), joint (offsets and
    placements; an index into the chain's joint list), axes (placements: tangent axes in GTSAM order),
    start value (a 4x4 pose, a float or a vector), prior value and sigma per axis (None: no prior), and
    which of its axes are free (False: held at the start value)."""

    role: str
    start: object
    prior: object = None
    sigma: np.ndarray | None = None
    joint: int = -1
    axes: tuple[int, ...] = ()
    free: np.ndarray | None = None

    @property
    def width(self) -> int:
        return 6 if self.role in ("base", "tool") else 1 if self.role == "offset" else len(self.axes)


def _exp(d: np.ndarray) -> np.ndarray:
    """Exp of a GTSAM-order twist [rotation, translation] as a 4x4 pose (Pinocchio's exp6)."""
    return pin.exp6(pin.Motion(np.asarray(d[3:], float), np.asarray(d[:3], float))).homogeneous


def _log(T: np.ndarray) -> np.ndarray:
    """Log of a 4x4 pose as a GTSAM-order twist (Pinocchio's log6)."""
    m = pin.log6(pin.SE3(T[:3, :3].copy(), T[:3, 3].copy()))
    return np.concatenate([m.angular, m.linear])


class ScipyCalibration:
    """Kinematic calibration by scipy least squares: `model` the reduced Pinocchio model of the arm (its
    configuration: one value per listed joint), `joint_ids` the listed joints' ids, `tool_id` the flange
    frame, `base_T_universe` (4x4) the base frame, `variables` in the order of the unknowns, `q` (N, n)
    joint readings, `measured` (N, 4, 4) marker poses, `sigma` (6,) the tracker's [rotation x3, translation x3]."""

    def __init__(self, model: pin.Model, joint_ids: list[int], tool_id: int, base_T_universe: np.ndarray,
                 variables: list[Variable], q: np.ndarray, measured: np.ndarray, sigma: np.ndarray):
        assert model.nq == model.nv, "revolute and prismatic joints only"
        self.model = pin.Model(model)
        self.data = self.model.createData()
        self.joint_ids, self.tool_id, self.base_T_universe = joint_ids, tool_id, base_T_universe
        self.idx_q = [self.model.joints[j].idx_q for j in joint_ids]
        self.nominal = {j: self.model.jointPlacements[j].copy() for j in joint_ids}
        self.variables, self.q = variables, np.asarray(q, float)
        self.measured_inv = np.linalg.inv(measured)
        self.sigma = np.asarray(sigma, float)
        self.free = np.concatenate([v.free if v.free is not None else np.ones(v.width, bool) for v in variables])
        self.evaluations = 0

    def values(self, x: np.ndarray) -> list:
        """Each variable's value at the unknowns x (tangent steps of the free axes)."""
        d = np.zeros(len(self.free))
        d[self.free] = x
        out, c = [], 0
        for v in self.variables:
            step = d[c:c + v.width]
            c += v.width
            out.append(v.start @ _exp(step) if v.role in ("base", "tool") else v.start + (step[0] if v.role == "offset"
                                                                                          else step))
        return out

    def marker_poses(self, values: list, q: np.ndarray) -> np.ndarray:
        """B F(q + dq; delta) M for each row of q, by Pinocchio."""
        B, M, dq = np.eye(4), np.eye(4), np.zeros(len(self.joint_ids))
        placements = {}
        for v, value in zip(self.variables, values):
            if v.role == "base":
                B = value
            elif v.role == "tool":
                M = value
            elif v.role == "offset":
                dq[v.joint] += value
            else:
                full = placements.setdefault(v.joint, np.zeros(6))
                full[list(v.axes)] += value
        for j, jid in enumerate(self.joint_ids):
            P = self.nominal[jid]
            self.model.jointPlacements[jid] = P * pin.SE3(_exp(placements[j])) if j in placements else P
        config = np.zeros(self.model.nq)
        out = np.empty((len(q), 4, 4))
        for i, qi in enumerate(q + dq):
            config[self.idx_q] = qi
            pin.forwardKinematics(self.model, self.data, config)
            flange = pin.updateFramePlacement(self.model, self.data, self.tool_id).homogeneous
            out[i] = B @ self.base_T_universe @ flange @ M
        return out

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """The whitened residuals at the unknowns x: the marker poses, then the priors."""
        self.evaluations += 1
        return self.residuals_at(self.values(x))

    def residuals_at(self, values: list) -> np.ndarray:
        """The whitened residuals at the variables' `values` (as `values(x)` returns them)."""
        T = self.marker_poses(values, self.q)
        out = [np.concatenate([_log(zi @ Ti) for zi, Ti in zip(self.measured_inv, T)]) / np.tile(self.sigma, len(T))]
        for v, value in zip(self.variables, values):
            if v.sigma is None:
                continue
            e = _log(np.linalg.inv(v.prior) @ value) if v.role in ("base", "tool") else np.atleast_1d(value - v.prior)
            out.append(e / v.sigma)
        return np.concatenate(out)

    def solve(self, **options) -> "ScipyResult":
        """least_squares from the start values (scipy's defaults unless `options` say otherwise), with one BLAS
        thread as fusionkit's estimate() has (numpy's threads only wait for a busy core on 2-4 cores)."""
        self.evaluations = 0
        with one_blas_thread():
            tic = time.perf_counter()
            res = least_squares(self.residuals, np.zeros(int(self.free.sum())), **options)
            seconds = time.perf_counter() - tic
        return ScipyResult(self.values(res.x), float(res.cost), int(res.nfev), self.evaluations, seconds, res)


@dataclass
class ScipyResult:
    values: list
    cost: float          # 0.5 * sum of squared whitened residuals: GTSAM's graph error without the encoders
    nfev: int
    evaluations: int     # residual evaluations, the finite-difference Jacobians' included
    seconds: float
    raw: object


def pose_of(value) -> np.ndarray:
    """A gtsam.Pose3 or a 4x4 matrix as a 4x4 matrix."""
    return value.matrix() if isinstance(value, gtsam.Pose3) else np.asarray(value, float)
