"""The short human summary printed after a run."""

from __future__ import annotations

import numpy as np

from ..pipeline import RunResult


def _fmt(values, sigma) -> str:
    v = np.atleast_1d(np.asarray(values, dtype=float))
    if sigma is None:
        return np.array2string(v, precision=4, separator=", ")
    s = np.atleast_1d(np.asarray(sigma, dtype=float))
    if v.size == 1:
        return f"{v[0]:.5g} ± {s[0]:.2g}"
    sig = "[" + ", ".join(f"{x:.2g}" for x in s) + "]"  # 2 significant digits, however small
    return f"{np.array2string(v, precision=4, separator=', ')} ± {sig}"


def summary_text(result: RunResult) -> str:
    s = result.solution
    lines = [f"fusionkit: {result.config.name}: {s.solver}, {s.iterations} iteration(s)/step(s), "
             f"cost {s.initial_error:.4g} -> {s.final_error:.4g}, solved in {s.seconds:.3f} s"]
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
                text = _fmt(vt.to_list(v), None if est.sigma is None else est.sigma[i])
                err = perrs.get(robot, {}).get(name)
                if err:
                    text += f"   (error vs truth {err['abs_error'][i]:.3g})"
                lines.append(f"  {label} = {text}")
    for robot, ev in result.evaluation.get("trajectories", {}).items():
        line = f"  {robot}: ATE RMSE {ev['ate_rmse_m']:.4f} m (align: {ev['align']})"
        if "rpe_translation_rmse_m" in ev:
            line += f", RPE {ev['rpe_translation_rmse_m']:.4f} m / {ev['rpe_rotation_rmse_deg']:.3f} deg per step"
        lines.append(line)
        if "consistency_percent" in ev:
            c = ev["consistency_percent"]
            within = ", ".join(f"{ax} {c[ax]['1sigma']:.0f}/{c[ax]['2sigma']:.0f}/{c[ax]['3sigma']:.0f}%" for ax in c)
            lines.append(f"    inside 1/2/3 sigma: {within} (ideal 68/95/99.7%)")
    lines += diagnostic_lines(result.problem.diagnostics)
    for note in result.problem.notes:
        lines.append(f"  note: {note}")
    return "\n".join(lines)


def diagnostic_lines(diagnostics: dict[str, dict]) -> list[str]:
    """The plain-language verdicts plugins attached to their diagnostics."""
    return [f"  {label}: {sentence}" for label, d in diagnostics.items() for sentence in d.get("verdict", [])]
