"""Fitting the e-puck's models to calibration data (docs/models/epuck.md#fitting-the-models): pure
functions behind `fusionkit epuck-fit-ir` and `fusionkit epuck-fit-motion`.

IR sensor models. Readings at known distances (the wall perpendicular to the sensor's axis, many
readings per distance) give per distance the mean reading and its variance, drop-outs left out (a
reading of exactly 0 at a distance whose median reading is not: the sensor now and then returns
nothing mid-range). Each is fitted by a
Gaussian sum of 1 to `max_terms` terms in weighted least squares: the mean with the standard error
of the sample mean, s^2 / n, the variance with that of the sample variance, 2 s^4 / (n - 1). A term
is parametrized as A exp(p1 (x - xc) + p2 (x - xc)^2), p2 < 0, xc the data's mean x: the same
function as a exp(-((x - b) / c)^2) (c = 1 / sqrt(-p2), b = xc - p1 / (2 p2), log |a| = log |A| -
p1^2 / (4 p2)) but well conditioned where the (a, b, c) form is not -- a term that is nearly
exponential over the range has a huge a and a far-away b (the published fits have a = 4e17,
b = -168) that trade off along a ridge. The amplitudes A are linear and solved for each (p1, p2)
(variable projection); the best fit is then polished with A, p1, p2 all free. The number of terms
is chosen by BIC = chi^2 + k ln(n); a variance model
must be positive over the range. Quality:
chi^2 per degree of freedom, each distance's residual in its sigmas, and the fitted curve's 1-sigma
at each distance from the parameter covariance.

Velocity-model noise. Repeated trials (straight runs, spins in place, turns in place) each give an
error e for a commanded amount u (distance m, or angle rad). Under the model the error is zero-mean
Gaussian with sigma = alpha |u|: alpha1 = translation error per distance of straight runs, alpha3 =
heading error per distance of straight runs, alpha2 = the centre's travel per angle of spins,
alpha4 = angle error per angle of turns. The maximum-likelihood alpha is sqrt(mean((e / u)^2)),
with 1-sigma alpha / sqrt(2 n) and a 95 % interval from the chi-square distribution; the mean
e / u with its standard error says whether the errors are systematic (a calibration error) rather
than noise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .irmodel import gaussian_sum

CURVATURE = (None, np.log(100.0))  # w's upper bound: p2 = -(p1^2 / (4 LOG_A_ROOM) + exp(w)), c >= 0.1
CANCELLATION = 1e4         # no term may exceed the data by more (terms that cancel are refused)
LOG_A_ROOM = 100.0         # p1^2 / (4 |p2|) <= this: log|a| stays representable (the published fits: <= 41)
WIDTHS = (0.5, 1.5, 5.0, 30.0)          # start values of a new term's c (x-units)
BEAM = 1                   # fits carried to the next number of terms
FAR = (5.0, 30.0)                        # and of its b: the data's x, and this far below the smallest
KINDS = {0: "straight", 1: "spin", 2: "turn"}
VARIANCE_ROUNDS = 2        # refits of the variance weighted by the fitted variance
ENVELOPE_GRID = 400        # points of the running minimum of a falling fit
DROPOUT_SIGMAS = 3.0       # a 0 is a drop-out where the non-zero readings' mean is this many of their sigmas above 0


@dataclass
class CurveFit:
    """A fitted Gaussian sum: its terms [a, b, c] (x in the fit's unit), the candidates tried
    ({terms: {chi2, bic, chi2_per_dof}}), chi^2 and degrees of freedom, residuals in sigmas and the
    curve's 1-sigma at the data's x."""

    terms: list[list[float]]
    chi2: float
    dof: int
    candidates: dict[int, dict[str, float]]
    residual_sigmas: np.ndarray
    curve_sigma: np.ndarray

    @property
    def chi2_per_dof(self) -> float:
        return self.chi2 / self.dof if self.dof > 0 else float("nan")


class _Problem:
    """Weighted data y(x) +- se and Gaussian terms A exp(p1 u + p2 u^2), u = x - xc. The search varies
    (p1, w) per term, p2 = -(p1^2 / (4 LOG_A_ROOM) + exp(w)), and solves the amplitudes linearly
    (variable projection: a term's sign comes out of the linear solve); the best fits are then
    polished with every (A, p1, p2) free. A fit is a tuple (chi2, p1, p2, A, terms)."""

    def __init__(self, x, y, se, positive_grid, falling: bool = False):
        self.x, self.y, self.se, self.grid = x, y, se, positive_grid
        self.xc = float(np.mean(x))
        # falling: a fit is judged by its running minimum from min(x) (the proximity model irmodel.Bank uses), on a
        # grid that holds the data's x
        self.envelope_x = np.union1d(np.linspace(x.min(), x.max(), ENVELOPE_GRID), x) if falling else None

    def curve(self, p1: np.ndarray, p2: np.ndarray, A: np.ndarray) -> np.ndarray:
        """The curve at the data's x: the Gaussian sum, or (falling) its running minimum from min(x)."""
        if self.envelope_x is None:
            return self.basis(p1, p2, self.x) @ A
        low = np.minimum.accumulate(self.basis(p1, p2, self.envelope_x) @ A)
        return low[np.searchsorted(self.envelope_x, self.x)]

    @staticmethod
    def slopes(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p1, p2) of each term from the searched (p1, w): curved enough that log|a| stays within
        LOG_A_ROOM of log|A| (a nearly exponential term keeps a finite c)."""
        q = q.reshape(-1, 2)
        return q[:, 0], -(q[:, 0] ** 2 / (4.0 * LOG_A_ROOM) + np.exp(np.minimum(q[:, 1], CURVATURE[1])))

    def basis(self, p1: np.ndarray, p2: np.ndarray, x: np.ndarray) -> np.ndarray:
        u = x[:, None] - self.xc
        return np.exp(np.clip(p1 * u + p2 * u * u, -700.0, 700.0))

    def amplitudes(self, q: np.ndarray) -> np.ndarray:
        B = self.basis(*self.slopes(q), self.x) / self.se[:, None]
        return np.linalg.lstsq(B, self.y / self.se, rcond=None)[0]

    def residual(self, q: np.ndarray) -> np.ndarray:
        return (self.basis(*self.slopes(q), self.x) @ self.amplitudes(q) - self.y) / self.se

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Kaufman's approximation of the projected residual's Jacobian: (I - P) W dPhi/dq A."""
        p1, p2 = self.slopes(q)
        B = self.basis(p1, p2, self.x) / self.se[:, None]
        A = np.linalg.lstsq(B, self.y / self.se, rcond=None)[0]
        Q = np.linalg.qr(B)[0]
        w = q.reshape(-1, 2)[:, 1]
        dp2_dw = np.where(w < CURVATURE[1], p2 + p1 ** 2 / (4.0 * LOG_A_ROOM), 0.0)
        u = (self.x - self.xc)[:, None]
        J = np.empty((len(self.x), len(q)))
        J[:, 0::2] = B * A * (u - u * u * p1 / (2.0 * LOG_A_ROOM))
        J[:, 1::2] = B * A * u * u * dp2_dw
        return J - Q @ (Q.T @ J)

    def start(self, b: float, c: float) -> np.ndarray:
        """(p1, w) of a term centred at b with width c (x-units)."""
        p1 = 2.0 * (b - self.xc) / c ** 2
        return np.array([p1, np.log(max(1.0 / c ** 2 - p1 ** 2 / (4.0 * LOG_A_ROOM), 1e-12))])

    def solve(self, q0: np.ndarray):
        """The search from q0: a fit, or None (not representable or admissible, or a start or step where the
        linear algebra fails: one diverging start must not stop the others)."""
        from scipy.optimize import least_squares
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            try:
                if not np.all(np.isfinite(self.residual(q0))):
                    return None
                sol = least_squares(self.residual, q0, jac=self.jacobian, method="lm", max_nfev=50 * len(q0))
                return self.admit(*self.slopes(sol.x), self.amplitudes(sol.x))
            except (np.linalg.LinAlgError, ValueError):
                return None

    def free_residual(self, v: np.ndarray) -> np.ndarray:
        v = v.reshape(-1, 3)
        return (self.basis(v[:, 1], v[:, 2], self.x) @ v[:, 0] - self.y) / self.se

    def free_jacobian(self, v: np.ndarray) -> np.ndarray:
        v = v.reshape(-1, 3)
        return self.full_jacobian(v[:, 1], v[:, 2], v[:, 0])

    def polish(self, fit):
        """The fit refined with every A, p1, p2 free (p2 < 0), if that lowers chi^2 and stays admissible."""
        from scipy.optimize import least_squares
        chi2, p1, p2, A, _ = fit
        n = len(A)
        lo, hi = np.tile([-np.inf, -np.inf, -np.inf], n), np.tile([np.inf, np.inf, -1e-9], n)
        start = np.column_stack([A, p1, np.minimum(p2, -2e-9)]).ravel()
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            try:
                sol = least_squares(self.free_residual, start, jac=self.free_jacobian, bounds=(lo, hi),
                                    method="trf", x_scale="jac", max_nfev=200)
            except (np.linalg.LinAlgError, ValueError):
                return fit
            v = sol.x.reshape(-1, 3)
            better = self.admit(v[:, 1], v[:, 2], v[:, 0])
        return better if better is not None and better[0] < chi2 else fit

    def admit(self, p1: np.ndarray, p2: np.ndarray, A: np.ndarray):
        """(chi2, p1, p2, A, terms), or None when terms cancel each other (their (a, b, c) would lose
        every digit), a variance model is not positive, or a term has no (a, b, c) form."""
        parts = np.abs(self.basis(p1, p2, self.x) * A)
        if not np.all(np.isfinite(parts)) or parts.max() > CANCELLATION * np.abs(self.y).max():
            return None
        if self.grid is not None and not np.min(self.basis(p1, p2, self.grid) @ A) > 0:
            return None
        terms = []
        for a1, a2, amp in zip(p1, p2, A):
            log_a = np.log(abs(amp)) - a1 * a1 / (4.0 * a2) if amp != 0 else np.inf
            if not np.isfinite(log_a) or log_a > 650.0:
                return None
            terms.append([float(np.sign(amp) * np.exp(log_a)), float(self.xc - a1 / (2.0 * a2)),
                          float(1.0 / np.sqrt(-a2))])
        chi2 = float(np.sum(((self.curve(p1, p2, A) - self.y) / self.se) ** 2))
        return chi2, p1, p2, A, terms

    def full_jacobian(self, p1: np.ndarray, p2: np.ndarray, A: np.ndarray) -> np.ndarray:
        """d(whitened residual) / d(A_j, p1_j, p2_j) for every term."""
        phi = self.basis(p1, p2, self.x) / self.se[:, None]
        u = (self.x - self.xc)[:, None]
        cols = [np.stack([phi[:, j], A[j] * phi[:, j] * u[:, 0], A[j] * phi[:, j] * u[:, 0] ** 2], 1)
                for j in range(len(A))]
        return np.concatenate(cols, 1)


def fit_gaussian_sum(x: np.ndarray, y: np.ndarray, se: np.ndarray, max_terms: int = 3,
                     positive: bool = False, falling: bool = False) -> CurveFit:
    """Fit y(x) +- se by Gaussian sums of 1..max_terms terms (3 parameters each, fewer than the points)
    and keep the one with the smallest BIC. Each number of terms starts from the BEAM best distinct fits
    with one term fewer, plus a new term centred at every other data point or far below them, in
    several widths (two terms: also a decay from far below with a bump at each data point).
    `positive`: the curve must be > 0 between min(x) and max(x). `falling` (x increasing): the fits are compared
    (chi^2, BIC, residuals) by their running minimum from min(x), the non-rising mean irmodel.Bank makes of them, so
    a sum that dips between two distances and rises again loses to one that does not."""
    x, y, se = (np.asarray(a, float) for a in (x, y, se))
    problem = _Problem(x, y, se, np.linspace(x.min(), x.max(), 200) if positive else None, falling)
    centres = list(x[::2]) + [x.min() - f for f in FAR] + [x.max() + f for f in FAR]
    new = [problem.start(b, c) for b in centres for c in WIDTHS]
    candidates, fits, beam = {}, {}, [np.zeros(0)]
    for n_terms in range(1, max_terms + 1):
        if 3 * n_terms >= len(x):
            break
        starts = [np.concatenate([seed, term]) for seed in beam for term in new]
        decay = problem.start(x.min() - FAR[1], FAR[1])
        if n_terms == 2:
            starts += [np.concatenate([decay, problem.start(b, c)]) for b in x for c in WIDTHS[:2]]
        if n_terms == 3:  # a decay, a narrow bump at a data point and a broad one about the near end
            starts += [np.concatenate([decay, problem.start(b, WIDTHS[1]), problem.start(b2, WIDTHS[2])])
                       for b in x[::2] for b2 in (x.min() - 1.0, x.min(), x.min() + 1.0)]
        solutions = sorted((s for s in map(problem.solve, starts) if s is not None), key=lambda s: s[0])
        if not solutions:
            break
        best = problem.polish(solutions[0])
        candidates[n_terms] = {"chi2": best[0], "bic": best[0] + 3 * n_terms * np.log(len(x)),
                               "chi2_per_dof": best[0] / (len(x) - 3 * n_terms)}
        fits[n_terms] = best
        beam = _distinct([np.column_stack([s[1], np.log(np.maximum(-s[2] - s[1] ** 2 / (4.0 * LOG_A_ROOM), 1e-30))]).ravel()
                          for s in solutions], BEAM)
    if not fits:
        raise ValueError("no Gaussian sum fits these points")
    chosen = min(candidates, key=lambda k: candidates[k]["bic"])
    chi2, p1, p2, A, terms = fits[chosen]
    # the curve's covariance is diag(se) J (J^T J)^-1 J^T diag(se) (whitened residuals): J's hat matrix,
    # the projection onto its column space -- computed from the SVD, stable where the terms are not
    U, sv, _ = np.linalg.svd(problem.full_jacobian(p1, p2, A), full_matrices=False)
    U = U[:, sv > 1e-12 * sv[0]]
    curve_sigma = se * np.sqrt(np.sum(U * U, axis=1))
    residual = (y - problem.curve(p1, p2, A)) / se
    return CurveFit(terms, chi2, len(x) - 3 * chosen, candidates, residual, curve_sigma)


def _distinct(solutions: list[np.ndarray], count: int) -> list[np.ndarray]:
    """The first `count` of the (sorted) solutions that differ from those kept before them."""
    kept: list[np.ndarray] = []
    for q in solutions:
        if all(np.max(np.abs(q - k)) > 1e-3 for k in kept):
            kept.append(q)
        if len(kept) == count:
            break
    return kept


@dataclass
class SensorFit:
    """A sensor's calibration: per distance (x units) the count, mean and variance of its readings,
    and the two fitted curves."""

    x: np.ndarray
    count: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    mean_fit: CurveFit
    var_fit: CurveFit
    dropped: int = 0        # drop-outs left out of the curves (`dropouts`)
    dropout: float = 0.0    # their probability: drop-outs per reading where they are told apart
    saturation: float | None = None  # the reading the sensor clips at (`saturation_level`), if it does
    saturated: int = 0      # distances left out of the curves: their median reading is the saturation
    clipped: int = 0        # distances left out of the curves: from the first with a reading clipped at 0 on


def in_units(distance: np.ndarray, unit: float) -> np.ndarray:
    """Distances (m) in the fit's x unit, rounded so that readings at one distance share one x."""
    return np.round(np.asarray(distance, float) / unit, 9)


def dropout_distances(distance: np.ndarray, reading: np.ndarray, unit: float) -> np.ndarray:
    """Which readings lie at a distance where a 0 is a drop-out, not a weak reading: the distance's non-zero readings
    (two or more) have a mean DROPOUT_SIGMAS of their standard deviations above 0 (there a sensor that returns
    nothing now and then is told apart; where the signal is near 0 a 0 is a reading clipped at 0)."""
    x = in_units(distance, unit)
    out = np.zeros(len(x), bool)
    for v in np.unique(x):
        at = x == v
        signal = reading[at & (reading != 0)]
        if len(signal) >= 2 and signal.mean() > DROPOUT_SIGMAS * signal.std(ddof=1):
            out |= at
    return out


def dropouts(distance: np.ndarray, reading: np.ndarray, unit: float) -> np.ndarray:
    """Which readings are drop-outs: exactly 0 where dropout_distances tells a 0 apart from a weak reading."""
    return dropout_distances(distance, reading, unit) & (np.asarray(reading) == 0)


def saturation_level(distance: np.ndarray, reading: np.ndarray, unit: float) -> float | None:
    """The reading a sensor clips at: its largest reading, when at some distance every reading (two or more) is
    that value (an ADC at its top near the wall reads one value), else None."""
    reading = np.asarray(reading, float)
    top = float(reading.max())
    x = in_units(distance, unit)
    for v in np.unique(x[reading == top]):
        at = reading[x == v]
        if len(at) >= 2 and np.all(at == top):
            return top
    return None


def distance_statistics(distance: np.ndarray, reading: np.ndarray, unit: float) -> tuple[np.ndarray, ...]:
    """Per distinct distance (m, in x = distance / unit): count, mean and sample variance of the readings."""
    x = in_units(distance, unit)
    xs = np.unique(x)
    count = np.array([np.sum(x == v) for v in xs])
    mean = np.array([reading[x == v].mean() for v in xs])
    var = np.array([reading[x == v].var(ddof=1) if c > 1 else np.nan for v, c in zip(xs, count)])
    return xs, count, mean, var


def fit_sensor(distance: np.ndarray, reading: np.ndarray, unit: float = 0.01, max_terms: int = 3) -> SensorFit:
    """Mean and variance models of one sensor from its readings at known distances (m): drop-outs (`dropouts`) left
    out of both, their probability estimated; distances read at the sensor's saturation (`saturation_level`) left
    out of both (they say only "at least that"), and the distances from the first with a reading clipped at 0 (not a
    drop-out) on (only "at most": the signal is weak there): the models hold between the first and last distance
    fitted (`x`), readings outside are censored; the mean judged as the non-rising running minimum the model uses
    (`fit_gaussian_sum`'s `falling`); a sample variance no smaller than an integer
    reading's quantization (1/12 count^2) where the readings are counts (a saturated sensor reads one value)."""
    reading = np.asarray(reading, float)
    eligible = dropout_distances(distance, reading, unit)
    dropped = eligible & (reading == 0)
    probability = float(dropped.sum() / eligible.sum()) if eligible.any() else 0.0
    distance, reading = np.asarray(distance)[~dropped], reading[~dropped]
    saturation = saturation_level(distance, reading, unit)
    x, count, mean, var = distance_statistics(distance, reading, unit)
    if np.any(count < 2):
        raise ValueError(f"each distance needs two or more readings; {np.sum(count < 2)} distance(s) have one")
    xs = in_units(distance, unit)
    # a distance read at the saturation says only "at least that", one with readings clipped at 0 (a weak signal)
    # only "at most": neither gives a mean or a variance
    flat = np.array([saturation is not None and np.median(reading[xs == v]) >= saturation for v in x])
    weak = np.array([np.any(reading[xs == v] == 0) for v in x])
    weak |= np.cumsum(weak) > 0  # from the first such distance on: the range ends where the signal gets weak
    x, count, mean, var = (a[~flat & ~weak] for a in (x, count, mean, var))
    if len(x) < 4:
        raise ValueError(f"{len(x)} distinct distances{' below saturation' if flat.any() else ''}: a one-term fit "
                         "needs 4 or more")
    var = np.maximum(var, 1.0 / 12.0 if np.all(reading == np.round(reading)) else 1e-12)
    mean_fit = fit_gaussian_sum(x, mean, np.sqrt(var / count), max_terms, falling=True)
    # what a new reading varies by about the fitted mean: its own variance, the fitted mean's uncertainty, and the
    # mean's misfit beyond its standard error
    misfit = np.maximum((mean_fit.residual_sigmas ** 2 - 1.0) * var / count, 0.0)
    target = var + mean_fit.curve_sigma ** 2 + misfit
    var_fit = fit_gaussian_sum(x, target, var * np.sqrt(2.0 / (count - 1)), max_terms, positive=True)
    for _ in range(VARIANCE_ROUNDS):  # weights from the fitted variance, not the sample's own (which favour low ones)
        fitted = np.maximum(gaussian_sum(np.asarray(var_fit.terms, float)[None], x[:, None])[0][:, 0], var.min())
        var_fit = fit_gaussian_sum(x, target, fitted * np.sqrt(2.0 / (count - 1)), max_terms, positive=True)
    return SensorFit(x, count, mean, var, mean_fit, var_fit, int(dropped.sum()), probability, saturation,
                     int(flat.sum()), int(weak.sum()))


def sensor_bank(model: dict, unit: float, ir_range) -> "Bank":
    """A Bank of one sensor from its description entry (mean, variance, dropout, saturation) on ir_range (m)."""
    from .irmodel import Bank
    return Bank([model["mean"]], [model["variance"]], unit, ir_range[0], ir_range[1], [model.get("dropout", 0.0)],
                [model.get("saturation")])


def coverage(bank, distance: np.ndarray, reading: np.ndarray, sigmas=(1.0, 2.0, 3.0)) -> np.ndarray:
    """Percent of readings inside 1, 2, 3 sigma of one sensor's model (`bank`, a Bank of one sensor) at known
    distances (m), drop-outs included: a reading's probability integral transform F(z) under the model, readings
    clipped at 0 (F(z) = pi + (1 - pi) Phi((z - m) / sigma) for z >= 0: a reading of 0 has the point mass F(0), its
    transform the interval 0 .. F(0), counted by the share of it inside; a reading at the sensor's saturation the
    interval F(sat) .. 1); k sigma is the central interval
    Phi(-k) .. Phi(k) of the transform, where a Gaussian reading within k sigma falls."""
    from scipy.special import ndtr
    ev = bank.evaluate(np.asarray(distance, float), np.zeros(len(distance), int))
    sigma = np.sqrt(np.maximum(ev.var, np.finfo(float).tiny))  # a variance fitted to 0 somewhere: a point mass
    pi, top = float(bank.dropout[0]), float(bank.saturation[0])
    reading = np.asarray(reading, float)
    cdf = pi + (1.0 - pi) * ndtr((reading - ev.mean) / sigma)
    lo = np.where(reading == 0, 0.0, cdf)
    hi = np.where(reading >= top, 1.0, cdf)
    out = []
    for k in sigmas:
        a, b = ndtr(-k), ndtr(k)
        width = hi - lo
        share = np.where(width > 0, np.clip(np.minimum(hi, b) - np.maximum(lo, a), 0.0, None) / np.where(width > 0, width, 1.0),
                         (lo > a) & (lo < b))
        out.append(100.0 * float(np.mean(share)))
    return np.array(out)


@dataclass
class AlphaFit:
    """One alpha: its maximum-likelihood value, 1-sigma, 95 % interval, the trials it came from, and
    the mean error per unit with its standard error (systematic errors show there)."""

    value: float
    sigma: float
    interval: tuple[float, float]
    trials: int
    mean_ratio: float
    mean_ratio_sigma: float
    mean_abs_ratio: float = field(default=float("nan"))


def fit_alpha(error: np.ndarray, commanded: np.ndarray) -> AlphaFit:
    """alpha of sigma = alpha |u| from errors e of commanded amounts u (zero-mean Gaussian model)."""
    from scipy.stats import chi2 as chi2_dist
    r = np.asarray(error, float) / np.abs(np.asarray(commanded, float))
    n = len(r)
    value = float(np.sqrt(np.mean(r * r)))
    interval = (value * np.sqrt(n / chi2_dist.ppf(0.975, n)), value * np.sqrt(n / chi2_dist.ppf(0.025, n)))
    return AlphaFit(value, value / np.sqrt(2.0 * n), interval, n, float(r.mean()),
                    float(r.std(ddof=1) / np.sqrt(n)) if n > 1 else float("nan"), float(np.mean(np.abs(r))))


def fit_alphas(kind: np.ndarray, commanded: np.ndarray, translation_error: np.ndarray,
               rotation_error: np.ndarray) -> dict[str, AlphaFit]:
    """alpha1..alpha4 from trials: kind 0 straight (commanded m), 1 spin, 2 turn (commanded rad)."""
    kind = np.asarray(kind).astype(int)
    out = {}
    for name, k, err in (("alpha1", 0, translation_error), ("alpha2", 1, translation_error),
                         ("alpha3", 0, rotation_error), ("alpha4", 2, rotation_error)):
        rows = kind == k
        if rows.sum() >= 2:
            out[name] = fit_alpha(np.asarray(err)[rows], np.asarray(commanded)[rows])
    return out
