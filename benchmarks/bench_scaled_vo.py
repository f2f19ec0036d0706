"""The scaled-VO example (configs/scaled_vo_mocap.yaml) end to end: config load, result.timings of
estimate(), the rest of estimate() (post), and writing the outputs (as `fusionkit run` does) without and with plots. Also the same config with
marginals off and with the iSAM2 solver, whose per-step latency is split into the first and last
10% of the steps (growth with the number of variables shows up there)."""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

import fusionkit
import fusionkit.api
from fusionkit.pipeline import estimate
from fusionkit.report.outputs import write_outputs

from _timing import ms, table

SCALED_VO = Path(__file__).resolve().parent.parent / "configs" / "scaled_vo_mocap.yaml"

VARIANTS = [
    ("batch lm, marginals on (as shipped)", []),
    ("batch lm, marginals off", ["solver.marginals=false"]),
    ("isam2, marginals off", ["solver.type=isam2", "solver.marginals=false"]),
]


def _once(overrides: list[str], write: bool) -> dict:
    tic = time.perf_counter()
    config = fusionkit.load_config(SCALED_VO, overrides)
    load = time.perf_counter() - tic
    tic = time.perf_counter()
    result = estimate(config)
    est = time.perf_counter() - tic
    t = result.timings
    out = {"load": load, "read": t["read_s"], "build": t["build_s"], "optimizer": t["solve_s"],
           "solve": t["solve_and_marginals_s"],
           "post": est - t["read_s"] - t["build_s"] - t["solve_and_marginals_s"], "estimate": est,
           "write": float("nan"), "write_plots": float("nan"), "states": len(next(iter(result.problem.states.values()))),
           "factors": len(result.problem.records), "iterations": result.solution.iterations}
    lat = result.solution.step_latency
    if lat is not None and len(lat):
        tenth = max(1, len(lat) // 10)
        out.update(p50=float(np.percentile(lat, 50)), p99=float(np.percentile(lat, 99)),
                   first=float(lat[:tenth].mean()), last=float(lat[-tenth:].mean()))
    if write:
        with tempfile.TemporaryDirectory(prefix="fusionkit-bench-") as tmp:
            for sub in ("noplots", "plots"):
                (Path(tmp) / sub).mkdir()
            tic = time.perf_counter()
            write_outputs(result, Path(tmp) / "noplots", plots=False)
            out["write"] = time.perf_counter() - tic
            tic = time.perf_counter()
            write_outputs(result, Path(tmp) / "plots", plots=True)
            out["write_plots"] = time.perf_counter() - tic
    return out


def run(quick: bool = False) -> dict:
    repeats = 2 if quick else 3
    _once([], False)  # warm-up: imports, plugin registry, matplotlib on first plot below
    rows, lat_rows, raw, failures = [], [], {}, []
    for name, overrides in VARIANTS:
        write = overrides == []
        try:
            runs = [_once(overrides, write) for _ in range(repeats)]
        except fusionkit.api.FusionkitError as exc:
            rows.append([name, "FAILED"] + [""] * 9)
            failures.append(f"{name}: FAILED with {exc.__class__.__name__}: {exc}")
            continue
        m = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        raw[name] = m
        rows.append([name, ms(m["load"]), ms(m["read"]), ms(m["build"]), ms(m["optimizer"]),
                     ms(m["solve"] - m["optimizer"]), ms(m["post"]), ms(m["estimate"]),
                     "" if np.isnan(m["write"]) else ms(m["write"]),
                     "" if np.isnan(m["write_plots"]) else ms(m["write_plots"]), int(m["iterations"])])
        if "p50" in m:
            lat_rows.append([name, f"{m['p50'] * 1e3:.3f}", f"{m['p99'] * 1e3:.3f}", f"{m['first'] * 1e3:.3f}",
                             f"{m['last'] * 1e3:.3f}", f"{m['last'] / m['first']:.1f}x"])
    first = raw[VARIANTS[0][0]]
    text = table(["scaled_vo variant", "load ms", "read_s", "build_s", "solve_s (optimizer)",
                  "checks+marginals", "post", "estimate ms", "write ms", "write+plots ms", "iters/steps"], rows,
                 f"scaled_vo_mocap end to end ({int(first['states'])} states, {int(first['factors'])} factors; "
                 f"median of {repeats}; ms)")
    if lat_rows:
        text += "\n\n" + table(["variant", "p50 ms", "p99 ms", "first 10% mean ms", "last 10% mean ms", "growth"],
                               lat_rows, "scaled_vo_mocap iSAM2 step latency: update + calculateEstimate "
                               "(Python CustomFactors)")
    text += "".join(f"\n{f}" for f in failures)
    text += ("\nread_s/build_s/solve_s come from result.timings; checks+marginals = solve_and_marginals_s - solve_s; "
             "post = the rest of estimate(); write = write_outputs(plots=False), write+plots = plots=True.")
    return {"text": text, "raw": raw}


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run)
