"""Health of a solve from the data alone, no ground truth: where the estimate does not fit, and whether an
incremental solver (iSAM2, fixed-lag) lost track.

An incremental solver hands out an estimate after every time step and takes one Gauss-Newton step per update:
it can lose track (a window that diverged, a calibration parameter frozen at a poor first estimate, a new state
far from its prediction) and still end with a plausible total cost. The checks:

- **fit per window** (`window_fit`, `misfit_windows`): the run is cut into windows (fixed-lag: `solver.lag`
  seconds; otherwise a twentieth of the run, at least a second) by factor time; each window's chi-square per
  degree of freedom, dof = its factors' dimensions minus its states'. For the fixed-lag smoother, a window is
  judged as the smoother believed it when the window was complete: its estimate at the first update at or after
  the window's end (which holds the window's states and the static variables; states before it as they left).
  A window is beyond chance when its chi-square passes the 1 - WINDOW_P quantile for its dof, and misfits when it is also WINDOW_FACTOR times the median window's ratio (at least 1).
- **lost track or the data** (`fit_check`): a window that fits badly has two causes, the data (a wheel slip, an
  outlier burst the model does not explain: the best fit misfits there too) or the solver. For an incremental
  run with a window beyond chance, the whole graph is polished by Levenberg-Marquardt from its estimate (the
  cost of a batch solve started near its end); windows the polish fits clearly better (chi-square down by more
  than the 1 - WINDOW_P quantile, and chi2/dof WINDOW_FACTOR times the best fit's, at least 1) are where the
  solver lost track (warning `incremental_fit`, the spans named); in more than LOST_SHARE of the windows, or
  GROSS_FACTOR times worse than the best fit in one, the run is rejected (one window lost and recovered is a
  warning). Misfit windows otherwise, and always for batch (its estimate is the
  best fit), are a warning `local_misfit` naming the span.
- **revisions beyond sigma** (`RevisionMonitor`, `jump_check`): after each time step, the estimate and marginal
  covariance of the newest state of each robot and of every static variable are kept; at the next step, the
  revision of each (Delta^T P^-1 Delta, Delta in its tangent space) is the update's innovation seen in the
  state: a consistent smoother's revision has a covariance no larger than P, so d^2 beyond the chi-square's
  1 - JUMP_P quantile means the estimate handed out live was not within its sigmas: warning
  `incremental_jumps` with the updates' times (the final estimate is judged by the fit check).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from ..graph.builder import Problem
from ..graph.keys import STATE
from .result import SolveWarning
from .chi_square import quantile

WINDOW_FACTOR = 10.0  # a window's chi2/dof this many times the median window's (at least 1) fails
WINDOW_P = 1e-6  # ... when also beyond the chi-square's 1 - WINDOW_P quantile for its dof
JUMP_P = 1e-4  # a revision beyond the chi-square's 1 - JUMP_P quantile for the variable's dimension is a jump
LOST_SHARE = 0.05  # lost track in more than this share of the windows: the run is rejected (fewer: a warning)
GROSS_FACTOR = 100.0  # ... or in one window this many times worse than the best fit (at least 1 per dof)
POLISH_ITERATIONS = 30  # Levenberg-Marquardt iterations of the polish that confirms a lost track
MONITORED_DIM = 60  # static variables watched for jumps, at most this total dimension (the covariances cost)


@dataclass
class Revision:
    """The largest revision of one time step: when, which variable, d^2 and the dimension it is judged with."""

    t: float
    key: int
    d2: float
    dim: int

    @property
    def jump(self) -> bool:
        return self.d2 > quantile(1 - JUMP_P, self.dim)


@dataclass
class RevisionMonitor:
    """Watches the estimate an incremental solver hands out at each time step (module docstring)."""

    problem: Problem
    static: list[int] = field(default_factory=list)
    revisions: list[Revision] = field(default_factory=list)
    _last: dict[int, tuple] = field(default_factory=dict)  # key -> (value, inverse covariance)
    _newest: dict[int, tuple[int, int]] = field(default_factory=dict)  # state family id -> (index, key), newest

    def __post_init__(self):
        total = 0
        for k in sorted(k for k, t in self.problem.key_time.items() if t == float("-inf")):
            dim = self.problem.keys.decode(k)[0].vartype.dim
            if total + dim > MONITORED_DIM:
                break
            self.static.append(k)
            total += dim

    def step(self, t: float, new_keys: list[int], estimate: gtsam.Values, isam: gtsam.ISAM2) -> None:
        """After the time step at `t` that added `new_keys`: judge the revision of what was watched, then watch
        the newest states and the static variables at `estimate` with `isam`'s marginal covariances."""
        worst = None
        for k, (value, information) in self._last.items():
            if not estimate.exists(k):
                continue
            vt = self.problem.keys.decode(k)[0].vartype
            delta = vt.local(value, vt.read(estimate, k))
            d2 = float(delta @ information @ delta)
            if worst is None or d2 / vt.dim > worst.d2 / worst.dim:
                worst = Revision(t, k, d2, vt.dim)
        if worst is not None:
            self.revisions.append(worst)
        for k in new_keys:
            family, index = self.problem.keys.decode(k)
            if family.kind == STATE and index > self._newest.get(family.id, (-1, 0))[0]:
                self._newest[family.id] = (index, k)
        self._last = {}
        for k in [*(key for _, key in self._newest.values()), *self.static]:
            if not estimate.exists(k):
                continue
            vt = self.problem.keys.decode(k)[0].vartype
            try:
                information = _information(np.asarray(isam.marginalCovariance(k)))
            except RuntimeError:  # a variable the solver cannot give a covariance for is not watched
                continue
            if information is not None:
                self._last[k] = (vt.read(estimate, k), information)


