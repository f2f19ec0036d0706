"""D-optimal static poses for calibrating a cable robot's pulleys and encoder offsets, chosen before any data are
taken (docs/models/cable_rigid.md#pose-selection).

Candidates: end-effector positions (level, the identity orientation) drawn uniformly in the box the simulator's
motion spans (the pulleys' footprint in x and y; from half the home height to a clearance below the pulleys), kept
where every cable is taut -- some tensions hold the weight, Sum_i T_i u_i = m g z, each at least MIN_TENSION of
the weight (non-negative least squares on the forces) -- or read from a file. At each pose the cables are measured
by their encoders (z_i = l_i(a_i, pose) + l0_i, sigma `encoder`) and the pose by motion capture (sigma per axis
of rotation and translation, GTSAM's body-frame tangent). The pose is a nuisance: the lengths' covariance at a pose
is C = encoder^2 I + J_x Sigma_x J_x^T, and the candidate's block is G = chol(C)^-1 J_theta, J_theta the lengths'
Jacobian on the pulleys (3 per cable) and offsets (1 per cable), by central differences of the cable model (a
pulley radius included), each column scaled by the parameter's prior sigma. fusionkit's D-optimal design
(fusionkit.api.d_optimal) then chooses the poses.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import gtsam
import numpy as np
from scipy.optimize import nnls

from fusionkit.api import Choice, d_optimal, prior_information

from .simulators import GRAVITY, Geometry, cables, home_position, nominal_geometry, workspace_extent

MIN_TENSION = 0.02  # of the weight: a candidate whose weakest cable would carry less is slack, not used
STEP = 1e-6  # m or rad: central-difference step of the cable model


@dataclass
class CableDesign:
    """The parameter axes (names, units, prior sigmas) of a cdpr description, its nominal geometry and offsets."""

    geometry: Geometry
    offsets: np.ndarray
    names: list[str]
    units: list[str]
    prior: np.ndarray

    @property
    def scale(self) -> np.ndarray:
        return np.where(np.isfinite(self.prior), self.prior, 1.0)


def _prior(param: dict, n: int, dim: int) -> np.ndarray:
    """(n, dim) prior sigmas of a description parameter's elements (inf: none)."""
    sigma = param.get("sigma")
    if sigma is None or param.get("fixed"):
        return np.full((n, dim), np.inf)
    return np.broadcast_to(np.asarray(sigma, float).reshape(-1, dim) if np.ndim(sigma) > 1 else
                           np.asarray(sigma, float), (n, dim)).astype(float)


def design_of(desc: dict) -> CableDesign:
    """The design of a cdpr description (its data, as robot_description_data gives it)."""
    geo = replace(nominal_geometry(desc), pulley_radius=float(desc["cables"].get("pulley_radius", 0.0) or 0.0))
    n = geo.n
    pulley, offset = desc["parameters"]["pulley"], desc["parameters"]["offset"]
    names = [f"pulley[{i}].{a}" for i in range(n) for a in "xyz"] + [f"offset[{i}]" for i in range(n)]
    prior = np.concatenate([_prior(pulley, n, 3).ravel(), _prior(offset, n, 1).ravel()])
    return CableDesign(geo, np.asarray(offset.get("values", [0.0] * n), float), names, ["m"] * len(names), prior)


def taut(design: CableDesign, positions: np.ndarray) -> np.ndarray:
    """Whether every cable is taut at each position (level end-effector): force balance by non-negative tensions,
    the weakest at least MIN_TENSION of the weight, the weight held to 1 %."""
    weight = design.geometry.mass * GRAVITY
    least = MIN_TENSION * weight
    _, u, _ = cables(positions, np.broadcast_to(np.eye(3), (len(positions), 3, 3)), design.geometry)
    out = np.zeros(len(positions), bool)
    for k, uk in enumerate(u):  # tensions T = least + T', T' >= 0 (the distribution need not be unique)
        _, residual = nnls(uk.T, np.array([0.0, 0.0, weight]) - least * uk.sum(axis=0))
        out[k] = residual < 0.01 * weight
    return out


def random_candidates(desc: dict, design: CableDesign, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 3) taut positions drawn uniformly in the simulator's workspace box (module docstring)."""
    home = home_position(desc)
    plus, minus = workspace_extent(desc, home)
    out: list[np.ndarray] = []
    for _ in range(100):
        draw = home + rng.uniform(-minus, plus, (4 * count, 3))
        out += list(draw[taut(design, draw)])
        if len(out) >= count:
            return np.array(out[:count])
    raise ValueError(f"fewer than {count} taut positions in the workspace box after 100 draws")


def _lengths(geo: Geometry, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    return cables(positions, rotations, geo)[0]


def candidate_blocks(design: CableDesign, positions: np.ndarray, encoder: float, mocap: dict) -> np.ndarray:
    """(M, n, 4n) whitened, scaled Jacobian blocks of the encoder readings at `positions` (module docstring)."""
    geo, M, n = design.geometry, len(positions), design.geometry.n
    eye = np.broadcast_to(np.eye(3), (M, 3, 3))
    J_theta = np.zeros((M, n, 4 * n))
    for i in range(n):
        for a in range(3):
            shift = np.zeros_like(geo.pulleys)
            shift[i, a] = STEP
            up, down = replace(geo, pulleys=geo.pulleys + shift), replace(geo, pulleys=geo.pulleys - shift)
            J_theta[:, :, 3 * i + a] = (_lengths(up, positions, eye) - _lengths(down, positions, eye)) / (2 * STEP)
        J_theta[:, i, 3 * n + i] = 1.0
    J_x = np.zeros((M, n, 6))  # GTSAM Pose3 tangent: rotation (body), translation (body)
    for j in range(6):
        xi = np.zeros(6)
        xi[j] = STEP
        plus, minus = (gtsam.Pose3.Expmap(s * xi) for s in (1.0, -1.0))
        J_x[:, :, j] = (_lengths(geo, positions + plus.translation(), eye @ plus.rotation().matrix())
                        - _lengths(geo, positions + minus.translation(), eye @ minus.rotation().matrix())) / (2 * STEP)
    sigma_x = np.array([mocap["rotation"]] * 3 + [mocap["translation"]] * 3, float)
    C = encoder ** 2 * np.eye(n) + np.einsum("mij,j,mkj->mik", J_x, sigma_x ** 2, J_x)
    L = np.linalg.cholesky(C)
    return np.linalg.solve(L, J_theta) * design.scale


def select(design: CableDesign, positions: np.ndarray, count: int, encoder: float, mocap: dict) -> Choice:
    """The D-optimal `count` of the candidate positions."""
    blocks = candidate_blocks(design, positions, encoder, mocap)
    return d_optimal(blocks, prior_information(blocks, design.prior), design.scale, count)
