"""The e-puck's IR proximity sensors (docs/models/epuck.md#ir-sensor-model): the mean reading and its
variance as functions of the distance d (m) from the sensor along its axis to the nearest wall.

Each is a Gaussian sum in x = d / unit (the published fits use unit = 1 cm):

    F(x) = sum_j a_j exp(-((x - b_j) / c_j)^2)

fitted on [d_min, d_max]. A proximity reading does not rise with distance: the mean is the sum's running
minimum from d_min (where a fitted sum rises -- IR6's published fit by 71 counts between 0.5 and 0.64 cm --
the mean stays flat until the sum falls below it again; at the fit's distances, where the sum follows the
measured means down, the two agree). Outside that range the functions are continued so that an estimate which
wanders out of it still feels a gradient: the mean exponentially beyond d_max (positive and C1: the
value and slope at d_max; it decays to 0 at infinity) and linearly below d_min (C1); the variance is
held at its end values. Readings are raw counts. All functions take the distances of many sensors at
once: arrays whose last axis is the sensor (a `Bank` holds every sensor's coefficients, zero-padded
to one number of terms)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GRID = 701  # points on [d_min, d_max] for the variance floor, the running minimum and the inverse lookup


def gaussian_sum(terms: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """F(x) and dF/dx of Gaussian sums: `terms` (S, J, 3) rows (a, b, c) per sensor, x (..., S)."""
    a, b, c = terms[..., 0], terms[..., 1], terms[..., 2]
    u = (np.asarray(x, float)[..., None] - b) / c
    e = a * np.exp(-u * u)
    return e.sum(-1), (-2.0 * u / c * e).sum(-1)


def stack_terms(per_sensor: list[list[list[float]]]) -> np.ndarray:
    """(S, J, 3) coefficients, shorter sums padded with zero terms (a = 0, c = 1)."""
    width = max(len(t) for t in per_sensor)
    out = np.zeros((len(per_sensor), width, 3))
    out[..., 2] = 1.0
    for i, t in enumerate(per_sensor):
        out[i, :len(t)] = np.asarray(t, float).reshape(-1, 3)
    return out


@dataclass
class Evaluation:
    """Mean reading, variance and their derivatives with respect to d (per m), at distances d."""

    mean: np.ndarray
    dmean: np.ndarray
    var: np.ndarray
    dvar: np.ndarray


class Bank:
    """The sensor models of several IR sensors: mean and variance Gaussian sums per sensor, the distance
    unit of their x (m), the range [d_min, d_max] (m) they were fitted on, each sensor's drop-out
    probability (a reading of exactly 0 whatever the distance; default 0) and the reading it saturates at
    (default none)."""

    def __init__(self, mean_terms: list, var_terms: list, unit: float, d_min: float, d_max: float,
                 dropout=None, saturation=None):
        self.mean_terms, self.var_terms = stack_terms(mean_terms), stack_terms(var_terms)
        self.size = len(self.mean_terms)
        self.dropout = np.zeros(self.size) if dropout is None else np.asarray(dropout, float)
        self.saturation = np.full(self.size, np.inf) if saturation is None else np.array(
            [np.inf if v is None else float(v) for v in saturation])
        self.unit, self.d_min, self.d_max = float(unit), float(d_min), float(d_max)
        grid = np.linspace(d_min, d_max, GRID)
        self.grid = grid
        sums = self._sum_inside(np.repeat(grid[:, None], self.size, 1))[0]
        self.sum_rise = (sums - np.minimum.accumulate(sums, axis=0)).max(axis=0)  # counts the envelope flattens
        self.grid_mean = np.minimum.accumulate(sums, axis=0)                      # (GRID, S), non-increasing
        ends = np.array([[d_min] * self.size, [d_max] * self.size])
        m, dm = self._mean_inside(ends)
        v, _ = self._var_inside(ends)
        self.mean_lo, self.slope_lo, self.mean_hi = m[0], dm[0], m[1]
        self.rate_hi = np.minimum(dm[1], 0.0) / m[1]  # 1/m: the exponential continuation's rate (<= 0)
        self.var_lo, self.var_hi = v[0], v[1]
        self.grid_var = self._var_inside(np.repeat(grid[:, None], self.size, 1))[0]
        self.var_floor = 0.9 * self.grid_var.min(axis=0)  # below every variance the model gives
        self.near_threshold = np.minimum(self.grid_mean[0], self.saturation)  # a reading above: closer than d_min,
        # or at the sensor's saturation
        self.far_threshold = self.mean_hi.copy()            # a reading below: nothing within d_max

    def _sum_inside(self, d: np.ndarray, sensor=slice(None)) -> tuple[np.ndarray, np.ndarray]:
        """The mean's Gaussian sum and its derivative (per m) at d inside the range."""
        f, df = gaussian_sum(self.mean_terms[sensor], d / self.unit)
        return f, df / self.unit

    def _mean_inside(self, d: np.ndarray, sensor=slice(None)) -> tuple[np.ndarray, np.ndarray]:
        """The mean at d inside the range: the Gaussian sum's running minimum from d_min (the smallest of the sum at
        d and its grid envelope at the grid point below d), its derivative 0 where the envelope holds it flat."""
        f, df = self._sum_inside(d, sensor)
        j = np.clip(((d - self.d_min) / (self.d_max - self.d_min) * (GRID - 1)).astype(int), 0, GRID - 1)
        columns = np.arange(self.size)[sensor] if isinstance(sensor, slice) else np.asarray(sensor)
        before = self.grid_mean[j, np.broadcast_to(columns, np.shape(d))]
        flat = (before < f) | (df > 0)
        return np.minimum(before, f), np.where(flat, 0.0, df)

    def _var_inside(self, d: np.ndarray, sensor=slice(None)) -> tuple[np.ndarray, np.ndarray]:
        f, df = gaussian_sum(self.var_terms[sensor], d / self.unit)
        return f, df / self.unit

    def evaluate(self, d: np.ndarray, sensor: np.ndarray | None = None) -> Evaluation:
        """The model at distances d in m (inf: nothing along the axis: mean 0): d (..., S) for every
        sensor, or d (R,) of the sensors `sensor` (R,)."""
        d = np.asarray(d, float)
        s = slice(None) if sensor is None else np.asarray(sensor)
        inside = np.clip(d, self.d_min, self.d_max)
        m, dm = self._mean_inside(inside, s)
        v, dv = self._var_inside(inside, s)
        below, above = d < self.d_min, d > self.d_max
        mean_hi, rate_hi = self.mean_hi[s], self.rate_hi[s]
        with np.errstate(invalid="ignore", over="ignore"):  # d = inf: nothing along the axis
            far = np.where(np.isfinite(d), mean_hi * np.exp(rate_hi * (d - self.d_max)), 0.0)
            m = np.where(below, self.mean_lo[s] + self.slope_lo[s] * (d - self.d_min), np.where(above, far, m))
        dm = np.where(below, self.slope_lo[s], np.where(above, rate_hi * far, dm))
        v = np.where(below, self.var_lo[s], np.where(above, self.var_hi[s], v))
        dv = np.where(below | above, 0.0, dv)
        return Evaluation(m, dm, v, dv)

    def inverse(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (m) whose mean reading is z (..., S) and its 1-sigma sigma(d) / |dF/dd| (m); where the mean is
        held flat (a sum that rises: IR3's published fit by 0.3 counts between 4.3 and 4.5 cm) a distance of the
        flat stretch. nan where z is outside the mean's readings over the range (nothing in range, or closer)."""
        z = np.asarray(z, float)
        shape = np.broadcast_shapes(z.shape, (self.size,))
        z = np.broadcast_to(z, shape)
        d = np.full(shape, np.nan)
        for s in range(self.size):
            m, g = self.grid_mean[::-1, s], self.grid[::-1]  # increasing readings
            zs = z[..., s]
            ok = (zs >= m[0]) & (zs <= m[-1])
            d[..., s] = np.where(ok, np.interp(zs, m, g), np.nan)
        for _ in range(3):  # Newton on the exact model where it is monotone (the grid is good to ~1e-6 m)
            e = self.evaluate(np.where(np.isnan(d), self.d_max, d))
            step = np.where(e.dmean < 0, (e.mean - z) / np.where(e.dmean < 0, e.dmean, -1.0), 0.0)
            d = np.clip(d - np.clip(step, -1e-4, 1e-4), self.d_min, self.d_max)
        e = self.evaluate(np.where(np.isnan(d), self.d_max, d))
        return d, np.sqrt(e.var) / np.abs(e.dmean)
