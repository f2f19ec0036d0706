"""(c) iSAM2 per-step latency on a pose chain: fusionkit (solver type isam2; SolveResult.step_latency,
the wall time of each ISAM2.update plus the calculateEstimate that hands its estimate out) vs a
hand-written ISAM2 loop (gtsam and numpy only) adding one state per update with the same factors,
initial values and ISAM2 parameters, timed the same way; its update alone is also reported (the
cost of calculateEstimate). Runs alternate fusionkit / hand-written; the percentiles of each run
are computed and the median over runs is reported."""

from __future__ import annotations

import gc
import tempfile
import time
from pathlib import Path

import gtsam
import numpy as np

import fusionkit
from fusionkit.pipeline import estimate

import chain
from _timing import latency_percentiles, median_of, ms, table


def run_fusionkit(config_path: Path) -> dict:
    gc.collect()
    config = fusionkit.load_config(config_path)
    tic = time.perf_counter()
    result = estimate(config)
    total = time.perf_counter() - tic
    lat = result.solution.step_latency
    return {"lat": lat, "updates": lat.sum(), "solve": result.timings["solve_and_marginals_s"],
            "loop": result.solution.seconds, "total": total, "steps": len(lat),
            "final_cost": result.solution.final_error}


def run_handwritten(folder: Path) -> dict:
    """One update per state: the odometry factor into it (+ the prior / absolute pose at that state),
    then calculateEstimate; `lat` times both, `lat_update` the update alone."""
    gc.collect()
    tic_all = time.perf_counter()
    odom, absolute = chain.load_arrays(folder)
    graph, initial = chain.handwritten_graph(odom, absolute)
    # group the factors by the newest state they touch, keep graph order inside a step
    steps: dict[int, list[int]] = {}
    for i in range(graph.size()):
        steps.setdefault(max(graph.at(i).keys()), []).append(i)
    isam = gtsam.ISAM2(chain.isam2_params())
    lat, lat_update = [], []
    tic_loop = time.perf_counter()
    for k in range(initial.size()):
        factors = gtsam.NonlinearFactorGraph()
        for i in steps[k]:
            factors.add(graph.at(i))
        values = gtsam.Values()
        values.insert(k, initial.atPose3(k))
        tic = time.perf_counter()
        isam.update(factors, values)
        updated = time.perf_counter()
        estimate_values = isam.calculateEstimate()
        lat.append(time.perf_counter() - tic)
        lat_update.append(updated - tic)
    end = time.perf_counter()
    lat = np.asarray(lat)
    return {"lat": lat, "lat_update": np.asarray(lat_update), "updates": lat.sum(), "solve": end - tic_loop,
            "loop": end - tic_loop,
            "total": end - tic_all, "steps": len(lat), "final_cost": graph.error(estimate_values)}


def run(quick: bool = False) -> dict:
    n = 2000
    repeats = 3 if quick else 5
    with tempfile.TemporaryDirectory(prefix="fusionkit-bench-") as tmp:
        config = chain.write_dataset(Path(tmp), n, "isam2")
        fk_runs, hw_runs = [], []
        for _ in range(repeats):
            fk_runs.append(run_fusionkit(config))
            hw_runs.append(run_handwritten(Path(tmp)))
    med = {}
    for name, runs in (("fusionkit", fk_runs), ("hand-written", hw_runs)):
        stats = [{**latency_percentiles(r["lat"]), **{k: r[k] for k in ("updates", "solve", "total")}} for r in runs]
        med[name] = median_of(stats)
        med[name]["steps"] = runs[0]["steps"]
        med[name]["final_cost"] = runs[0]["final_cost"]
    update_only = median_of([latency_percentiles(r["lat_update"]) for r in hw_runs])
    med["hand-written"]["update_only"] = update_only
    rows = []
    for name, m in med.items():
        rows.append([name, m["steps"], f"{m['p50'] * 1e3:.3f}", f"{m['p90'] * 1e3:.3f}", f"{m['p99'] * 1e3:.3f}",
                     f"{m['max'] * 1e3:.2f}", ms(m["updates"]), ms(m["solve"]), ms(m["total"]),
                     f"{m['final_cost']:.6g}"])
    fk, hw = med["fusionkit"], med["hand-written"]
    rows.append(["hand-written, update alone", hw["steps"], *(f"{update_only[k] * 1e3:.3f}" for k in ("p50", "p90", "p99")),
                 f"{update_only['max'] * 1e3:.2f}", "", "", "", ""])
    rows.append(["ratio fk/hand", "", f"{fk['p50'] / hw['p50']:.2f}x", f"{fk['p90'] / hw['p90']:.2f}x",
                 f"{fk['p99'] / hw['p99']:.2f}x", f"{fk['max'] / hw['max']:.2f}x",
                 f"{fk['updates'] / hw['updates']:.2f}x", f"{fk['solve'] / hw['solve']:.2f}x",
                 f"{fk['total'] / hw['total']:.2f}x", ""])
    text = table(["impl", "steps", "p50 ms", "p90 ms", "p99 ms", "max ms", "sum of updates ms", "solve ms",
                  "total ms", "final cost"], rows,
                 f"(c) iSAM2 per-step latency, {n}-state chain, median over {repeats} runs of each")
    text += ("\nlatency = wall time of one ISAM2.update + calculateEstimate (what a real-time user waits for "
             "each step; fusionkit: SolveResult.step_latency); 'update alone' leaves calculateEstimate out. "
             "solve = whole "
             "incremental solve (fusionkit: solve_and_marginals_s incl. check_constrained, grouping factors by "
             "time, value subsets, check_solution; hand: the update loop). total = "
             "fusionkit estimate() incl. read/build/post; hand: read + build + loop.")
    return {"text": text, "raw": med}


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run)
