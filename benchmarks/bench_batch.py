"""(b) Batch solve of pose chains: fusionkit (config + TUM files -> estimate) vs the same graph
hand-written against GTSAM (numpy arrays from the same files -> python loop -> LM optimizer).

Sizes run smallest first. Before each size the fusionkit time is projected from the previous
sizes (power-law fit of measured time vs states); a size whose projection exceeds the budget is
reported as skipped with its projection, so the run stays within a few minutes even when a part
of fusionkit scales badly.
"""

from __future__ import annotations

import gc
import math
import tempfile
import time
from pathlib import Path

import gtsam

import fusionkit
from fusionkit.pipeline import estimate

import chain
from _timing import median_of, ms, table

TARGET = 1.2        # read and build, fusionkit / hand-written (issue 12)
TOTAL_TARGET = 1.3  # end to end


def run_fusionkit(config_path: Path) -> tuple[dict, object]:
    gc.collect()
    tic = time.perf_counter()
    config = fusionkit.load_config(config_path)
    load = time.perf_counter() - tic
    tic = time.perf_counter()
    result = estimate(config)
    total_est = time.perf_counter() - tic
    t = result.timings
    solve = t["solve_and_marginals_s"]
    out = {"load": load, "read": t["read_s"], "build": t["build_s"], "solve": solve,
           "optimizer": t["solve_s"], "checks": solve - t["solve_s"],
           "post": total_est - t["read_s"] - t["build_s"] - solve, "total": load + total_est}
    return out, result


def run_handwritten(folder: Path) -> tuple[dict, dict]:
    gc.collect()
    tic = time.perf_counter()
    odom, absolute = chain.load_arrays(folder)
    read = time.perf_counter() - tic
    tic = time.perf_counter()
    graph, initial = chain.handwritten_graph(odom, absolute)
    build = time.perf_counter() - tic
    tic = time.perf_counter()
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, chain.lm_params())
    values = optimizer.optimize()
    solve = time.perf_counter() - tic
    info = {"iterations": optimizer.iterations(), "final_cost": graph.error(values)}
    return ({"load": 0.0, "read": read, "build": build, "solve": solve, "optimizer": solve, "checks": 0.0,
             "post": 0.0, "total": read + build + solve}, info)


def lm_defaults_warning() -> list[str]:
    """A WARNING line when fusionkit's LM defaults no longer match the hand-written chain.LM_DEFAULTS."""
    from dataclasses import asdict

    from fusionkit.solve.levenberg import DampingSettings
    current = asdict(DampingSettings())
    if current == chain.LM_DEFAULTS:
        return []
    return [f"WARNING: fusionkit's LM defaults {current} differ from the baseline's {chain.LM_DEFAULTS}"]


def _project(history: list[tuple[int, float]], n: int) -> float:
    """Fusionkit seconds at n states from a power-law fit through the last two sizes."""
    if not history:
        return 0.0
    if len(history) == 1:
        n0, t0 = history[0]
        return t0 * (n / n0)  # assume linear until a second size says otherwise
    (n0, t0), (n1, t1) = history[-2:]
    k = max(1.0, math.log(t1 / t0) / math.log(n1 / n0))
    return t1 * (n / n1) ** k