def _information(covariance: np.ndarray) -> np.ndarray | None:
    """The pseudo-inverse of a marginal covariance (symmetric eigen-decomposition), None when it is not finite
    (a diverged solver's covariance: LAPACK's SVD does not return on NaN)."""
    if not np.isfinite(covariance).all():
        return None
    w, v = np.linalg.eigh(0.5 * (covariance + covariance.T))
    keep = w > w.max() * 1e-12 if w.size and w.max() > 0 else np.zeros_like(w, dtype=bool)
    return (v[:, keep] / w[keep]) @ v[:, keep].T



def jump_check(problem: Problem, revisions: list[Revision], settings: dict) -> list[SolveWarning]:
    """A warning naming the updates whose estimate the next update moved beyond its sigmas (none: no warning).
    Not a rejection: the estimates handed out live were overconfident there, the final estimate is judged by
    the fit check. One Gauss-Newton step per update leaves a live estimate unconverged where a variable first
    becomes observable (a VO scale at the second motion-capture sample): more steps per update are the remedy
    then."""
    jumps = [r for r in revisions if r.jump]
    if not jumps:
        return []
    worst = max(jumps, key=lambda r: r.d2 / r.dim)
    spans = _spans([r.t for r in jumps])
    text = (f"at {len(jumps)} of {len(revisions)} updates the next update moved an estimate it had handed out "
            f"beyond its sigmas (chi-square above its 1 - {JUMP_P:g} quantile); worst "
            f"{problem.keys.name_of(worst.key)} at t = {worst.t:.2f} s, {np.sqrt(worst.d2):.3g} sigma; at t = "
            f"{_span_text(spans)}: the live estimates there were off by more than their sigmas claimed"
            + ("; solver.updates_per_step: 2 or more converges each update further"
               if settings.get("updates_per_step", 1) < 2 else ""))
    return [SolveWarning("incremental_jumps", text, (spans[0][0], spans[-1][1]))]


def first_jump(revisions: list[Revision]) -> Revision | None:
    """The earliest revision beyond its sigmas, if any: where an incremental run that later fails went astray."""
    return next((r for r in revisions if r.jump), None)


def health(problem: Problem, values: gtsam.Values, settings: dict, revisions: list[Revision] | None = None,
           snapshots: list[tuple[float, gtsam.Values]] | None = None) -> tuple[list[SolveWarning], str | None]:
    """The checks of a solve: (their warnings, why the run is rejected or None). Batch: the fit per window;
    incremental: also confirmed by a polish (fit_check) and the revisions (jump_check). `snapshots`: the
    fixed-lag smoother's static variables as each state left (window_fit)."""
    warnings, rejection = fit_check(problem, values, window_length(settings, problem), settings, snapshots)
    return warnings + jump_check(problem, revisions or [], settings), rejection


@dataclass
class Window:
    start: float
    end: float
    chi2: float
    dof: int

    @property
    def ratio(self) -> float:
        return self.chi2 / self.dof

    @property
    def beyond_chance(self) -> bool:
        return self.chi2 > quantile(1 - WINDOW_P, self.dof)


