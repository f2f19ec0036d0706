"""The IR readings of one state as one factor (docs/models/epuck.md#ir-factor): the residual and its
Jacobians with respect to the Pose2 and each reading's gain and offset.

Reading z of sensor s at distance d (walls.sensor_distances) is modelled as
z ~ N(g_s F_mean(d) + o_s, F_var(d)), g_s and o_s optional calibration parameters (gain 1, offset 0
without them). An in-range reading contributes

    e1 = (z - g F_mean(d) - o) / sqrt(F_var(d))          (whitened; d(1/sqrt F_var)/dd included)
    e2 = sqrt(log(F_var(d) / v0))                        (noise: full; v0 below every F_var)

so that (e1^2 + e2^2) / 2 = (z - mean)^2 / (2 var) + log(var) / 2 + const is the exact negative
log-likelihood of the heteroscedastic Gaussian (`noise: whitened` drops e2; `noise: at_reading`
divides by the sigma at the reading's inverse-lookup distance, fixed when the graph is built;
`outlier_k`, used by the initializer's forward pass: e1 through a Cauchy loss, `cauchy_rows`). A
reading below the far threshold F_mean(d_max) (nothing within range) or above the near one (closer
than d_min) is censored: it says only that the reading fell on that side of the threshold, with
probability Phi(-u), u = sign (g F_mean(d) + o - threshold) / sqrt(F_var(d)) (sign +1 far, -1 near);
its residual e = sqrt(-2 log Phi(-u)) makes e^2 / 2 exactly that negative log-likelihood. A sensor with a
drop-out probability pi (`dropout:` in the description: it returns 0 now and then whatever the distance) reads 0
with probability pi + (1 - pi) Phi(-u): a reading of 0 then costs at most -log pi, wherever the wall is.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .irmodel import Bank
from .walls import ray_distances

IN, FAR, NEAR = 0, 1, 2
NOISE_MODES = ("full", "whitened", "at_reading")
HALF_LOG_2PI = 0.5 * np.log(2.0 * np.pi)


def censored_residual(u: np.ndarray, dropout=None) -> tuple[np.ndarray, np.ndarray]:
    """e = sqrt(-2 log Phi(-u)) and de/du, stable for any u (e -> 0 as u -> -inf). With `dropout` pi (per u,
    > 0 where a reading may be a drop-out): e = sqrt(-2 log(pi + (1 - pi) Phi(-u))), bounded by
    sqrt(-2 log pi)."""
    from scipy.special import log_ndtr
    u = np.asarray(u, float)
    if dropout is not None and np.any(dropout > 0):
        e, de = censored_residual(u)
        pi = np.broadcast_to(np.asarray(dropout, float), u.shape)
        mixed = pi > 0
        p = pi + (1.0 - pi) * np.exp(log_ndtr(-u))
        e_mix = np.sqrt(np.maximum(-2.0 * np.log(p), 0.0))
        pdf = np.exp(-0.5 * u * u - HALF_LOG_2PI)
        de_mix = (1.0 - pi) * pdf / (p * np.maximum(e_mix, 1e-12))
        return np.where(mixed, e_mix, e), np.where(mixed, de_mix, de)
    log_pdf = -0.5 * u * u - HALF_LOG_2PI
    lc = log_ndtr(-u)                      # log Phi(-u) <= 0
    c = -lc
    big = c > 1e-12
    e_big = np.sqrt(2.0 * np.where(big, c, 1.0))
    # small c: -log(1 - Phi(u)) ~ Phi(u), so e ~ sqrt(2 Phi(u)) and de/du ~ phi(u) / e
    log_phi_u = log_ndtr(np.where(big, -1.0, u))
    e_small = np.exp(0.5 * (np.log(2.0) + log_phi_u))
    de_small = np.exp(log_pdf - 0.5 * np.log(2.0) - 0.5 * log_phi_u)
    e = np.where(big, e_big, e_small)
    de = np.where(big, np.exp(log_pdf - lc) / e_big, de_small)
    return e, de


def cauchy_rows(e: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
    """e' = k sign(e) sqrt(log(1 + (e/k)^2)) and de'/de: e'^2 / 2 is the Cauchy loss of e, so a reading
    the model cannot explain pulls with a bounded force (per reading, unlike a kernel on the factor)."""
    r = (e / k) ** 2
    L = np.log1p(r)
    small = r < 1e-12
    root = np.sqrt(np.where(small, 1.0, L))
    out = np.where(small, e, k * np.sign(e) * root)
    slope = np.where(small, 1.0, np.abs(e) / k / (root * (1.0 + r)))
    return out, slope


@dataclass
class ReadingSet:
    """Readings: sensor index into the layout (R,), reading z (counts), kind (IN, FAR, NEAR), the
    threshold of censored ones, and for `noise: at_reading` the fixed sigma (1 for censored ones)."""

    sensor: np.ndarray
    z: np.ndarray
    kind: np.ndarray
    threshold: np.ndarray
    sigma_fixed: np.ndarray
    _rows: dict = field(default_factory=dict, repr=False)

    def rows(self, noise: str) -> tuple[np.ndarray, np.ndarray]:
        """The residual's rows as (component, reading): e1 of the in-range readings, then (noise: full)
        their e2, then the censored ones' e (components 0, 1, 2 of `Quantities`)."""
        if noise not in self._rows:
            self._rows[noise] = self._make_rows(noise)
        return self._rows[noise]

    def _make_rows(self, noise: str) -> tuple[np.ndarray, np.ndarray]:
        inside = np.flatnonzero(self.kind == IN)
        parts = [(0, inside)] + ([(1, inside)] if noise == "full" else []) + [(2, np.flatnonzero(self.kind != IN))]
        return (np.concatenate([np.full(len(r), c) for c, r in parts]).astype(int),
                np.concatenate([r for _, r in parts]).astype(int))


