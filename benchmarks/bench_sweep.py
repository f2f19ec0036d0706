"""Runs at scale: `fusionkit sweep` on a local process pool and on a local Ray instance against a serial loop
of the same runs in this process (docs/reference/cli.md#sweep).

200 quickstart-sized runs (configs/quickstart.yaml, seeds 0..199; --quick: 20): the wall time of each
backend, the seconds spent inside the runs, and the scheduling overhead per run, (wall x workers - inside)
/ runs, against the mean run's length; and whether every backend gives the serial loop's numbers (ATE,
pulley error) to the last digit. Workers: 2 local processes; Ray with 2 CPUs (ray.init timed apart: a user's
cluster is running; the workers' first imports are counted; left out
when Ray is not installed: pip install 'fusionkit[scale]').

    python benchmarks/bench_sweep.py [--quick]
"""

from __future__ import annotations

import importlib.util
import time
from pathlib import Path

import numpy as np

from fusionkit.sweep import execute, run_one, run_settings
from _timing import run_parts, table

REPO = Path(__file__).resolve().parents[1]
CONFIG = str(REPO / "configs" / "quickstart.yaml")
FIGURES = ["evaluation.trajectories.cdpr.ate_rmse_m", "evaluation.parameters.cdpr.pulley.mean_abs_error"]
WORKERS = 2


def backends(runs: int) -> tuple[str, dict]:
    settings = run_settings({"seeds": list(range(runs))}, {0: 0})  # source 0 at seeds 0 .. runs - 1
    rows, raw, reference = [], {}, None
    names = ("serial loop", "local pool") + (("ray",) if importlib.util.find_spec("ray") else ())
    cluster_start = None
    for name in names:
        if name == "ray":  # a running cluster is what `--backend ray` meets: its start is timed apart
            import ray
            tic = time.perf_counter()
            ray.init(num_cpus=WORKERS, include_dashboard=False, log_to_driver=False, logging_level="error")
            cluster_start = time.perf_counter() - tic
        tic = time.perf_counter()
        if name == "serial loop":
            results = [run_one(CONFIG, s, FIGURES) for s in settings]
        elif name == "ray":
            results = execute(CONFIG, settings, FIGURES, "ray", WORKERS)
        else:
            results = execute(CONFIG, settings, FIGURES, "local", WORKERS)
        wall = time.perf_counter() - tic
        if name == "ray":
            ray.shutdown()
        workers = 1 if name == "serial loop" else WORKERS
        inside = sum(r["seconds"] for r in results)
        overhead = (wall * workers - inside) / runs
        mean = inside / runs
        values = np.array([[r[f] for f in FIGURES] for r in results], float)
        reference = values if reference is None else reference
        same = bool(np.array_equal(values, reference))
        raw[name] = {"wall_s": wall, "inside_s": inside, "overhead_per_run_s": overhead, "mean_run_s": mean,
                     "same_numbers": same, "failed": sum(r["status"] == "error" for r in results)}
        rows.append([name, workers, f"{wall:.1f}", f"{inside:.1f}", f"{mean:.3f}", f"{overhead * 1e3:.0f}",
                     f"{100 * overhead / mean:.1f}", "yes" if same else "NO", raw[name]["failed"]])
    text = table(["backend", "workers", "wall s", "inside runs s", "mean run s", "overhead per run ms",
                  "overhead % of a run", "serial's numbers", "failed"], rows,
                 f"fusionkit sweep: {runs} quickstart runs (seeds 0..{runs - 1})")
    if cluster_start is not None:
        raw["ray"]["cluster_start_s"] = cluster_start
        text += (f"\nray: starting the local Ray instance (ray.init) took {cluster_start:.1f} s, not counted above: "
                 "`--backend ray` meets a running cluster; the workers' first import of fusionkit is counted")
    return text, raw


def run(quick: bool) -> dict:
    return run_parts({"backends": lambda: backends(20 if quick else 200)})


def summary(results: dict) -> list[str]:
    raw = results["raw"]["backends"]
    return [f"sweep: {name}: {d['wall_s']:.1f} s wall, overhead {100 * d['overhead_per_run_s'] / d['mean_run_s']:.1f} % "
            f"of a {d['mean_run_s']:.2f} s run, {'same numbers as the serial loop' if d['same_numbers'] else 'DIFFERENT'}"
            for name, d in raw.items() if name != "serial loop"]


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