def window_fit(problem: Problem, values: gtsam.Values, length: float,
               snapshots: list[tuple[float, gtsam.Values]] | None = None) -> list[Window]:
    """Chi-square and degrees of freedom of the factors in each window of `length` seconds (by factor time;
    static-only factors in none) at `values`; windows without redundancy are left out. With `snapshots` (a
    fixed-lag run: `values` holds each state as it left the window), a window's factors are evaluated at the
    first snapshot at or after its end (the smoother's estimate then, `values` for what it no longer held): what
    the smoother believed of that window; the windows after the last snapshot at `values`."""
    times = np.array([r.time for r in problem.records])
    timed = np.isfinite(times)
    if not timed.any():
        return []
    start = float(times[timed].min())
    bins = np.full(len(times), -1)
    bins[timed] = np.floor((times[timed] - start) / length).astype(int)
    count = int(bins.max()) + 1
    errors = _window_errors(problem, values, bins, count, start, length, snapshots or [])
    dims = np.array([r.factor.dim() for r in problem.records])
    chi = np.bincount(bins[timed], weights=2 * errors[timed], minlength=count)
    rows = np.bincount(bins[timed], weights=dims[timed], minlength=count)
    key_times = np.array([t for t in problem.key_time.values()])
    key_dims = np.array([problem.keys.decode(k)[0].vartype.dim for k in problem.key_time])
    finite = np.isfinite(key_times) & (key_times >= start)
    key_bins = np.floor((key_times[finite] - start) / length).astype(int)
    inside = key_bins < count
    unknowns = np.bincount(key_bins[inside], weights=key_dims[finite][inside], minlength=count)
    out = []
    for b in range(count):
        dof = int(rows[b] - unknowns[b])
        if dof > 0:
            out.append(Window(start + b * length, start + (b + 1) * length, float(chi[b]), dof))
    return out


def _window_errors(problem: Problem, values: gtsam.Values, bins: np.ndarray, count: int, start: float,
                   length: float, snapshots: list[tuple[float, gtsam.Values]]) -> np.ndarray:
    """Each record's error, at `values` updated with the snapshot its window takes."""
    evaluator = problem.evaluator()
    errors = evaluator.record_errors(values)
    if not snapshots:
        return errors
    left = np.array([t for t, _ in snapshots])
    chosen: dict[int, list[int]] = {}
    for b in range(count):
        i = int(np.searchsorted(left, start + (b + 1) * length - 1e-9))  # first snapshot at or after its end
        if i < len(snapshots):
            chosen.setdefault(i, []).append(b)
    for i, window_bins in chosen.items():
        at = gtsam.Values(values)
        at.update(snapshots[i][1])
        mask = np.isin(bins, window_bins)
        errors[mask] = evaluator.record_errors(at)[mask]
    return errors


def misfit_windows(windows: list[Window]) -> tuple[list[Window], float]:
    """(the windows that fit far worse than the others, the median window's chi2/dof, at least 1)."""
    if len(windows) < 2:
        return [], 1.0
    median = max(1.0, float(np.median([w.ratio for w in windows])))
    return [w for w in windows if w.ratio > WINDOW_FACTOR * median and w.beyond_chance], median


def polished(problem: Problem, values: gtsam.Values) -> gtsam.Values | None:
    """The best fit of the whole graph reached by Levenberg-Marquardt (QR) from `values`; None if it fails."""
    from .levenberg import DampingSettings, levenberg_marquardt
    try:
        out, _ = levenberg_marquardt(problem.evaluator(), values, 1e-6, 1e-9, POLISH_ITERATIONS, DampingSettings(),
                                     qr=True)
    except RuntimeError:
        return None
    return out


def fit_check(problem: Problem, values: gtsam.Values, length: float, settings: dict,
              snapshots: list[tuple[float, gtsam.Values]] | None = None) -> tuple[list[SolveWarning], str | None]:
    """The windows of `length` s at `values` (window_fit). Incremental runs: every window beyond chance is compared
    with the best fit of the whole graph (polished from `values`): where that fits clearly better (a chi-square
    drop beyond the 1 - WINDOW_P quantile, and WINDOW_FACTOR times its chi2/dof, at least 1), the solver lost
    track there: rejection. Windows
    that fit far worse than the others (misfit_windows) but no better at the best fit, and for batch (its estimate
    is the best fit) every such window: the data there are what the model does not explain, a named warning."""
    windows = window_fit(problem, values, length, snapshots)
    if settings["type"] != "batch" and any(w.beyond_chance for w in windows):
        lost = _lost_track(problem, values, windows, length, settings)
        if lost is not None:
            return lost
    failed, median = misfit_windows(windows)
    if not failed:
        return [], None
    spans = _merge([(w.start, w.end) for w in failed])
    worst = max(failed, key=lambda w: w.ratio)
    text = (f"the data in {len(failed)} of {len(windows)} windows of {length:.3g} s fit far worse than in the "
            f"others: chi-square per degree of freedom up to {worst.ratio:.3g} (t = {worst.start:.2f} .. "
            f"{worst.end:.2f} s) against a median of {median:.3g}, at t = {_span_text(spans)}: measurements the "
            "model does not explain there (a slip, a bump, an outlier burst, a sensor on another clock); look at "
            "the residual plot there, and consider a robust loss on the factors involved")
    return [SolveWarning("local_misfit", text, (spans[0][0], spans[-1][1]))], None


