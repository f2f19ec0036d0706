"""Monte-Carlo self-calibration of a cable robot (spec cable_rigid.md, "Initialization"): pulleys
a_i, encoder offsets l0_i and the VO scale s from the encoder readings and the unscaled visual
odometry alone -- no prior values for the pulleys.

Model
-----
The end-effector pose at state k is X0 o (R_k, s t_k), (R_k, t_k) = VO_0^-1 VO_k at the state
times and X0 the initial value of the first pose (the user's zero pose, set by `pose.origin`).
The attachment point of cable i is linear in the scale, q_ik(s) = c_ik + s d_k, with
c_ik = X0 (R_k b_i) and d_k = R_X0 t_k computed once. Relative encoders are read against the first
sample: dz_ik = z_ik - z_i0, and the particle's encoder offset is l0_i = z_i0 - L0_i with L0_i the
cable length at the first pose, so

    r_ik = dz_ik + L0_i - |q_ik(s) - a_i|         (eq. 4.1 with l0 eliminated)

Each cable is a particle system over theta = (a_i, eps_i, s) with L0_i = |a_i - c_i0| + eps_i:
the parametrization puts the first pose's constraint (pulley on the sphere of radius L0 around the
first attachment point, within `initial_length_spread` of the nominal length) into the
coordinates, so sampling starts on that shell instead of the whole region.

Likelihood without per-pose work: sufficient statistics
-------------------------------------------------------
Squaring the cable equation gives the algebraic residual

    e_k = (dz_k + L0)^2 - |c_k + s d_k - a|^2 = phi_k . w(theta),
    phi_k = [dz^2 - |c|^2, dz, 1, c.d, |d|^2, c, d],  w = [1, 2L0, L0^2 - |a|^2, -2s, -s^2, 2a, 2sa]

with e_k = r_k (l_meas + l_pred) ~ 2 l_k r_k. Dividing phi_k by 2 l_k sigma_k (l_k = dz_k + L0
at the current estimate of L0, sigma_k the per-pose noise) makes e_k / (2 l_k sigma_k) the
whitened geometric residual to first order (relative error |r|/2l plus the L0 spread over l:
below 1e-3 near the posterior), and then

    chi2_n(theta) = sum_{k<n} (phi~_k . w)^2 = w^T G_n w,     G_n = sum_{k<n} phi~_k phi~_k^T (11 x 11)

The (particles x poses) residual array is summed analytically: evaluating all particles against
any prefix n of the trajectory costs one (11 x 11) @ (11 x P) product, independent of the number
of poses, and prefix Gram matrices are cumulative sums. That is what makes 750 poses x 5000
particles x 4 cables run in a fraction of a second; the exact geometric residual is evaluated
for the estimate (diagnostic `fit_rms_m`).

Sampler: sequential importance resampling over the data, tempered
------------------------------------------------------------------
Iterated batch importance sampling (Chopin 2002) with adaptive tempering inside each batch
(Del Moral, Doucet and Jasra 2006): the targets are the posteriors of growing prefixes of the
trajectory (batches of `batch` poses); when a batch is too informative for the current cloud the
likelihood increment is tempered in, exponent chosen by bisection so that the conditional
effective sample size stays at half the particles. When the ESS falls below half, the cloud is
resampled (systematic) and moved by random-walk Metropolis-Hastings steps (proposal: the weighted
particle covariance, step size adapted towards 25 % acceptance) that leave the current tempered
target invariant -- the "jitter" that keeps the cloud diverse without biasing it. Priors: uniform
over `region` (pulley), uniform L0 within +-`initial_length_spread` of the nominal length (from
the description's offsets), uniform `scale_range`.

The shared scale: each cable first estimates (a_i, L0_i, s) from its own data. With independent
priors the joint posterior's scale marginal is the product of the per-cable marginals (divided by
the flat prior), so the cables' scale beliefs (Gaussian fits) are multiplied into the combined
scale; then each cable's cloud is tempered towards its own likelihood times the message from the
other cables, N(s; mean_-i, var_-i), with the same resample-move steps: its pulley belief then
includes the scale uncertainty of the combined estimate (refinement with the scale held at the
combined belief, not at a point). Outputs: weighted means and covariances.

VO drift: treating the dead-reckoned VO as exact, its drift becomes a model error that grows along
the trajectory. With `vo_sigma` (per-frame rotation/translation noise, as in the
`pose.scaled_relative` factor) the per-pose noise is sigma_k^2 = sigma^2 + k sigma_t^2 +
sigma_r^2 sum_{j<k} |p_k - p_j|^2 (random walks of translation and heading, p the metric positions
at the mid-range scale). Drift errors are correlated in time, so the spreads stay somewhat
optimistic; the estimate only needs to land in the factor graph's basin.

Stages of the belief (plot): the boundaries come from the data, by the principal directions of the
motion covered so far. For every prefix of the trajectory the covariance of the VO displacements
gives principal spreads; an axis counts as covered once its spread exceeds `STAGE_FRACTION` (10 %)
of the largest spread of the whole trajectory (a scale-free threshold, well above VO drift). Stage
1 ends just before a second axis is covered (the first straight-line motion: a shell), stage 2
just before a third (a ring), stage 3 is the end (a cluster). A trajectory that never covers a
second or third axis has the missing stages at its end -- the diagnostic says so. Fractions of the
trajectory would misplace the stages whenever the motion plan differs from the assumed one.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import gtsam
import numpy as np

from fusionkit import Initializer, Spec
from fusionkit.data.association import interpolate_poses, nearest
from fusionkit.data.stream import POSE_COLUMNS

from .factors import check_cdpr, length_columns
from .model import cable_robot

NF = 11                  # lifted features of the squared cable equation
DIM = 5                  # particle state: a (3, relative to the first attachment point), eps, s
ESS_TARGET = float(os.environ.get("MC_ESS", 0.3))         # conditional ESS per tempering step, and resampling threshold (fraction of P)
MOVES = int(os.environ.get("MC_MOVES", 2))                # random-walk Metropolis-Hastings moves after each resampling (plus a rotation)
ACCEPT_TARGET = 0.25
RING_CONCENTRATION = float(os.environ.get("MC_RING", 0.99))  # |mean exp(i phi)| below this: the cloud is spread around the axis
MAX_STEP = {"step": 2.0, "turn": np.pi}  # random-walk step (in cloud sigmas), rotation angle sigma (rad)
STAGE_FRACTION = 0.1     # an axis of motion is covered once its spread exceeds this fraction of the largest
CONVERGED_SPREAD = 0.1   # m: a pulley belief wider than this (1 sigma, any direction) is not resolved
PLOT_POINTS = 1500       # particles drawn per panel


# ------------------------------------------------------------------------------------ likelihood
def features(c: np.ndarray, d: np.ndarray, dz: np.ndarray) -> np.ndarray:
    """(K, 11) rows phi_k: e_k = phi_k . w(theta) = (dz_k + L0)^2 - |c_k + s d_k - a|^2."""
    return np.column_stack([dz ** 2 - np.einsum("ki,ki->k", c, c), dz, np.ones(len(dz)),
                            np.einsum("ki,ki->k", c, d), np.einsum("ki,ki->k", d, d), c, d])


SERIES_COEF = np.array([(-1) ** j * (j + 1) for j in range(8)], float)
SERIES_ERROR = 0.05  # bound on the chi2 error of the truncated series


def series_terms(dz: np.ndarray, L0_ref: float, spread: float) -> int:
    """Terms of 1/(l + delta)^2 = sum_j (-1)^j (j+1) delta^j / l^(j+2) needed for |delta| <= spread:
    the first dropped term, (J+1) (spread/l)^J relative, times K stays below SERIES_ERROR."""
    x = spread / max(float(np.min(dz + L0_ref)), 1e-3)
    J = 1
    while J < len(SERIES_COEF) and (J + 1) * x ** J * len(dz) > SERIES_ERROR:
        J += 1
    return J


def series_weights(dz: np.ndarray, sig: np.ndarray, L0_ref: float, terms: int) -> np.ndarray:
    """(terms, K) weights of the Gram matrices: 1 / (4 sigma_k^2 l_k^(j+2)), l_k = dz_k + L0_ref."""
    l_ref = np.maximum(dz + L0_ref, 1e-3)
    return np.array([1.0 / (4.0 * sig ** 2 * l_ref ** (j + 2)) for j in range(terms)])


def lifted(theta: np.ndarray, ra: np.ndarray) -> np.ndarray:
    """(11, P) w(theta) for particles theta (5, P) = [a, eps, s]; ra = |a|."""
    a, eps, s = theta[:3], theta[3], theta[4]
    W = np.empty((NF, theta.shape[1]))
    W[0] = 1.0
    W[1] = 2.0 * (ra + eps)
    W[2] = eps * (2.0 * ra + eps)  # L0^2 - |a|^2 without cancellation
    W[3] = -2.0 * s
    W[4] = -s * s
    np.multiply(a, 2.0, out=W[5:8])
    np.multiply(W[5:8], s, out=W[8:11])
    return W


def rotate(v: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: the columns of v (3, P) rotated about the unit `axis` by `angle` (P,)."""
    cos, sin = np.cos(angle), np.sin(angle)
    cross = np.cross(axis, v, axis=0)
    along = axis[:, None] * (axis @ v)
    return v * cos + cross * sin + along * (1.0 - cos)


