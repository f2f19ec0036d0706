"""Run every fusionkit benchmark and print one report of ratios against hand-written GTSAM
baselines measured in the same process.

    python benchmarks/run_all.py            # full: a few minutes on 2 cores
    python benchmarks/run_all.py --quick    # smaller sizes, well under a minute
    python benchmarks/run_all.py --only factors,isam2

Sections: factors (a), batch (b), isam2 (c), scaled_vo, cable_rigid (ARAS-CAM accuracy and speed),
cable_design (designed against random static poses for the pulley calibration, 24 seeds),
cable_sag (sagging cables: thesis Table 5.2, finite-element data, static simulator and calibration speed),
uwb (bias models, robust kernels, anchor self-calibration, Labyrinth recordings, incremental/batch speed),
serial_arm (real UR10 leave-one-out against FIGAROH, scipy side by side, 7-DoF speed, drift, simulation table),
wheels_real (wheel calibration on the OptiOdom recordings: UMBmark, least squares, the graph, held out),
wheels_speed (10,000 wheel steps in batch, per step and preintegrated; fixed-lag latency),
wheels_sim (the wheel graph against the rule-based odometers over 50 simulated runs per fault class),
time_offset (clock offsets estimated in the graph: lagging cable encoders held out, z-scores, UWB, cost),
epuck (IR localization in a known arena against dead reckoning, ablations, single scans, fitting tools, fixed-lag speed),
fixed_lag (the smoother's frozen variables held or relinearized: swaps and latency per update; its sigmas over seeds),
busy_core (the quickstart with another process keeping one core busy).
See benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import subprocess
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import numpy as np  # noqa: E402

SECTIONS = ("factors", "batch", "isam2", "scaled_vo", "cable_rigid", "cable_design", "cable_sag", "uwb", "serial_arm", "wheels_real",
            "wheels_speed", "wheels_sim", "time_offset", "epuck", "fixed_lag", "sweep", "busy_core")


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=HERE.parent, capture_output=True, text=True,
                              timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def header(quick: bool) -> str:
    import gtsam
    dirty = _git("status", "--porcelain", "--", "fusionkit", "plugins", "research")
    gtsam_version = getattr(gtsam, "__version__", None)
    if gtsam_version is None:
        from importlib.metadata import version
        gtsam_version = version("gtsam")
    try:
        load = "load avg %.2f %.2f %.2f" % os.getloadavg()
    except OSError:
        load = ""
    return "\n".join([
        f"fusionkit benchmarks ({'--quick' if quick else 'full'})",
        f"python {platform.python_version()}, gtsam {gtsam_version}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPUs, {load}",
        f"fusionkit commit {_git('rev-parse', '--short', 'HEAD')}"
        + (f" + uncommitted changes in {len(dirty.splitlines())} file(s) under fusionkit/ plugins/ "
           "research/" if dirty else ""),
        "all ratios are fusionkit / hand-written (or / native), measured in this process; lower is better",
    ])


def bench_module(section: str):
    """The module of a section: benchmarks/bench_<section>.py."""
    return importlib.import_module(f"bench_{section}")


def summary(results: dict) -> str:
    lines = ["summary (target: fusionkit / hand-written <= 1.2)", "=" * 50]
    if "factors" in results:
        f = results["factors"]
        lines.append(f"(a) scaled_relative linearize, vectorized: {f['fk_over_hand_lin']:.2f}x hand-written "
                     f"CustomFactor, {f['fk_over_native_lin']:.1f}x native BetweenFactorPose3 (one at a time: "
                     f"{f['one_at_a_time_over_native_lin']:.0f}x)")
    if "batch" in results:
        for n, d in results["batch"]["raw"].items():
            if "fusionkit" not in d:
                lines.append(f"(b) {n} states: fusionkit skipped (projected "
                             f"{d['fusionkit_projected_s'] / d['handwritten']['total']:.0f}x hand-written total)")
                continue
            fk, hw = d["fusionkit"], d["handwritten"]
            lines.append(f"(b) {n} states: build {fk['build'] / hw['build']:.2f}x, solve {fk['solve'] / hw['solve']:.2f}x"
                         f" (optimizer alone {fk['optimizer'] / hw['optimizer']:.2f}x), total {fk['total'] / hw['total']:.2f}x")
    if "isam2" in results:
        fk, hw = results["isam2"]["raw"]["fusionkit"], results["isam2"]["raw"]["hand-written"]
        lines.append(f"(c) iSAM2 step latency p50 {fk['p50'] / hw['p50']:.2f}x, p99 {fk['p99'] / hw['p99']:.2f}x; "
                     f"whole solve {fk['solve'] / hw['solve']:.2f}x")
    if "scaled_vo" in results:
        q = next(iter(results["scaled_vo"]["raw"].values()))
        lines.append(f"scaled_vo: estimate {q['estimate'] * 1e3:.0f} ms = read {q['read'] * 1e3:.0f} + build "
                     f"{q['build'] * 1e3:.0f} + optimizer {q['optimizer'] * 1e3:.0f} + checks/marginals "
                     f"{(q['solve'] - q['optimizer']) * 1e3:.0f} + post {q['post'] * 1e3:.0f}")
    for name in SECTIONS[SECTIONS.index("cable_rigid"):]:  # these sections summarize themselves
        if name in results:
            lines += bench_module(name).summary(results[name])
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="smaller sizes and fewer repeats (< 1 min)")
    ap.add_argument("--only", default=",".join(SECTIONS), help=f"comma-separated subset of {','.join(SECTIONS)}")
    args = ap.parse_args(argv)
    wanted = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = set(wanted) - set(SECTIONS)
    if unknown:
        ap.error(f"unknown section(s) {', '.join(sorted(unknown))}; choose from {', '.join(SECTIONS)}")

    modules = {name: bench_module(name) for name in SECTIONS}

    print(header(args.quick), flush=True)
    results, failed, start = {}, [], time.perf_counter()
    for name in SECTIONS:
        if name not in wanted:
            continue
        tic = time.perf_counter()
        try:
            results[name] = modules[name].run(args.quick)
        except Exception:  # noqa: BLE001 - one broken section must not hide the others
            failed.append(name)
            print(f"\n[{name}: FAILED after {time.perf_counter() - tic:.1f} s]\n{traceback.format_exc()}", flush=True)
            continue
        print(f"\n{results[name]['text']}\n[{name}: {time.perf_counter() - tic:.1f} s]", flush=True)
    print(f"\n{summary(results)}\n[total {time.perf_counter() - start:.1f} s]")
    if failed:
        print(f"FAILED sections: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    from _timing import with_big_stack
    sys.exit(with_big_stack(main))  # GTSAM needs a deep stack for 100k-state chains
