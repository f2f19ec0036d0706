"""The short human summary printed after a run, and the parameter rows report.html shares with it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..pipeline import ParameterEstimate, RunResult
from ..graph.builder import Held
from ..solve.identifiability import SHOWN
from ..solve.noise_scales import scale_text

MAX_SERIES = 8  # time-varying parameters the summary lists, one line each; the others are counted


def _number_list(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.5g}" for x in v) + "]"


def format_value(values, sigma, vartype, held=()) -> str:
    """`2.5 ± 0.01`; types with named components: `x 1, y 2, ... ± rx 0.01, ...` (sigma: 2 significant digits);
    vectors: `[1, 2] ± [0.01, 0.02]`. The sigmas of the tangent axes in `held` read `held`."""
    v = np.atleast_1d(np.asarray(values, dtype=float))
    s = None if sigma is None else np.atleast_1d(np.asarray(sigma, dtype=float))

    def sig(j: int, x: float) -> str:
        return "held" if j in held else f"{x:.2g}"

    if v.size == 1:
        return f"{v[0]:.5g}" + ("" if s is None else f" ± {sig(0, s[0])}")
    if not vartype.components:
        text = _number_list(v)
        return text if s is None else text + " ± [" + ", ".join(sig(j, x) for j, x in enumerate(s)) + "]"
    names, sigma_names = vartype.names()
    text = ", ".join(f"{n} {x:.5g}" for n, x in zip(names, v))
    if s is None:
        return text
    axes = f" ({vartype.sigma_note})" if vartype.sigma_note else ""
    return f"{text} ± " + ", ".join(f"{n} {sig(j, x)}" for j, (n, x) in enumerate(zip(sigma_names, s))) + axes


@dataclass
class ParameterRow:
    """One line of the parameters: an element of a static parameter (`index`), or a time-varying parameter
    as a whole (`index` None, `series` True). `label` names it as everywhere (`arm/joint_offsets[elbow_joint]`);
    `text` is what follows it: the value ± sigma with the unit, `held (why) at ...`, or the series in brief."""

    robot: str
    name: str
    index: int | None
    label: str
    text: str
    series: bool = False


def _unit(result: RunResult, est: ParameterEstimate) -> str:
    """The unit the robot description gives the parameter (`unit:`), with a leading space; "" if none."""
    param = result.config.robots[est.robot].description.parameters.get(est.name.split("[")[0]) \
        if est.robot in result.config.robots else None
    return f" {param.unit}" if param is not None and param.unit else ""


def _nominal(result: RunResult, est: ParameterEstimate, i: int) -> Any:
    """The description's value of element i (what a hold holds it at); the estimate if the description has none."""
    param = result.config.robots[est.robot].description.parameters.get(est.name) \
        if est.robot in result.config.robots else None
    if param is None or len(param.values) != len(est.values):
        return est.values[i]
    return param.values[i]


def _held_text(vt, value, nominal, sigma, held: Held, unit: str) -> str:
    """An element some of whose axes a factor holds: `held (why) at 0 rad` when all are, else the value with
    those sigmas reading `held` (and, for vectors, their nominal values) and `; tx, rx held (why)`."""
    if len(held.axes) >= vt.dim:
        return f"held ({held.reason}) at {format_value(vt.to_list(nominal), None, vt)}{unit}"
    shown = np.atleast_1d(np.asarray(vt.to_list(value), dtype=float))
    if not vt.components and shown.size == vt.dim:  # a vector: its entries are its tangent axes
        shown[list(held.axes)] = np.atleast_1d(np.asarray(vt.to_list(nominal), dtype=float))[list(held.axes)]
    names = held.labels or tuple(vt.axes[a] if vt.axes else f"[{a}]" for a in held.axes)
    return (f"{format_value(shown, sigma, vt, set(held.axes))}{unit}; "
            f"{', '.join(names)} held ({held.reason})")


def _range(vt, values: list) -> str | None:
    """min..max of each component over a series (none for types with a rotation)."""
    if vt.lie_group is not None:
        return None
    rows = np.array([np.atleast_1d(np.asarray(vt.to_list(v), dtype=float)) for v in values])
    lo, hi = rows.min(axis=0), rows.max(axis=0)
    spans = [f"{a:.5g}..{b:.5g}" for a, b in zip(lo, hi)]
    if len(spans) == 1:
        return spans[0]
    if vt.components:
        return ", ".join(f"{n} {x}" for n, x in zip(vt.components, spans))
    return "[" + ", ".join(spans) + "]"


def series_text(result: RunResult, est: ParameterEstimate) -> str:
    """A time-varying parameter in brief: `time-varying over 400 states, first 0.052 ± 0.004 m, last 0.061 ±
    0.004 m, range 0.049..0.066 m`; one the data cannot identify: `time-varying over 400 states, held (why)`."""
    vt, unit, n = est.family.vartype, _unit(result, est), len(est.values)
    head = f"time-varying over {n} state{'s' if n != 1 else ''}"
    holds = [result.problem.held.get(k) for k in _series_keys(result, est)]
    if holds and all(h is not None and len(h.axes) >= vt.dim for h in holds):
        return f"{head}, held ({holds[0].reason})"

    def at(i: int) -> str:
        return format_value(vt.to_list(est.values[i]), None if est.sigma is None else est.sigma[i], vt) + unit

    text = f"{head}, first {at(0)}, last {at(-1)}"
    span = _range(vt, est.values)
    return text + (f", range {span}{unit}" if span is not None else "")