def principal_axis(d: np.ndarray) -> np.ndarray:
    """Unit direction of the line through the first pose that best fits the displacements d."""
    return np.linalg.eigh(d.T @ d)[1][:, -1]


def geometric_residuals(c: np.ndarray, d: np.ndarray, dz: np.ndarray, a: np.ndarray, L0: float,
                        s: float) -> np.ndarray:
    """(K,) exact r_k = dz_k + L0 - |c_k + s d_k - a| of one parameter set."""
    return dz + L0 - np.linalg.norm(c + s * d - a, axis=1)


# ------------------------------------------------------------------------------------ SMC helpers
def ess(logw: np.ndarray) -> float:
    w = np.exp(logw - logw.max())
    return float(w.sum() ** 2 / (w @ w))


def normalized(logw: np.ndarray) -> np.ndarray:
    w = np.exp(logw - logw.max())
    return w / w.sum()


def systematic(logw: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    c = np.cumsum(normalized(logw))
    c[-1] = 1.0
    return np.searchsorted(c, (rng.random() + np.arange(len(logw))) / len(logw))


def next_beta(W: np.ndarray, delta: np.ndarray, beta: float, target: float) -> float:
    """Largest beta' in (beta, 1] whose conditional ESS (weights W, energy increment delta) is at
    least `target` (a fraction): bisection on the exponent step, to 1 % of the ESS."""
    finite = np.isfinite(delta)
    W, delta = W[finite], delta[finite] - delta[finite].min()

    def cess(step: float) -> float:
        u = np.exp(-0.5 * step * delta)
        return (W @ u) ** 2 / (W @ (u * u))

    if cess(1.0 - beta) >= target:
        return 1.0
    lo, hi = 0.0, 1.0 - beta
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        c = cess(mid)
        if abs(c - target) < 0.01:
            lo = mid
            break
        lo, hi = (mid, hi) if c > target else (lo, mid)
    return beta + max(lo, 1e-9 * (1.0 - beta))


def sample_shell_in_box(rmin: float, rmax: float, lo: np.ndarray, hi: np.ndarray, n: int,
                        rng: np.random.Generator) -> np.ndarray | None:
    """n points uniform in {rmin <= |a| <= rmax} inside the box [lo, hi] (relative coordinates),
    by rejection from the shell or from the box, whichever accepts more; None if they miss."""
    def shell(m):
        v = rng.normal(size=(m, 3))
        v *= (np.cbrt(rng.uniform(max(rmin, 0.0) ** 3, rmax ** 3, m)) / np.linalg.norm(v, axis=1))[:, None]
        return v[np.all((v >= lo) & (v <= hi), axis=1)]

    def box(m):
        p = rng.uniform(lo, hi, (m, 3))
        r = np.linalg.norm(p, axis=1)
        return p[(r >= rmin) & (r <= rmax)]

    pilot = 20_000
    got = [shell(pilot), box(pilot)]
    best = shell if len(got[0]) >= len(got[1]) else box
    rate = max(len(got[0]), len(got[1])) / pilot
    pts = np.concatenate(got)
    while len(pts) < n:
        if rate < 2e-5:  # 5000 particles would need more than 2.5e8 draws
            return None
        m = int(min(2_000_000, 1.2 * (n - len(pts)) / rate + 1000))
        pts = np.concatenate([pts, best(m)])
        rate = max(rate, 1e-5)
    return pts[rng.permutation(len(pts))[:n]]


# ------------------------------------------------------------------------------------ one cable
@dataclass
class Target:
    """Energy E = w^T G w + lam (s - mu)^2 (= -2 log posterior inside the prior box; G None: 0)."""

    G: np.ndarray | None
    mu: float = 0.0
    lam: float = 0.0

    def plus(self, beta: float, incr: "Target") -> "Target":
        """This target plus beta times an increment (energies are linear in G and lam)."""
        G = self.G if incr.G is None else self.G + beta * incr.G
        return Target(G, incr.mu if incr.lam else self.mu, self.lam + beta * incr.lam)


class CableSampler:
    """The particle belief of one cable over theta = (a - c0, eps, s), L0 = |a - c0| + eps."""

    def __init__(self, c: np.ndarray, d: np.ndarray, dz: np.ndarray, sig: np.ndarray, L0_range: tuple,
                 lo: np.ndarray, hi: np.ndarray, scale_range: tuple, P: int, rng: np.random.Generator):
        self.origin = c[0].copy()
        self.c, self.d, self.dz, self.sig = c - self.origin, d, dz, sig
        self.L0_range = (float(L0_range[0]), float(L0_range[1]))
        self.lo, self.hi = lo - self.origin, hi - self.origin
        self.srange = (float(scale_range[0]), float(scale_range[1]))
        self.P, self.rng = P, rng
        box_lo = np.concatenate([self.lo, [self.L0_range[0], self.srange[0]]])
        box_hi = np.concatenate([self.hi, [self.L0_range[1], self.srange[1]]])
        self.mid, self.half = 0.5 * (box_lo + box_hi), 0.5 * (box_hi - box_lo)
        self.set_reference_length(0.5 * sum(self.L0_range))
        self.step, self.turn = 0.3, 0.3
        self.stats = {"tempering_steps": 0, "resamplings": 0, "moves": 0, "acceptance": []}

    def set_reference_length(self, L0: float) -> None:
        self.L0_ref = L0
        self.F = features(self.c, self.d, self.dz)
        self.terms = series_terms(self.dz, L0, 0.5 * (self.L0_range[1] - self.L0_range[0]))
        self.series = series_weights(self.dz, self.sig, L0, self.terms)

    def gram(self, n0: int, n1: int) -> np.ndarray:
        """(terms, 11, 11) Gram matrices of poses n0..n1-1."""
        F = self.F[n0:n1]
        return np.einsum("jk,ka,kb->jab", self.series[:, n0:n1], F, F)

    def quad(self, G: np.ndarray, W: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """chi2 = sum_j c_j delta^j w^T G_j w (the whitened residual with the particle's own
        measured length l_k = dz_k + L0 in the denominator, as a series around L0_ref)."""
        out = np.einsum("ip,ip->p", G[-1] @ W, W) * SERIES_COEF[len(G) - 1]
        for j in range(len(G) - 2, -1, -1):
            out = out * delta + SERIES_COEF[j] * np.einsum("ip,ip->p", G[j] @ W, W)
        return out

    def inside(self, theta: np.ndarray, ra: np.ndarray) -> np.ndarray:
        """Inside the uniform priors: region, L0 range, scale range (|x - mid| <= half width)."""
        ok = np.abs(theta[0] - self.mid[0]) <= self.half[0]
        for i in (1, 2):
            ok &= np.abs(theta[i] - self.mid[i]) <= self.half[i]
        ok &= np.abs(ra + theta[3] - self.mid[3]) <= self.half[3]
        ok &= np.abs(theta[4] - self.mid[4]) <= self.half[4]
        return ok

    def energies(self, theta: np.ndarray, targets) -> tuple[np.ndarray, list[np.ndarray]]:
        """(inside the prior, [E for each target])."""
        ra = np.sqrt(np.einsum("ip,ip->p", theta[:3], theta[:3]))
        W = lifted(theta, ra)
        delta = ra + theta[3] - self.L0_ref
        return self.inside(theta, ra), [(0.0 if t.G is None else self.quad(t.G, W, delta))
                                        + t.lam * (theta[4] - t.mu) ** 2 for t in targets]

    def initialize(self, eps_sigma: float) -> bool:
        a = sample_shell_in_box(*self.L0_range, self.lo, self.hi, self.P, self.rng)
        if a is None:
            return False
        eps = self.rng.normal(0.0, eps_sigma, self.P)
        s = self.rng.uniform(*self.srange, self.P)
        self.theta = np.vstack([a.T, eps, s])
        self.logw = np.zeros(self.P)
        return True

    # --- annealing -----------------------------------------------------------------------------
    def anneal(self, base: Target, incr: Target, E: np.ndarray, axis: np.ndarray) -> np.ndarray:
        """Temper the cloud from the target `base` (particle energies E) to base + incr by
        adaptive steps; `axis`: of the rotation moves. Returns the energies at base + incr."""
        ok, (dE,) = self.energies(self.theta, (incr,))
        self.logw[~ok] = -np.inf
        beta = 0.0
        while beta < 1.0:
            b = next_beta(normalized(self.logw), dE, beta, ESS_TARGET)
            self.logw += -0.5 * (b - beta) * dE
            self.logw -= self.logw.max()
            E = E + (b - beta) * dE
            beta = b
            self.stats["tempering_steps"] += 1
            if ess(self.logw) < ESS_TARGET * self.P:
                idx = systematic(self.logw, self.rng)
                self.theta, E = self.theta[:, idx], E[idx]
                self.logw = np.zeros(self.P)
                self.stats["resamplings"] += 1
                E = self.move(base.plus(beta, incr), E, axis)
                if beta < 1.0:
                    _, (dE,) = self.energies(self.theta, (incr,))
        return E

    def move(self, target: Target, E: np.ndarray, axis: np.ndarray) -> np.ndarray:
        """Metropolis-Hastings moves that leave the target invariant, in cylindrical coordinates
        about the principal axis u of the motion so far, through the first attachment point:
        y = (xi, rho, phi, eps, s) with a = xi u + rho (cos phi e1 + sin phi e2).

        Along a straight line the likelihood does not depend on phi: the belief is a ring around
        the line, a thin band in y. Two proposals, both symmetric in y (the acceptance ratio is
        the target ratio times the volume factor rho'/rho):
        - a Gaussian random walk shaped by the cloud's covariance in y (step adapted towards
          ACCEPT_TARGET acceptance): it follows the band's thin directions;
        - a rotation about u, phi' = phi + N(0, turn^2) (turn adapted, up to pi): it crosses
          the ring in one step where a random walk would crawl along it.
        Once the motion spans more axes the belief is a compact cluster and the rotations shrink
        to small turns."""
        e1 = np.linalg.svd(axis[None])[2][1]
        e2 = np.cross(axis, e1)
        Y = self._cylindrical(axis, e1, e2)
        centred = Y.copy()
        mean_phi = np.arctan2(np.sin(Y[2]).mean(), np.cos(Y[2]).mean())
        centred[2] = np.mod(Y[2] - mean_phi + np.pi, 2 * np.pi)  # the cloud's spread in phi about its mean
        L = np.linalg.cholesky(np.cov(centred) + 1e-14 * np.eye(DIM))
        ring = np.hypot(np.sin(Y[2]).mean(), np.cos(Y[2]).mean()) < RING_CONCENTRATION
        for _ in range(MOVES + (not ring)):
            prop = Y + self.step * (L @ self.rng.standard_normal((DIM, self.P), dtype=np.float32))
            E, Y = self._metropolis(prop, Y, target, E, (axis, e1, e2), "step")
        if ring:
            prop = Y.copy()
            prop[2] += self.turn * self.rng.standard_normal(self.P, dtype=np.float32)
            E = self._metropolis(prop, Y.copy(), target, E, (axis, e1, e2), "turn")[0]
        return E

    def _cylindrical(self, u, e1, e2) -> np.ndarray:
        a = self.theta[:3]
        xi, x1, x2 = u @ a, e1 @ a, e2 @ a
        return np.vstack([xi, np.hypot(x1, x2), np.arctan2(x2, x1), self.theta[3:]])

    def _metropolis(self, prop: np.ndarray, Y: np.ndarray, target: Target, E: np.ndarray, frame,
                    scale: str) -> tuple[np.ndarray, np.ndarray]:
        u, e1, e2 = frame
        theta = np.empty_like(self.theta)
        theta[:3] = (u[:, None] * prop[0] + prop[1] * (e1[:, None] * np.cos(prop[2])
                                                     + e2[:, None] * np.sin(prop[2])))
        theta[3:] = prop[3:]
        ok, (E2,) = self.energies(theta, (target,))
        ok &= prop[1] > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            log_alpha = -0.5 * (E2 - E) + np.log(prop[1] / Y[1])
        acc = ok & (np.log(self.rng.random(self.P)) < log_alpha)
        np.copyto(self.theta, theta, where=acc)
        np.copyto(Y, prop, where=acc)
        rate = float(acc.mean())
        setattr(self, scale, min(getattr(self, scale) * np.exp(rate - ACCEPT_TARGET), MAX_STEP[scale]))
        self.stats["moves"] += 1
        self.stats["acceptance"].append(rate)
        return np.where(acc, E2, E), Y

    def assimilate(self, bounds, snapshots=()) -> dict[int, np.ndarray]:
        """The data prefix by prefix (batch ends `bounds`); the clouds (3, P) at `snapshots`."""
        G, n_prev, snaps, E = np.zeros((self.terms, NF, NF)), 0, {}, np.zeros(self.P)
        for n in bounds:
            dG = self.gram(n_prev, n)
            E = self.anneal(Target(G), Target(dG), E, principal_axis(self.d[:n]))
            G, n_prev = G + dG, n
            if n in snapshots:
                snaps[n] = self.resampled_pulleys()
        self.G, self.E = G, E
        return snaps

    def condition_scale(self, mean: float, var: float) -> None:
        """Temper in the other cables' scale belief N(mean, var)."""
        self.E = self.anneal(Target(self.G), Target(None, mean, 1.0 / var), self.E, principal_axis(self.d))

    # --- summaries ---------------------------------------------------------------------------
    def weights(self) -> np.ndarray:
        return normalized(self.logw)

    def pulleys(self) -> np.ndarray:
        return self.theta[:3] + self.origin[:, None]

    def lengths(self) -> np.ndarray:
        return np.linalg.norm(self.theta[:3], axis=0) + self.theta[3]

    def resampled_pulleys(self, m: int | None = None) -> np.ndarray:
        idx = systematic(self.logw, self.rng)
        if m is not None and m < len(idx):
            idx = self.rng.choice(idx, m, replace=False)
        return self.pulleys()[:, idx]

    def scale_belief(self) -> tuple[float, float]:
        W = self.weights()
        m = float(W @ self.theta[4])
        return m, float(W @ (self.theta[4] - m) ** 2)


# ------------------------------------------------------------------------------------ stages
def motion_stages(d: np.ndarray, fraction: float = STAGE_FRACTION) -> tuple[list[int], int]:
    """Prefix lengths [n1, n2, K] ending the 1-axis (shell), 2-axis (ring) and full (cluster)
    stages, and the number of axes the whole motion covers (see the module docstring)."""
    K = len(d)
    n = np.arange(1, K + 1)[:, None]
    mean = np.cumsum(d, axis=0) / n
    second = np.cumsum(d[:, :, None] * d[:, None, :], axis=0) / n[:, :, None]
    cov = second - mean[:, :, None] * mean[:, None, :]
    spread = np.sqrt(np.clip(np.linalg.eigvalsh(cov), 0.0, None))[:, ::-1]  # largest first
    covered = (spread >= fraction * spread[-1, 0]).sum(axis=1) if spread[-1, 0] > 0 else np.zeros(K, int)
    out = []
    for axes in (2, 3):
        hit = np.flatnonzero(covered >= axes)
        if not len(hit):
            out.append(K)
            continue
        # back to where that axis' spread started growing: the motion along it began there
        j, s = int(hit[0]), spread[:, axes - 1]
        while j > 1 and s[j - 1] < s[j]:
            j -= 1
        out.append(j + 1)  # prefix length: poses 0..j
    out = [max(min(x, K), 2) for x in out]
    return [out[0], max(out[1], out[0]), K], int(covered[-1])


def pose_sigmas(d: np.ndarray, sigma: float, vo_sigma: tuple[float, float], scale: float) -> np.ndarray:
    """Per-pose noise of dz_k (see the module docstring: encoder noise plus VO drift)."""
    rot, trans = vo_sigma
    K = len(d)
    k = np.arange(K)
    var = np.full(K, sigma ** 2) + k * trans ** 2
    if rot > 0:
        p = scale * d
        s1 = np.concatenate([[np.zeros(3)], np.cumsum(p, axis=0)[:-1]])
        s2 = np.concatenate([[0.0], np.cumsum(np.einsum("ki,ki->k", p, p))[:-1]])
        var += rot ** 2 * np.maximum(k * np.einsum("ki,ki->k", p, p) - 2 * np.einsum("ki,ki->k", p, s1) + s2, 0.0)
    return np.sqrt(var)


# ------------------------------------------------------------------------------------ the core
@dataclass
class Calibration:
    pulley: np.ndarray            # (n, 3)
    pulley_cov: np.ndarray        # (n, 3, 3)
    length: np.ndarray            # (n,) L0_i, cable length at the first pose
    length_sigma: np.ndarray
    scale: float
    scale_sigma: float
    scale_per_cable: np.ndarray   # (n, 2) mean, sigma of each cable's own scale belief
    scale_consistency: float      # scatter of the cables' scales over their spreads (chi2 / dof)
    fit_rms: np.ndarray           # (n,) exact residual rms of the estimate (m)
    stage_poses: list[int]        # prefix lengths ending the stages
    axes_covered: int
    clouds: list[np.ndarray]      # per stage: (n, 3, m) pulley particles (resampled)
    stage_spread: np.ndarray      # (stages, n, 3) principal 1-sigma spreads of the pulley belief, largest first
    seconds: float
    stats: list[dict] = field(default_factory=list)

    def principal_spread(self) -> np.ndarray:
        return np.sqrt(np.clip(np.linalg.eigvalsh(self.pulley_cov), 0, None))[:, ::-1]


def calibrate(c: np.ndarray, d: np.ndarray, z: np.ndarray, L0_guess: np.ndarray, region: tuple,
              scale_range: tuple, sigma: float, *, spread: float = 0.05, particles: int = 5000,
              rng: np.random.Generator | None = None, vo_sigma: tuple[float, float] = (0.0, 0.0),
              batch: int = 25, plot_points: int = PLOT_POINTS, workers: int | None = None) -> Calibration:
    """The Monte-Carlo self-calibration on arrays.

    c: (n, K, 3) attachment points at scale 0 (X0 R_k b_i + t0); d: (K, 3) the unscaled VO
    displacement in the base frame (R_X0 t_k); z: (n, K) encoder readings; L0_guess: (n,) nominal
    cable lengths at the first pose; region: (lo, hi) where pulleys may be; scale_range: (min, max);
    sigma: encoder noise (m); vo_sigma: per-frame VO (rotation rad, translation m) noise.
    Cables run in `workers` threads (default: up to 2; numpy releases the GIL in the array work);
    each cable draws from its own generator spawned from `rng`, so results do not depend on it."""
    tic = time.perf_counter()
    rng = np.random.default_rng() if rng is None else rng
    n, K = z.shape
    lo, hi = (np.asarray(x, float) for x in region)
    stage_poses, axes = motion_stages(d)
    bounds = sorted(set(list(range(batch, K, batch)) + [K] + stage_poses))
    sig = pose_sigmas(d, sigma, vo_sigma, float(np.sqrt(scale_range[0] * scale_range[1])))
    samplers = []
    for i, r in enumerate(rng.spawn(n)):
        L0r = (L0_guess[i] - spread, L0_guess[i] + spread)
        smp = CableSampler(c[i], d, z[i] - z[i, 0], sig, L0r, lo, hi, scale_range, particles, r)
        if not smp.initialize(sigma):
            raise ValueError(f"cable {i}: the region does not meet the sphere of radius "
                             f"{L0_guess[i]:.3f} +- {spread} m around the first attachment point")
        samplers.append(smp)
    workers = min(n, workers or min(2, os.cpu_count() or 1))

    def run_all(fn, items):
        if workers <= 1:
            return [fn(*x) for x in items]
        with ThreadPoolExecutor(workers) as pool:
            return list(pool.map(lambda x: fn(*x), items))

    clouds = run_all(lambda smp: smp.assimilate(bounds, set(stage_poses)), [(s,) for s in samplers])

    # the shared scale: product of the cables' beliefs (variances inflated by the scatter of their
    # means when it exceeds them: drift makes the cables disagree more than their own spreads say)
    own = np.array([smp.scale_belief() for smp in samplers])  # mean, var
    var = np.maximum(own[:, 1], 1e-14)
    consistency = 1.0
    if n > 1:
        m = (own[:, 0] / var).sum() / (1.0 / var).sum()
        consistency = float(((own[:, 0] - m) ** 2 / var).sum() / (n - 1))
        var = var * max(consistency, 1.0)
    prec = 1.0 / var
    scale_var = 1.0 / prec.sum()
    scale = float(scale_var * (prec @ own[:, 0]))
    if n > 1:
        others = [((prec @ own[:, 0] - prec[i] * own[i, 0]) / (prec.sum() - prec[i]), 1.0 / (prec.sum() - prec[i]))
                  for i in range(n)]
        run_all(lambda smp, mv: smp.condition_scale(*mv), list(zip(samplers, others)))

    pulley, cov, L0, L0s, rms, final = [], [], [], [], [], []
    for i, smp in enumerate(samplers):
        W = smp.weights()
        A = smp.pulleys()
        m = A @ W
        pulley.append(m)
        cov.append(np.cov(A, aweights=W))
        lengths = smp.lengths()
        L0.append(float(W @ lengths))
        L0s.append(float(np.sqrt(W @ (lengths - L0[-1]) ** 2)))
        r = geometric_residuals(c[i], d, z[i] - z[i, 0], m, L0[-1], scale)
        rms.append(float(np.sqrt(np.mean(r ** 2))))
        final.append(smp.resampled_pulleys())
    stage_clouds = [[clouds[i][stage_poses[0]] for i in range(n)], [clouds[i][stage_poses[1]] for i in range(n)],
                    final]
    stage_spread = np.array([[np.sqrt(np.clip(np.linalg.eigvalsh(np.cov(p)), 0, None))[::-1] for p in pts]
                             for pts in stage_clouds])
    thin = [np.stack([p[:, rng.choice(p.shape[1], min(plot_points, p.shape[1]), replace=False)] for p in pts])
            for pts in stage_clouds]
    return Calibration(np.array(pulley), np.array(cov), np.array(L0), np.array(L0s), scale,
                       float(np.sqrt(scale_var)), np.column_stack([own[:, 0], np.sqrt(own[:, 1])]), consistency,
                       np.array(rms), stage_poses, axes, thin, stage_spread, time.perf_counter() - tic,
                       [s.stats for s in samplers])