def run(quick: bool = False) -> dict:
    sizes = [1000, 2000, 10000] if quick else [1000, 2000, 10000, 100000]
    budget = 15.0 if quick else 90.0  # seconds for one fusionkit run of one size
    rows, ratio_rows, notes, fk_history, raw = [], [], [], [], {}
    tmp = tempfile.TemporaryDirectory(prefix="fusionkit-bench-")
    for n in sizes:
        projected = _project(fk_history, n)
        folder = Path(tmp.name) / f"chain_{n}"
        if projected > budget:
            notes.append(f"{n} states: fusionkit skipped, projected ~{projected:.0f} s (budget {budget:.0f} s; "
                         f"power law through {fk_history[-2:]} [states, s])"
                         + ("; hand-written skipped too in --quick" if quick else ""))
            if not quick:
                chain.write_dataset(folder, n, "batch")
                hw, info = run_handwritten(folder)
                rows.append([f"{n}", "fusionkit", "skipped", "", "", "", "", "", "", f"~{projected * 1e3:.0f}",
                             f"~{projected / n * 1e6:.0f}", "", ""])
                rows.append([f"{n}", "hand-written", ms(hw["load"]), ms(hw["read"]), ms(hw["build"]),
                             ms(hw["optimizer"]), ms(hw["checks"]), ms(hw["solve"]), ms(hw["post"]),
                             ms(hw["total"]), f"{hw['total'] / n * 1e6:.1f}", info["iterations"],
                             f"{info['final_cost']:.6g}"])
                ratio_rows.append([f"{n}", "", "", "", "", f"~{projected / hw['total']:.0f}x (proj.)",
                                   "skipped", "", 1])
                raw[n] = {"handwritten": hw, "fusionkit_projected_s": projected}
            continue
        config = chain.write_dataset(folder, n, "batch")
        repeats = 3 if projected < 10.0 else 1
        fk_runs, hw_runs = [], []
        for _ in range(repeats):  # interleaved, so load drifts hit both
            fk, result = run_fusionkit(config)
            hw, info = run_handwritten(folder)
            fk_runs.append(fk)
            hw_runs.append(hw)
        fk, hw = median_of(fk_runs), median_of(hw_runs)
        fk_history.append((n, fk["total"]))
        raw[n] = {"fusionkit": fk, "handwritten": hw}
        fk_iter, fk_cost = result.solution.iterations, result.solution.final_error
        same = abs(fk_cost - info["final_cost"]) <= 1e-4 * max(1.0, info["final_cost"])
        for name, d, it, cost in (("fusionkit", fk, fk_iter, fk_cost),
                                  ("hand-written", hw, info["iterations"], info["final_cost"])):
            rows.append([f"{n}", name, ms(d["load"]), ms(d["read"]), ms(d["build"]), ms(d["optimizer"]),
                         ms(d["checks"]), ms(d["solve"]), ms(d["post"]), ms(d["total"]),
                         f"{d['total'] / n * 1e6:.1f}", it, f"{cost:.6g}"])
        r = {k: fk[k] / hw[k] for k in ("read", "build", "solve", "optimizer", "total")}
        ratio_rows.append([f"{n}", f"{r['read']:.2f}x", f"{r['build']:.2f}x", f"{r['optimizer']:.2f}x",
                           f"{r['solve']:.2f}x", f"{r['total']:.2f}x",
                           "ok" if max(r["read"], r["build"]) <= TARGET and r["total"] <= TOTAL_TARGET else "OVER",
                           "same" if same else "DIFFERENT", repeats])
    tmp.cleanup()
    notes += lm_defaults_warning()
    text = table(["states", "impl", "load ms", "read ms", "build ms", "optimizer ms", "checks ms",
                  "solve ms", "post ms", "total ms", "us/state", "iters", "final cost"], rows,
                 "(b) batch LM, pose chain (odometry + origin prior + absolute pose every 100 states), "
                 "marginals off")
    text += "\n\n" + table(["states", "read", "build", "optimizer", "solve", "total",
                             f"read&build<={TARGET}, total<={TOTAL_TARGET}", "final cost", "runs"], ratio_rows,
                            "(b) ratios fusionkit / hand-written")
    text += ("\nsolve = optimizer + checks (fusionkit: check_constrained before, check_solution after, graph "
             "assembly); hand-written solve = LevenbergMarquardtOptimizer(...).optimize(). post = trajectories, "
             "parameters, evaluation, residuals_by_entry. total includes load (config validation).")
    if notes:
        text += "\n" + "\n".join(notes)
    return {"text": text, "raw": raw}


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run)
