"""Monte-Carlo self-calibration of a cable robot (docs/models/cable_rigid.md#monte-carlo-initialization): pulleys
a_i, encoder offsets l0_i and the VO scale s from the encoder readings and the unscaled visual
odometry alone -- no prior values for the pulleys. Pure numpy; the `cable.monte_carlo`
initializer (initializers.py) feeds it from a config.

Model
-----
The end-effector pose at state k is X0 o (R_k, s t_k), (R_k, t_k) = VO_0^-1 VO_k at the state
times and X0 the initial value of the first pose (the user's zero pose, set by `pose.origin`).
The attachment point of cable i is linear in the scale, q_ik(s) = c_ik + s d_k, with
c_ik = X0 (R_k b_i) and d_k = R_X0 t_k computed once. The encoders are read against the first
sample, dz_ik = z_ik - z_i0, and a particle's encoder offset is l0_i = z_i0 - L0_i with L0_i the
cable length at the first pose:

    r_ik = dz_ik + L0_i - |q_ik(s) - a_i|         (thesis eq. 4.1 with l0 eliminated)

Each cable has its own particle system over theta = (a_i, eps_i, s), L0_i = |a_i - c_i0| + eps_i.
The parametrization puts the first pose's constraint into the coordinates: particles start
uniform over {a in region, |a - c_i0| within initial_length_spread of the nominal L0} -- the
shell -- with eps ~ N(0, sigma), and s uniform over scale_range.

Likelihood without per-pose work
--------------------------------
Squaring the cable equation gives an algebraic residual linear in lifted unknowns,

    e_k = (dz_k + L0)^2 - |c_k + s d_k - a|^2 = phi_k . w(theta),
    phi_k = [dz^2 - |c|^2, dz, 1, c.d, |d|^2, c, d],  w = [1, 2L0, L0^2 - |a|^2, -2s, -s^2, 2a, 2sa]

and e_k = r_k (l_k + |q_k - a|) with l_k = dz_k + L0 the particle's own measured length, so
r_k / sigma_k = e_k / (2 l_k sigma_k) up to a relative r_k / 2 l_k (1e-4 near the posterior).
The particle-dependent 1 / l_k^2 is a power series in delta = L0 - L0_ref around the nominal
length (`series_terms` terms, truncation below SERIES_ERROR in chi2), hence

    chi2_n(theta) = sum_j c_j delta^j w^T G_jn w,   G_jn = sum_{k<n} phi_k phi_k^T / (4 sigma_k^2 l_ref,k^(j+2))

(11 x 11 matrices, cumulative over prefixes). The sum over the (particles x poses) residual array
is done analytically: one prefix costs a few (11 x 11) @ (11 x P) products whatever its number of
poses. (Weighting with the nominal length only, instead of each particle's, biases L0 by
centimetres: the chi2 of ~K noise terms rewards shorter cables.) The exact geometric residual is
evaluated for the estimate (`fit_rms`).

Noise: sigma_k^2 = sigma^2 + VO drift (`pose_sigmas`: random walks of translation and heading
from the per-frame `vo_sigma`, which the dead-reckoned VO turns into a growing model error). The
energy is chi2 profiled over an inflation c >= 1 of that noise (`profile`): when the data misfit
more than the model says (drift larger than vo_sigma, unmodelled swing), the belief widens with
the residuals instead of sharpening a wrong answer, and the annealing does not crawl through a
chi2 of millions. Drift errors are correlated in time, so the spreads stay somewhat optimistic.

Sampler: annealed sequential importance resampling
--------------------------------------------------
Iterated batch importance sampling (Chopin 2002) with adaptive tempering inside each batch (Del
Moral, Doucet and Jasra 2006): the targets are the posteriors of growing prefixes of the
trajectory (batches of `batch` poses). When a batch is too informative for the cloud, its
likelihood is tempered in, each exponent step chosen by bisection so that the conditional
effective sample size is ESS_TARGET of the particles; when the ESS falls below that the cloud is
resampled (systematic) and moved by Metropolis-Hastings steps that leave the current tempered
target invariant -- the jitter that keeps the cloud diverse without biasing it (`move`:
random walks in cylindrical coordinates about the motion's principal axis, plus rotations about
it, which cross the ring in one step). At most MAX_ROUNDS resample-move rounds per batch.

The shared scale: each cable estimates (a_i, L0_i, s) from its own data first. With independent
priors the scale marginal of the joint posterior is the product of the cables' marginals, so
their Gaussian fits are multiplied (variances inflated by the scatter of the means when it is
larger than they are: `scale_consistency`); then each cable's cloud is tempered towards its own
likelihood times the message of the other cables, N(s; mean_-i, var_-i): its pulley belief is
conditioned on the combined scale belief. Outputs: weighted means and covariances.

Stages (the plot's shell -> ring -> cluster): from the data, by the directions the motion has
covered (`motion_stages`): stage 1 ends where the motion first leaves its first axis, stage 2
where it leaves the plane of the first two, stage 3 is the end. A line of motion leaves the
pulley on a ring around it (the scale and the position along the line follow from the curvature
of the length profile, the angle around the line not at all); with the initial-length shell this
is the thesis's shell of thickness +-initial_length_spread narrowed to a band; a second axis cuts
it to one or two spots, elongated along the cable; more motion shrinks them to a cluster. The
directions, not fractions of the trajectory, because any motion plan must work; directions of
velocity, not the spread of positions, because VO drift spreads positions along every axis.

Cost (750 poses, 5000 particles, 4 cables): about 0.4 s on one core of this 2-core machine,
30-50 resample-move rounds per cable. Threads do not help: the arrays (5000 particles) are too
small for numpy to outrun the GIL.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

NF = 11                  # lifted features of the squared cable equation
DIM = 5                  # particle state: a (3, relative to the first attachment point), eps, s
ESS_TARGET = 0.3         # conditional ESS per tempering step, and resampling threshold (fraction of P)
MAX_ROUNDS = 60         # resample-move rounds per batch before the rest of it is taken in one step
MOVES = 2                # random-walk Metropolis-Hastings moves after each resampling (plus a rotation)
ACCEPT_TARGET = 0.25
RING_CONCENTRATION = 0.99  # |mean exp(i phi)| below this: the cloud is spread around the axis
MAX_STEP = {"step": 2.0, "turn": np.pi}  # random-walk step (in cloud sigmas), rotation angle sigma (rad)
STAGE_WINDOW = 5         # poses: velocity by central differences over +-5 poses; a new axis must last 5 poses
STAGE_SLOW = 0.25        # poses slower than this fraction of the 95th-percentile speed have no direction
STAGE_OFF_SPAN = 0.5     # a direction more than 30 deg out of the span of the axes so far starts a new axis
CONVERGED_SPREAD = 0.1   # m: a pulley belief wider than this (1 sigma, any direction) is not resolved
PLOT_POINTS = 1500       # particles drawn per panel


# ------------------------------------------------------------------------------------ likelihood
def features(c: np.ndarray, d: np.ndarray, dz: np.ndarray) -> np.ndarray:
    """(K, 11) rows phi_k: e_k = phi_k . w(theta) = (dz_k + L0)^2 - |c_k + s d_k - a|^2."""
    return np.column_stack([dz ** 2 - np.einsum("ki,ki->k", c, c), dz, np.ones(len(dz)),
                            np.einsum("ki,ki->k", c, d), np.einsum("ki,ki->k", d, d), c, d])


SERIES_ERROR = 0.5  # bound on the chi2 error of the truncated series in delta = L0 - L0_ref


def series_terms(dz: np.ndarray, L0_ref: float, spread: float) -> int:
    """Terms J of 1/(2 (l + delta)) = sum_j (-1)^j delta^j / (2 l^(j+1)) needed for |delta| <=
    spread: the relative residual error (spread/l)^J, times 2 K, stays below SERIES_ERROR."""
    x = spread / max(float(np.min(dz + L0_ref)), 1e-3)
    J = 1
    while J < 6 and 2 * x ** J * len(dz) > SERIES_ERROR:
        J += 1
    return J


def noise_cholesky(d: np.ndarray, sigma: float, vo_sigma: tuple[float, float], scale: float,
                   frames: np.ndarray | None = None) -> np.ndarray:
    """Lower Cholesky factor of the (K, K) covariance of the length residuals: encoder noise plus
    the drift of the dead-reckoned VO, random walks in translation and heading (vo_sigma: per
    frame, rotation rad and translation in VO units, as the `pose.scaled_relative` sigma; frames:
    VO frames from the first pose to pose k, default 0, 1, 2, ...). Drift at pose k:
    sum_{j<k} eps_j + dtheta_j x (p_k - p_j) with p = scale d (metric); its covariance between
    poses k and k' is taken isotropic along the cable:

        (s sigma_t)^2 m + sigma_r^2 sum_{j<m} (p_k - p_j).(p_k' - p_j),   m = min(frames k, k')

    The drift is correlated along the trajectory: whitening with the full covariance (generalized
    least squares) keeps 750 poses from counting as 750 independent looks at a drifting pose."""
    K = len(d)
    rot, trans = vo_sigma
    f = np.arange(K, dtype=float) if frames is None else np.asarray(frames, float)
    cov = np.diag(np.full(K, float(sigma) ** 2))
    if rot > 0 or trans > 0:
        m = np.minimum.outer(np.arange(K), np.arange(K))  # index of the earlier pose
        cov += (scale * trans) ** 2 * f[m]
        if rot > 0:
            p = scale * d
            w = np.diff(f, prepend=f[0])  # frames between consecutive poses
            s0 = np.cumsum(w) - w
            s1 = np.cumsum(w[:, None] * p, axis=0) - w[:, None] * p
            s2 = np.cumsum(w * np.einsum("ki,ki->k", p, p)) - w * np.einsum("ki,ki->k", p, p)
            cross = np.take_along_axis(p @ s1.T, m, axis=1)  # p_k . s1[min(k, k')]
            cov += rot ** 2 * (s0[m] * (p @ p.T) - cross - cross.T + s2[m])
    return np.linalg.cholesky(cov)


def whitened_features(F: np.ndarray, dz: np.ndarray, L0_ref: float, terms: int, chol: np.ndarray) -> np.ndarray:
    """(terms, K, 11): L^-1 (a_j * F), a_jk = (-1)^j / (2 l_k^(j+1)), l_k = dz_k + L0_ref; causal
    (row k uses poses <= k), so prefix Gram matrices are cumulative sums."""
    from scipy.linalg import solve_triangular

    l_ref = np.maximum(dz + L0_ref, 1e-3)
    return np.stack([solve_triangular(chol, ((-1) ** j / (2.0 * l_ref ** (j + 1)))[:, None] * F, lower=True)
                     for j in range(terms)])


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


def next_beta(W: np.ndarray, step, beta: float, target: float) -> float:
    """Largest beta' in (beta, 1] whose conditional ESS is at least `target` (a fraction) of the
    particles (weights W); step(beta') is each particle's energy increment from beta to beta'.
    Bisection to 1 % of the ESS."""
    live = W > 0
    W = W[live]

    def cess(b: float) -> float:
        inc = step(b)[live]
        u = np.exp(-0.5 * (inc - inc.min()))
        return (W @ u) ** 2 / (W @ (u * u))

    if cess(1.0) >= target:
        return 1.0
    lo, hi = beta, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        c = cess(mid)
        if abs(c - target) < 0.01:
            lo = mid
            break
        lo, hi = (mid, hi) if c > target else (lo, mid)
    return max(lo, beta + 1e-9 * (1.0 - beta))


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
    """Energy profile(chi2, n) + lam (s - mu)^2, chi2 = w^T G w over n poses (G None: 0); the
    energy is -2 log of the posterior inside the prior box."""

    G: np.ndarray | None
    n: float = 0.0
    mu: float = 0.0
    lam: float = 0.0

    def plus(self, beta: float, incr: Target) -> Target:
        """This target plus beta times an increment (G, n and lam add)."""
        G = self.G if incr.G is None else self.G + beta * incr.G
        return Target(G, self.n + beta * incr.n, incr.mu if incr.lam else self.mu, self.lam + beta * incr.lam)

    def total(self, chi: np.ndarray, s: np.ndarray) -> np.ndarray:
        out = profile(chi, self.n)
        return out + self.lam * (s - self.mu) ** 2 if self.lam else out


def profile(chi: np.ndarray, n: float) -> np.ndarray:
    """chi2 minimized over an unknown inflation c >= 1 of the noise variance, plus n log c:
    chi2 while chi2 <= n (the noise model fits), n (1 + log(chi2 / n)) beyond. Smooth at chi2 = n.
    A trajectory whose VO drifts more than `vo_sigma` says then widens the belief instead of
    sharpening a wrong one, and the annealing does not crawl through a huge chi2 range."""
    if n <= 0:
        return chi
    return np.where(chi <= n, chi, n * (1.0 + np.log(np.maximum(chi, n) / n)))


class CableSampler:
    """The particle belief of one cable over theta = (a - c0, eps, s), L0 = |a - c0| + eps."""

    def __init__(self, c: np.ndarray, d: np.ndarray, dz: np.ndarray, chol: np.ndarray, L0_range: tuple,
                 lo: np.ndarray, hi: np.ndarray, scale_range: tuple, P: int, rng: np.random.Generator):
        self.origin = c[0].copy()
        self.c, self.d, self.dz, self.chol = c - self.origin, d, dz, chol
        self.L0_range = (float(L0_range[0]), float(L0_range[1]))
        self.lo, self.hi = lo - self.origin, hi - self.origin
        self.srange = (float(scale_range[0]), float(scale_range[1]))
        self.P, self.rng = P, rng
        box_lo = np.concatenate([self.lo, [self.L0_range[0], self.srange[0]]])
        box_hi = np.concatenate([self.hi, [self.L0_range[1], self.srange[1]]])
        self.mid, self.half = 0.5 * (box_lo + box_hi), 0.5 * (box_hi - box_lo)
        self.set_reference_length(0.5 * sum(self.L0_range))
        self.step, self.turn = 0.3, 0.3
        self.stats = {"tempering_steps": 0, "resamplings": 0, "moves": 0, "acceptance": [], "capped": 0}

    def set_reference_length(self, L0: float) -> None:
        self.L0_ref = L0
        terms = series_terms(self.dz, L0, 0.5 * (self.L0_range[1] - self.L0_range[0]))
        self.psi = whitened_features(features(self.c, self.d, self.dz), self.dz, L0, terms, self.chol)
        self.terms = 2 * terms - 1

    def gram(self, n0: int, n1: int) -> np.ndarray:
        """(2 terms - 1, 11, 11) Gram matrices of the whitened rows n0..n1-1, by power of delta."""
        P = self.psi[:, n0:n1]
        J = len(P)
        out = np.zeros((2 * J - 1, NF, NF))
        for j in range(J):
            for k in range(J):
                out[j + k] += P[j].T @ P[k]
        return out

    def quad(self, G: np.ndarray, W: np.ndarray, delta: np.ndarray) -> np.ndarray:
        """chi2 = sum_m delta^m w^T G_m w: the whitened residuals with the particle's own measured
        length l_k = dz_k + L0 in the denominator, as a series around L0_ref."""
        out = np.einsum("ip,ip->p", G[-1] @ W, W)
        for m in range(len(G) - 2, -1, -1):
            out = out * delta + np.einsum("ip,ip->p", G[m] @ W, W)
        return out

    def inside(self, theta: np.ndarray, ra: np.ndarray) -> np.ndarray:
        """Inside the uniform priors: region, L0 range, scale range (|x - mid| <= half width)."""
        ok = np.abs(theta[0] - self.mid[0]) <= self.half[0]
        for i in (1, 2):
            ok &= np.abs(theta[i] - self.mid[i]) <= self.half[i]
        ok &= np.abs(ra + theta[3] - self.mid[3]) <= self.half[3]
        ok &= np.abs(theta[4] - self.mid[4]) <= self.half[4]
        return ok

    def energies(self, theta: np.ndarray, target: Target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(inside the prior, chi2 of the target's poses, the target's energy)."""
        ra = np.sqrt(np.einsum("ip,ip->p", theta[:3], theta[:3]))
        if target.G is None:
            chi = np.zeros(theta.shape[1])
        else:
            chi = self.quad(target.G, lifted(theta, ra), ra + theta[3] - self.L0_ref)
        return self.inside(theta, ra), chi, target.total(chi, theta[4])

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
    def anneal(self, base: Target, incr: Target, chi: np.ndarray, axis: np.ndarray) -> np.ndarray:
        """Temper the cloud from the target `base` (the particles' chi2 there: `chi`) to
        base + incr by adaptive steps; `axis`: of the rotation moves. Returns the chi2 at the end."""
        ok, dchi, _ = self.energies(self.theta, incr)
        self.logw[~ok] = -np.inf
        beta, E, rounds = 0.0, base.total(chi, self.theta[4]), 0
        while beta < 1.0:
            def step(b, beta=beta, chi=chi, dchi=dchi, E=E):
                return base.plus(b, incr).total(chi + (b - beta) * dchi, self.theta[4]) - E
            b = 1.0 if rounds >= MAX_ROUNDS else next_beta(normalized(self.logw), step, beta, ESS_TARGET)
            inc = step(b)
            self.logw -= 0.5 * inc
            self.logw -= self.logw.max()
            chi, E, beta = chi + (b - beta) * dchi, E + inc, b
            self.stats["tempering_steps"] += 1
            if ess(self.logw) < ESS_TARGET * self.P:
                idx = systematic(self.logw, self.rng)
                self.theta, chi, E = self.theta[:, idx], chi[idx], E[idx]
                self.logw = np.zeros(self.P)
                self.stats["resamplings"] += 1
                rounds += 1
                chi, E = self.move(base.plus(beta, incr), chi, E, axis)
                if beta < 1.0:
                    _, dchi, _ = self.energies(self.theta, incr)
        self.stats["capped"] += rounds >= MAX_ROUNDS
        return chi

    def move(self, target: Target, chi: np.ndarray, E: np.ndarray, axis: np.ndarray):
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
        for _ in range(MOVES):
            prop = Y + self.step * (L @ self.rng.standard_normal((DIM, self.P), dtype=np.float32))
            chi, E = self._metropolis(prop, Y, target, chi, E, (axis, e1, e2), "step")
        if ring:
            prop = Y.copy()
            prop[2] += self.turn * self.rng.standard_normal(self.P, dtype=np.float32)
            chi, E = self._metropolis(prop, Y.copy(), target, chi, E, (axis, e1, e2), "turn")
        return chi, E

    def _cylindrical(self, u, e1, e2) -> np.ndarray:
        a = self.theta[:3]
        xi, x1, x2 = u @ a, e1 @ a, e2 @ a
        return np.vstack([xi, np.hypot(x1, x2), np.arctan2(x2, x1), self.theta[3:]])

    def _metropolis(self, prop: np.ndarray, Y: np.ndarray, target: Target, chi: np.ndarray, E: np.ndarray,
                    frame, scale: str) -> tuple[np.ndarray, np.ndarray]:
        """One proposal for every particle (y coordinates `prop`); updates theta and Y in place;
        returns the chi2 and energies after acceptance."""
        u, e1, e2 = frame
        theta = np.empty_like(self.theta)
        theta[:3] = (u[:, None] * prop[0] + prop[1] * (e1[:, None] * np.cos(prop[2])
                                                     + e2[:, None] * np.sin(prop[2])))
        theta[3:] = prop[3:]
        ok, chi2, E2 = self.energies(theta, target)
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
        return np.where(acc, chi2, chi), np.where(acc, E2, E)

    def assimilate(self, bounds, snapshots=()) -> dict[int, np.ndarray]:
        """The data prefix by prefix (batch ends `bounds`); the clouds (3, P) at `snapshots`."""
        G, n_prev, snaps, chi = np.zeros((self.terms, NF, NF)), 0, {}, np.zeros(self.P)
        for n in bounds:
            dG = self.gram(n_prev, n)
            chi = self.anneal(Target(G, n_prev), Target(dG, n - n_prev), chi, principal_axis(self.d[:n]))
            G, n_prev = G + dG, n
            if n in snapshots:
                snaps[n] = self.resampled_pulleys()
        self.G, self.n, self.chi = G, n_prev, chi
        return snaps

    def condition_scale(self, mean: float, var: float) -> None:
        """Temper in the other cables' scale belief N(mean, var)."""
        self.chi = self.anneal(Target(self.G, self.n), Target(None, 0.0, mean, 1.0 / var), self.chi,
                               principal_axis(self.d))

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
def motion_stages(d: np.ndarray) -> tuple[list[int], int]:
    """Prefix lengths [n1, n2, K] ending the one-axis (shell), two-axis (ring) and full (cluster)
    stages, and the number of independent directions the whole motion covers.

    From the direction of motion, not from positions (VO drift spreads positions in every
    direction): velocities by central differences over +-STAGE_WINDOW poses; poses moving faster
    than STAGE_SLOW times the 95th-percentile speed have a direction. A new axis begins where the
    direction leaves the span of the axes found so far by more than STAGE_OFF_SPAN (sine of the
    angle) for STAGE_WINDOW poses in a row; the stage before it ends at the slowest pose between
    the last motion along the old axes and that point (the turnaround or rest before the new
    axis)."""
    K, w = len(d), STAGE_WINDOW
    if K < 2 * w + 2:
        return [K, K, K], 0
    v = np.zeros_like(d)
    v[w:K - w] = (d[2 * w:] - d[:K - 2 * w]) / (2 * w)
    speed = np.linalg.norm(v, axis=1)
    top = np.percentile(speed, 95)
    if top <= 0:
        return [K, K, K], 0
    moving = speed >= STAGE_SLOW * top
    u = np.where(moving[:, None], v / np.maximum(speed, 1e-300)[:, None], 0.0)
    basis: list[np.ndarray] = []
    starts: list[int] = []
    last_along = 0  # last moving pose along the axes found so far
    k = 0
    while k < K - w and len(basis) < 3:
        if not moving[k]:
            k += 1
            continue
        block = u[k:k + w]
        off = block - sum(np.outer(block @ e, e) for e in basis) if basis else block
        if moving[k:k + w].all() and np.all(np.linalg.norm(off, axis=1) > STAGE_OFF_SPAN):
            if basis:
                gap = speed[last_along:k + 1]
                starts.append(last_along + int(np.argmin(gap)) + 1)  # prefix length: up to the slowest pose
            e = off.mean(axis=0)
            for b in basis:
                e = e - (e @ b) * b
            basis.append(e / np.linalg.norm(e))
            k += w
            continue
        if basis and np.linalg.norm(u[k] - sum((u[k] @ e) * e for e in basis)) <= STAGE_OFF_SPAN:
            last_along = k
        k += 1
    n1 = starts[0] if len(starts) > 0 else K
    n2 = starts[1] if len(starts) > 1 else K
    return [max(n1, 2), max(n2, n1, 2), K], len(basis)


# ------------------------------------------------------------------------------------ the core
@dataclass
class Calibration:
    """What `calibrate` found. Clouds: per stage, (n, 3, m) pulley particles (resampled)."""

    pulley: np.ndarray            # (n, 3) weighted means
    pulley_cov: np.ndarray        # (n, 3, 3)
    length: np.ndarray            # (n,) L0_i: cable length at the first pose (offset = z_i0 - L0_i)
    length_sigma: np.ndarray      # (n,)
    length_guess: np.ndarray      # (n,) nominal L0 (centre of its prior)
    length_at_edge: np.ndarray    # (n,) share of the L0 belief in the outer tenth of its prior
    spread: float                 # half width of the L0 prior
    scale: float
    scale_sigma: float
    scale_per_cable: np.ndarray   # (n, 2) mean, sigma of each cable's own scale belief
    scale_consistency: float      # scatter of the cables' scales over their variances (chi2 / dof)
    fit_rms: np.ndarray           # (n,) exact residual rms of the estimate (m)
    stage_poses: list[int]        # prefix lengths ending the stages
    axes_covered: int
    clouds: list[np.ndarray]
    stage_spread: np.ndarray      # (3, n, 3) principal 1-sigma spreads of the pulley belief, largest first
    particles: int
    seconds: float
    stats: list[dict] = field(default_factory=list)

    def principal_spread(self) -> np.ndarray:
        """(n, 3) principal 1-sigma spreads of the final pulley beliefs, largest first."""
        return np.sqrt(np.clip(np.linalg.eigvalsh(self.pulley_cov), 0, None))[:, ::-1]


def calibrate(c: np.ndarray, d: np.ndarray, z: np.ndarray, L0_guess: np.ndarray, region: tuple,
              scale_range: tuple, sigma: float, *, spread: float = 0.05, particles: int = 5000,
              rng: np.random.Generator | None = None, vo_sigma: tuple[float, float] = (0.0, 0.0),
              frames: np.ndarray | None = None, batch: int = 25, plot_points: int = PLOT_POINTS) -> Calibration:
    """The Monte-Carlo self-calibration on arrays.

    c: (n, K, 3) attachment points at scale 0 (X0 R_k b_i + t0); d: (K, 3) the unscaled VO
    displacement in the base frame (R_X0 t_k); z: (n, K) encoder readings; L0_guess: (n,) nominal
    cable lengths at the first pose; region: (lo, hi) corners of where pulleys may be;
    scale_range: (min, max); sigma: encoder noise (m); spread: L0 prior half width (m);
    vo_sigma: per-frame VO noise (rotation rad, translation in VO units); frames: (K,) VO frames
    since the first pose (default 0, 1, 2, ...). Raises ValueError when the region misses a
    cable's shell."""
    tic = time.perf_counter()
    rng = np.random.default_rng() if rng is None else rng
    n, K = z.shape
    lo, hi = (np.asarray(x, float) for x in region)
    stage_poses, axes = motion_stages(d)
    bounds = sorted(set(list(range(batch, K, batch)) + [K] + stage_poses))
    chol = noise_cholesky(d, sigma, vo_sigma, float(np.sqrt(scale_range[0] * scale_range[1])), frames)
    samplers, clouds = [], []
    for i, r in enumerate(rng.spawn(n)):
        smp = CableSampler(c[i], d, z[i] - z[i, 0], chol, (L0_guess[i] - spread, L0_guess[i] + spread), lo, hi,
                           scale_range, particles, r)
        if not smp.initialize(sigma):
            raise ValueError(f"cable {i}: the region does not meet the sphere of radius {L0_guess[i]:.3f} "
                             f"+- {spread} m around the first attachment point")
        snaps = smp.assimilate(bounds, set(stage_poses))
        clouds.append([snaps[p] for p in stage_poses[:2]])
        samplers.append(smp)

    # the shared scale: product of the cables' beliefs (variances inflated by the scatter of their
    # means when it exceeds them), then each cable conditioned on the others' product
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
    for i, smp in enumerate(samplers):
        if n > 1:
            p = prec.sum() - prec[i]
            smp.condition_scale(float((prec @ own[:, 0] - prec[i] * own[i, 0]) / p), float(1.0 / p))

    pulley, cov, L0, L0s, edge, rms = [], [], [], [], [], []
    for i, smp in enumerate(samplers):
        W, A, lengths = smp.weights(), smp.pulleys(), smp.lengths()
        pulley.append(A @ W)
        cov.append(np.cov(A, aweights=W))
        L0.append(float(W @ lengths))
        L0s.append(float(np.sqrt(W @ (lengths - L0[-1]) ** 2)))
        edge.append(float(W @ (np.abs(lengths - L0_guess[i]) > 0.9 * spread)))
        r = geometric_residuals(c[i], d, z[i] - z[i, 0], pulley[-1], L0[-1], scale)
        rms.append(float(np.sqrt(np.mean(r ** 2))))
        clouds[i].append(smp.resampled_pulleys())
    stage_spread = np.array([[np.sqrt(np.clip(np.linalg.eigvalsh(np.cov(clouds[i][j])), 0, None))[::-1]
                              for i in range(n)] for j in range(3)])
    thin = [np.stack([clouds[i][j][:, rng.choice(particles, min(plot_points, particles), replace=False)]
                      for i in range(n)]) for j in range(3)]
    return Calibration(np.array(pulley), np.array(cov), np.array(L0), np.array(L0s), np.asarray(L0_guess, float),
                       np.array(edge), float(spread), scale, float(np.sqrt(scale_var)),
                       np.column_stack([own[:, 0], np.sqrt(own[:, 1])]), consistency, np.array(rms), stage_poses,
                       axes, thin, stage_spread, particles, time.perf_counter() - tic, [s.stats for s in samplers])