@dataclass
class Quantities:
    """Per reading r and residual component c (0: e1, 1: e2, 2: censored e): the value e[c, r] and its
    derivatives with respect to the distance, the gain and the offset; dd/dxi[r] (R, 3) of its ray.
    Only the components a reading's kind and the noise mode use are meaningful."""

    e: np.ndarray
    de_dd: np.ndarray
    de_dgain: np.ndarray
    de_doffset: np.ndarray
    dd_dpose: np.ndarray


class IrModelContext:
    """What every IR factor of an entry shares: the walls, the sensors' mounts, angles and models, and
    the noise mode."""

    def __init__(self, walls: np.ndarray, mounts: np.ndarray, angles: np.ndarray, bank: Bank, noise: str,
                 outlier_k: float | None = None):
        assert noise in NOISE_MODES
        self.walls, self.mounts, self.angles, self.bank, self.noise = walls, mounts, angles, bank, noise
        self.outlier_k = outlier_k

    def quantities(self, pose: np.ndarray, readings: ReadingSet, gain: np.ndarray, offset: np.ndarray) -> Quantities:
        """Residual components and derivatives of readings taken at poses (R, 3) (x, y, theta) with
        gains and offsets (R,)."""
        s = readings.sensor
        d, dd = ray_distances(self.walls, pose, self.mounts[s], self.angles[s], jacobian=True)
        ev = self.bank.evaluate(d, s)
        mu, dmu, var, dvar = ev.mean, ev.dmean, ev.var, ev.dvar
        sigma = np.sqrt(var)
        pred = gain * mu + offset
        inside = readings.kind == IN
        if self.noise == "at_reading":
            scale, dlog_scale = readings.sigma_fixed, 0.0
        else:
            scale, dlog_scale = sigma, dvar / (2.0 * var)
        e1 = (readings.z - pred) / scale
        de1 = -gain * dmu / scale - e1 * dlog_scale
        de1_dgain, de1_doffset = -mu / scale, -1.0 / scale
        if self.outlier_k:
            e1, slope = cauchy_rows(e1, self.outlier_k)
            de1, de1_dgain, de1_doffset = slope * de1, slope * de1_dgain, slope * de1_doffset
        e2 = np.sqrt(np.log(var / self.bank.var_floor[s]))
        de2 = dvar / (2.0 * var * e2)
        sign = np.where(readings.kind == FAR, 1.0, -1.0)
        u = np.where(inside, 0.0, sign * (pred - readings.threshold) / sigma)
        dropout = np.where((readings.kind == FAR) & (readings.z == 0.0), self.bank.dropout[s], 0.0)
        ec, dec = censored_residual(u, dropout)
        dec_dd = dec * (sign * gain * dmu / sigma - u * dvar / (2.0 * var))
        zero = np.zeros_like(e1)
        return Quantities(np.stack([e1, e2, ec]), np.stack([de1, de2, dec_dd]),
                          np.stack([de1_dgain, zero, dec * sign * mu / sigma]),
                          np.stack([de1_doffset, zero, dec * sign / sigma]), dd)

    def residual(self, pose: np.ndarray, readings: ReadingSet, gain: np.ndarray, offset: np.ndarray,
                 jacobians: bool = False):
        """One state's residual e and, with `jacobians`, de/dpose (rows, 3), de/dgain (rows, R) and
        de/doffset (rows, R) (reading j's gain and offset are column j). pose (3,); gain, offset (R,)."""
        R = len(readings.sensor)
        q = self.quantities(np.tile(pose, (R, 1)), readings, gain, offset)
        comp, reading = readings.rows(self.noise)
        return assemble(q, comp, reading, reading, R, jacobians)


def assemble(q: Quantities, comp: np.ndarray, reading: np.ndarray, column: np.ndarray, width: int,
             jacobians: bool):
    """A factor's residual from quantities: rows (comp, reading), `column` (per row) the reading's
    column in the gain and offset blocks (`width` wide)."""
    e = q.e[comp, reading]
    if not jacobians:
        return e
    rows = np.arange(len(e))
    Hg, Ho = np.zeros((len(e), width)), np.zeros((len(e), width))
    Hg[rows, column] = q.de_dgain[comp, reading]
    Ho[rows, column] = q.de_doffset[comp, reading]
    return e, q.de_dd[comp, reading][:, None] * q.dd_dpose[reading], Hg, Ho