def remedies(settings: dict) -> str:
    """What an incremental run that lost track can try, leaving out what `settings` already do."""
    out = [] if settings.get("new_states") == "carried" else ["solver.new_states: carried"]
    out += ["solver.warmup" if not settings.get("warmup") else "a longer solver.warmup"]
    if settings.get("type") == "fixed_lag":
        out.append("a longer solver.lag")
    if settings.get("updates_per_step", 1) < 2:
        out.append("solver.updates_per_step: 2")
    return ", ".join(out) + ", or the batch solver"


def _lost_track(problem: Problem, values: gtsam.Values, windows: list[Window], length: float, settings: dict
                ) -> tuple[list[SolveWarning], str | None] | None:
    """The windows beyond chance that the best fit from `values` explains clearly better: (the warning, the
    rejection when they are more than LOST_SHARE of the windows or one is GROSS_FACTOR times worse than the best
    fit, else None); None when there are none."""
    best = polished(problem, values)
    refit = {(w.start, w.end): w for w in window_fit(problem, best, length)} if best is not None else {}
    lost = []
    for w in windows:
        if not w.beyond_chance:
            continue
        after = refit.get((w.start, w.end))
        if after is None or (w.chi2 - after.chi2 > quantile(1 - WINDOW_P, w.dof)
                             and w.ratio > WINDOW_FACTOR * max(1.0, after.ratio)):
            lost.append((w, after))
    if not lost:
        return None
    rejected = (len(lost) > LOST_SHARE * len(windows)
                or any(after is None or w.ratio > GROSS_FACTOR * max(1.0, after.ratio) for w, after in lost))
    spans = _merge([(w.start, w.end) for w, _ in lost])
    worst, after = max(lost, key=lambda pair: pair[0].ratio)
    text = (f"the estimate fits the data in {len(lost)} of {len(windows)} windows of {length:.3g} s far worse than "
            f"the best fit of the same data does: chi-square per degree of freedom up to {worst.ratio:.3g} (t = "
            f"{worst.start:.2f} .. {worst.end:.2f} s; "
            + (f"{after.ratio:.3g} at the best fit" if after else "no best fit found")
            + f"), at t = {_span_text(spans)}: the solver lost track there (a diverged update, a parameter frozen "
            f"at a poor first estimate, a new state far from its prediction); try {remedies(settings)}")
    warning = SolveWarning("incremental_fit", text, (spans[0][0], spans[-1][1]))
    if not rejected:
        return [warning], None
    return [warning], f"the incremental run failed its health check: {text}"


def window_length(settings: dict, problem: Problem) -> float:
    """The fit check's window: the fixed-lag smoother's lag; otherwise a twentieth of the run, at least 1 s."""
    if settings["type"] == "fixed_lag":
        return float(settings["lag"])
    times = [r.time for r in problem.records if np.isfinite(r.time)]
    return max(1.0, (max(times) - min(times)) / 20) if times else 1.0


def _merge(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    out: list[list[float]] = []
    for a, b in sorted(spans):
        if out and a <= out[-1][1] + 1e-9:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out]


def _spans(times: list[float], gap: float = 1.0) -> list[tuple[float, float]]:
    """Times grouped into spans (first, last) where consecutive ones are at most `gap` s apart."""
    out: list[list[float]] = []
    for t in sorted(times):
        if out and t - out[-1][1] <= gap:
            out[-1][1] = t
        else:
            out.append([t, t])
    return [(a, b) for a, b in out]


def _span_text(spans: list[tuple[float, float]], most: int = 4) -> str:
    text = ", ".join(f"{a:.2f} .. {b:.2f} s" for a, b in spans[:most])
    return text + (f" and {len(spans) - most} more" if len(spans) > most else "")
