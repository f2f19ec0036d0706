"""The short human summary printed after a run."""

from __future__ import annotations

import numpy as np

from ..pipeline import RunResult
from ..graph.variables import COMPONENTS
from ..robots.calibration_file import SIGMA_AXES
from ..solve.noise_scales import scale_text


def format_value(values, sigma, kind: str = "") -> str:
    """`2.5 ± 0.01`; types with named components: `x 1, y 2, ... ± rx 0.01, ...` (sigma: 2 significant digits)."""
    v = np.atleast_1d(np.asarray(values, dtype=float))
    s = None if sigma is None else np.atleast_1d(np.asarray(sigma, dtype=float))
    if v.size == 1:
        return f"{v[0]:.5g}" + ("" if s is None else f" ± {s[0]:.2g}")
    if kind not in COMPONENTS:
        text = np.array2string(v, precision=4, separator=", ")
        return text if s is None else text + " ± [" + ", ".join(f"{x:.2g}" for x in s) + "]"
    names, sigma_names = COMPONENTS[kind]
    text = ", ".join(f"{n} {x:.5g}" for n, x in zip(names, v))
    if s is None:
        return text
    axes = f" ({SIGMA_AXES[kind]})" if kind in SIGMA_AXES else ""
    return f"{text} ± " + ", ".join(f"{n} {x:.2g}" for n, x in zip(sigma_names, s)) + axes


def summary_text(result: RunResult) -> str:
    s = result.solution
    fit = "" if s.chi2_per_dof is None else f", chi2/dof {s.chi2_per_dof:.3g} (sigma0 {s.sigma0:.3g})"
    lines = [f"fusionkit: {result.config.name}: {s.solver}, {s.iterations} iteration(s)/step(s), "
             f"cost {s.initial_error:.4g} -> {s.final_error:.4g}{fit}, solved in {s.seconds:.3f} s"
             + (" -- REJECTED by the chi-square gate" if s.rejection else "")]
    if s.sigmas_scaled:
        lines.append(f"  sigmas below are scaled by sigma0 = {s.sigma0:.3g} (solver.a_posteriori_sigmas)")
    for label, fit in (s.noise_scales or {}).items():
        lines.append(f"  noise scale of {label}: {scale_text(fit)}")
    stats = s.stats()
    if "step_latency_ms" in stats:
        lat = stats["step_latency_ms"]
        lines.append(f"  per-step latency: p50 {lat['p50']:.3f} ms, p99 {lat['p99']:.3f} ms")
    perrs = result.evaluation.get("parameters", {})
    for robot, params in result.parameters.items():
        for name, est in params.items():
            if est.series_t is not None:
                continue
            vt = est.family.vartype
            for i, v in enumerate(est.values):
                label = f"{robot}/{name}" + (f"[{i}]" if len(est.values) > 1 else "")
                text = format_value(vt.to_list(v), None if est.sigma is None else est.sigma[i], vt.name)
                err = perrs.get(robot, {}).get(name)
                if err:
                    text += f"   (error vs truth {err['abs_error'][i]:.3g})"
                lines.append(f"  {label} = {text}")
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
    lines += diagnostic_lines(result.problem.diagnostics)
    for note in result.notes:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def diagnostic_lines(diagnostics: dict[str, dict]) -> list[str]:
    """The plain-language verdicts plugins attached to their diagnostics."""
    return [f"  {label}: {sentence}" for label, d in diagnostics.items() for sentence in d.get("verdict", [])]