def _series_keys(result: RunResult, est: ParameterEstimate) -> list[int]:
    """The keys of a time-varying parameter's values (one per state it has a value at)."""
    states = result.problem.states.get(est.robot)
    if states is None or est.series_t is None:
        return []
    index = np.searchsorted(states.t, est.series_t)
    return est.family.keys(np.clip(index, 0, max(len(states.t) - 1, 0)))


def parameter_rows(result: RunResult) -> list[ParameterRow]:
    """Every estimated parameter as the summary and report.html list it: static ones element by element,
    time-varying ones one row each (series=True)."""
    rows = []
    for robot, params in result.parameters.items():
        for name, est in params.items():
            fam, vt = est.family, est.family.vartype
            if est.series_t is not None:
                rows.append(ParameterRow(robot, name, None, fam.label(), series_text(result, est), series=True))
                continue
            unit = _unit(result, est)
            for i, v in enumerate(est.values):
                label = fam.label(i) if len(est.values) > 1 or fam.elements else fam.label()
                sigma = None if est.sigma is None else est.sigma[i]
                held = result.problem.held.get(fam.key(i))
                text = (format_value(vt.to_list(v), sigma, vt) + unit if held is None
                        else _held_text(vt, v, _nominal(result, est, i), sigma, held, unit))
                rows.append(ParameterRow(robot, name, i, label, text))
    return rows


def summary_text(result: RunResult) -> str:
    s = result.solution
    fit = "" if s.chi2_per_dof is None else f", chi2/dof {s.chi2_per_dof:.3g} (sigma0 {s.sigma0:.3g})"
    lines = [f"fusionkit: {result.config.name}: {s.solver}, {s.iterations} iteration(s)/step(s), "
             f"cost {s.initial_error:.4g} -> {s.final_error:.4g}{fit}, solved in {s.seconds:.3f} s"
             + (" -- REJECTED (see the error below)" if s.rejection else "")]
    lines += [f"  {w.text()}" for w in s.warnings]
    if s.sigmas_scaled:
        lines.append(f"  sigmas below are scaled by sigma0 = {s.sigma0:.3g} (solver.a_posteriori_sigmas)")
    for label, fit in (s.noise_scales or {}).items():
        lines.append(f"  noise scale of {label}: {scale_text(fit)}")
    stats = s.stats()
    if "step_latency_ms" in stats:
        lat = stats["step_latency_ms"]
        lines.append(f"  per-step latency: p50 {lat['p50']:.3f} ms, p99 {lat['p99']:.3f} ms")
    perrs = result.evaluation.get("parameters", {})
    series = 0
    for row in parameter_rows(result):
        if row.series:
            series += 1
            if series <= MAX_SERIES:
                lines.append(f"  {row.label}: {row.text}")
            continue
        err = perrs.get(row.robot, {}).get(row.name)
        lines.append(f"  {row.label} = {row.text}" + (f"   (error vs truth {err['abs_error'][row.index]:.3g})" if err else ""))
    if series > MAX_SERIES:
        lines.append(f"  ... and {series - MAX_SERIES} more time-varying parameters (report.json has every series)")
    found = identifiability_lines(result.problem, result.identifiability)
    if found:
        lines.append("  identifiability (what the data determine; report.json identifiability):")
        lines += [f"    {line}" for line in found]
    for robot, ev in result.evaluation.get("trajectories", {}).items():
        matched = f"{ev['matched_poses']} of {ev['states']} states matched to truth"
        if "ate_rmse_m" not in ev:
            lines.append(f"  {robot}: no ATE: {matched}")
            continue
        line = f"  {robot}: ATE RMSE {ev['ate_rmse_m']:.4f} m over {matched} (align: {ev['align']})"
        if "rpe_translation_rmse_m" in ev:
            line += f", RPE {ev['rpe_translation_rmse_m']:.4f} m / {ev['rpe_rotation_rmse_deg']:.3f} deg per step"
        lines.append(line)
        if "consistency_percent" in ev:
            c = ev["consistency_percent"]
            within = ", ".join(f"{ax} {c[ax]['1sigma']:.0f}/{c[ax]['2sigma']:.0f}/{c[ax]['3sigma']:.0f}%" for ax in c)
            lines.append(f"    inside 1/2/3 sigma: {within} (ideal 68/95/99.7%)")
    lines += diagnostic_lines(result.problem.diagnostics, set(result.problem.analyses))
    for note in result.notes:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def diagnostic_lines(diagnostics: dict[str, dict], leave_out: set[str] = frozenset()) -> list[str]:
    """The plain-language verdicts plugins attached to their diagnostics (but those of `leave_out`)."""
    return [f"  {label}: {sentence}" for label, d in diagnostics.items() if label not in leave_out
            for sentence in d.get("verdict", [])]


def analysis_lines(problem, shown: int | None = None) -> list[str]:
    """The verdicts of the families' own analyses of what the data determine (`add_diagnostic(...,
    identifiability=True)`: a cable's observability, an arm's identifiable axes), `label: sentence`; at most
    `shown` of each analysis, then how many more report.json holds."""
    out = []
    for label in problem.analyses:
        verdict = problem.diagnostics.get(label, {}).get("verdict", [])
        out += [f"{label}: {sentence}" for sentence in verdict[:shown]]
        if shown is not None and len(verdict) > shown:
            out.append(f"{label}: ... and {len(verdict) - shown} more (report.json diagnostics)")
    return out


def identifiability_lines(problem, report) -> list[str]:
    """The identifiability section on the console: the families' analyses, then what the joint covariance says
    (`report`), each kind at most SHOWN lines."""
    return analysis_lines(problem, SHOWN) + (report.lines() if report is not None else [])
