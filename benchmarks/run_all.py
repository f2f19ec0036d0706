"""Run every fusionkit benchmark and print one report of ratios against hand-written GTSAM
baselines measured in the same process.

    python benchmarks/run_all.py            # full: a few minutes on 2 cores
    python benchmarks/run_all.py --quick    # smaller sizes, well under a minute
    python benchmarks/run_all.py --only factors,isam2

Sections: factors (a), batch (b), isam2 (c), scaled_vo, cable_rigid (ARAS-CAM accuracy and speed),
cable_sag (sagging cables: thesis Table 5.2, finite-element data, static simulator and calibration speed),
uwb (bias models, robust kernels, anchor self-calibration, Labyrinth recordings, incremental/batch speed),
serial_arm (real UR10 leave-one-out against FIGAROH, scipy side by side, 7-DoF speed, drift, simulation table),
wheels_real (wheel calibration on the OptiOdom recordings: UMBmark, least squares, the graph, held out),
wheels_speed (10,000 wheel steps in batch, per step and preintegrated; fixed-lag latency),
wheels_sim (the wheel graph against the rule-based odometers over 50 simulated runs per fault class),
time_offset (clock offsets estimated in the graph: lagging cable encoders held out, z-scores, UWB, cost),
epuck (IR localization in a known arena against dead reckoning, ablations, single scans, fitting tools, fixed-lag speed),
busy_core (the quickstart with another process keeping one core busy).
See benchmarks/README.md.
"""

from __future__ import annotations

import argparse
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

SECTIONS = ("factors", "batch", "isam2", "scaled_vo", "cable_rigid", "cable_sag", "uwb", "serial_arm", "wheels_real", "wheels_speed", "wheels_sim",
            "time_offset", "epuck", "busy_core")


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=HERE.parent, capture_output=True, text=True,
                              timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def header(quick: bool) -> str:
    import gtsam
    dirty = _git("status", "--porcelain", "--", "fusionkit", "plugins", "benchmarks/research")
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
           "benchmarks/research/" if dirty else ""),
        "all ratios are fusionkit / hand-written (or / native), measured in this process; lower is better",
    ])


def summary(results: dict) -> str:
    lines = ["summary (target: fusionkit / hand-written <= 1.2)", "=" * 50]
    if "factors" in results:
        f = results["factors"]
        lines.append(f"(a) scaled_relative linearize: {f['fk_over_hand_lin']:.2f}x hand-written CustomFactor, "
                     f"{f['fk_over_native_lin']:.1f}x native BetweenFactorPose3")
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
    if "cable_rigid" in results:
        import bench_cable_rigid
        lines += bench_cable_rigid.summary(results["cable_rigid"])
    if "cable_sag" in results:
        import bench_cable_sag
        lines += bench_cable_sag.summary(results["cable_sag"])
    if "uwb" in results:
        import bench_uwb
        lines += bench_uwb.summary(results["uwb"])
    if "serial_arm" in results:
        import bench_serial_arm
        lines += bench_serial_arm.summary(results["serial_arm"])
    if "wheels_real" in results:
        import bench_wheels_real
        lines += bench_wheels_real.summary(results["wheels_real"])
    if "wheels_speed" in results:
        import bench_wheels_speed
        lines += bench_wheels_speed.summary(results["wheels_speed"])
    if "wheels_sim" in results:
        import bench_wheels_sim
        lines += bench_wheels_sim.summary(results["wheels_sim"])
    if "time_offset" in results:
        import bench_time_offset
        lines += bench_time_offset.summary(results["time_offset"])
    if "epuck" in results:
        import bench_epuck
        lines += bench_epuck.summary(results["epuck"])
    if "busy_core" in results:
        import bench_busy_core
        lines += bench_busy_core.summary(results["busy_core"])
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

    import bench_batch
    import bench_busy_core
    import bench_cable_rigid
    import bench_cable_sag
    import bench_epuck
    import bench_factors
    import bench_isam2
    import bench_scaled_vo
    import bench_serial_arm
    import bench_time_offset
    import bench_uwb
    import bench_wheels_real
    import bench_wheels_sim
    import bench_wheels_speed
    modules = {"factors": bench_factors, "batch": bench_batch, "isam2": bench_isam2,
               "scaled_vo": bench_scaled_vo, "cable_rigid": bench_cable_rigid, "cable_sag": bench_cable_sag, "uwb": bench_uwb,
               "serial_arm": bench_serial_arm, "wheels_real": bench_wheels_real, "wheels_speed": bench_wheels_speed, "wheels_sim": bench_wheels_sim, "time_offset": bench_time_offset,
               "epuck": bench_epuck, "busy_core": bench_busy_core}

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
