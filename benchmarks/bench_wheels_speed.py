"""Speed of the wheel factors (docs/models/wheels.md#speed) on wheels.sim figure eights (20 Hz wheel samples,
no faults), estimated in batch:

  - per step: wheels.encoder for the three wheels, wheels.gyro and wheels.nonholonomic between every two
    samples (5 Python factors per step), with the camera's poses (pose.absolute, 10 Hz);
  - preintegrated: wheels.preintegrated between states every 10 samples, with the camera's poses at the
    states (2 Hz);

each on 10,000 wheel steps (--quick: 2,500), and per step without the camera on 1,200 steps (the
fault-handling setup of configs/wheels_passive.yaml). Without an absolute reference on 10,000 steps GTSAM's
Cholesky declares the system indeterminate: the intrinsics the wheels cannot observe (the length scale,
the heading scale) are held by their priors alone, orders of magnitude weaker than the data on each
single intrinsic. Baseline, in
the same process: the same number of Pose2 states chained by native BetweenFactorPose2 (plain odometry with
known intrinsics), built and solved by gtsam.LevenbergMarquardtOptimizer. Times are fusionkit's pipeline
stages (`estimate()` timings): read (the simulation itself), build, solve (with marginals); "end to end" is
the whole estimate() call without the simulation. Then the fixed-lag smoother's per-step latency (update +
estimate) on 60 s (--quick: 30 s) of each, after a 5 s batch warm-up (the gyro's scale and bias are not yet
observable in the first seconds); the preintegrated config in five runs alternating with a hand-written GTSAM
loop over the same factors (the latencies move by 2x with this machine's state: compare within a run).

    python benchmarks/bench_wheels_speed.py [--quick]
"""

from __future__ import annotations

import time

import gtsam
import numpy as np

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config

from _baselines import hand_fixed_lag, problem_data
from _timing import latency_percentiles, median_of, run_parts, table

CAMERA = {"type": "pose.absolute", "robot": "robot", "stream": "camera",
          "sigma": {"rotation": 0.02, "translation": 0.0028}}


def per_step(camera: bool):
    """The simulator's own config (every wheel, the gyro and no sideways motion at every sample)."""
    def edit(config: dict) -> None:
        if camera:
            config["factors"].append(CAMERA)
            config["initializers"] = [{"type": "pose.interpolate", "robot": "robot", "stream": "camera"}]
    return edit


def preintegrated(camera: bool):
    def edit(config: dict) -> None:
        config["robots"]["robot"]["states"]["every"] = 10
        config["factors"] = [config["factors"][0],
                             {"type": "wheels.preintegrated", "robot": "robot", "stream": "wheels", "sigma": 2e-4,
                              "lateral_sigma": 1e-3}] + ([CAMERA] if camera else [])
        if camera:
            config["initializers"] = [{"type": "pose.interpolate", "robot": "robot", "stream": "camera"}]
    return edit


VARIANTS = {"per step + camera 10 Hz": (per_step(True), None),
            "preintegrated (10 steps) + camera 2 Hz": (preintegrated(True), None),
            "per step, no reference": (per_step(False), 60.0)}


def native_chain(n: int) -> dict[str, float]:
    """n Pose2 states chained by native BetweenFactorPose2 with a prior on the first, from a perturbed start:
    build and LM solve (hand-written GTSAM)."""
    rng = np.random.default_rng(0)
    tic = time.perf_counter()
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-3, 1e-3, 2e-3]))
    graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(), noise))
    step = gtsam.Pose2(0.0075, 0.0, 0.01)
    pose = gtsam.Pose2()
    values.insert(0, pose)
    for k in range(1, n):
        graph.add(gtsam.BetweenFactorPose2(k - 1, k, step, noise))
        pose = pose.compose(gtsam.Pose2(*(np.array([0.0075, 0.0, 0.01]) + rng.normal(scale=1e-3, size=3))))
        values.insert(k, pose)
    build = time.perf_counter() - tic
    tic = time.perf_counter()
    gtsam.LevenbergMarquardtOptimizer(graph, values, gtsam.LevenbergMarquardtParams()).optimize()
    return {"build": build, "solve": time.perf_counter() - tic}


def batch(quick: bool) -> tuple[str, dict]:
    rows, raw = [], {}
    for name, (edit, seconds) in VARIANTS.items():
        duration = seconds or (125.0 if quick else 500.0)
        with simulated_config("wheels.sim", {"duration": duration, "path": "figure_eight"}, seed=0, edit=edit) as config:
            tic = time.perf_counter()
            result = estimate(config, keep_rejected=True)
            total = time.perf_counter() - tic
        t = result.timings
        states = len(result.problem.states["robot"])
        native = native_chain(states)
        ate = result.evaluation["trajectories"]["robot"]["ate_rmse_m"]
        raw[name] = {"states": states, "factors": len(result.problem.records), "read": t["read_s"],
                     "build": t["build_s"], "solve": t["solve_and_marginals_s"], "total": total,
                     "iterations": result.solution.iterations, "ate_m": ate, "native": native}
        rows.append([name, int(duration * 20), states, len(result.problem.records), f"{t['read_s']:.2f}", f"{t['build_s']:.2f}",
                     f"{t['solve_and_marginals_s']:.2f}", result.solution.iterations, f"{total:.2f}",
                     f"{total - t['read_s']:.2f}", f"{(total - t['read_s']) / (native['build'] + native['solve']):.1f}",
                     f"{ate:.4f}"])
    return table(["variant", "steps", "states", "factors", "read (sim) s", "build s", "solve s", "iterations", "total s",
                  "total - read s", "/ native chain", "ATE m"], rows,
                 "wheels batch, end to end"), raw


ALTERNATIONS = 5  # preintegrated fixed-lag: runs of fusionkit and of the hand-written loop, alternating


def fixed_lag(quick: bool) -> tuple[str, dict]:
    """Per step: the simulator's config plus the camera, started by dead reckoning; the intrinsics are
    ~0.04 m, so relinearize below 1e-4; with one update per step (one Gauss-Newton step) and with two.
    Preintegrated: as in batch, run ALTERNATIONS times alternating with a hand-written GTSAM loop over the
    same factors, warm-up and lag (_baselines.hand_fixed_lag: the Python factors handed to the smoother as
    CustomFactors); each run's percentiles, the median over runs reported. A run the smoother loses is
    reported as diverged."""
    from fusionkit.api import SolverError
    duration = 30.0 if quick else 60.0
    rows, raw = [], {}
    for name, edit, settings, runs in (
            ("per step + camera, 20 Hz, 1 update/step", lambda c: c["factors"].append(CAMERA),
             {"lag": 2.0, "relinearize_threshold": 1e-4, "updates_per_step": 1}, 1),
            ("per step + camera, 20 Hz, 2 updates/step", lambda c: c["factors"].append(CAMERA),
             {"lag": 2.0, "relinearize_threshold": 1e-4, "updates_per_step": 2}, 1),
            ("preintegrated + camera, 2 Hz", preintegrated(True), {"lag": 5.0}, ALTERNATIONS)):
        def solver(config, edit=edit, settings=settings):
            edit(config)
            config["solver"] = {"type": "fixed_lag", "warmup": 5.0, **settings}
        ours, hand = [], []
        for _ in range(runs):
            with simulated_config("wheels.sim", {"duration": duration, "path": "figure_eight"}, seed=0,
                                  edit=solver) as config:
                try:
                    result = estimate(config, keep_rejected=True)
                except SolverError as exc:
                    raw[name] = {"diverged": str(exc)}
                    break
            ours.append(latency_percentiles(result.solution.step_latency * 1e3))
            if runs > 1:
                hand.append(latency_percentiles(hand_fixed_lag(*problem_data(result.problem),
                                                               {"warmup": 5.0, **settings}) * 1e3))
        if name in raw:
            rows.append([name, "-", "diverged", "", "", ""])
            continue
        ate = result.evaluation["trajectories"]["robot"]["ate_rmse_m"]
        for label, measured, ate_text in ((name, ours, f"{ate:.4f}"), ("  hand-written GTSAM loop, same factors",
                                                                        hand, "")):
            if not measured:
                continue
            row = median_of(measured)  # ms
            raw[label.strip()] = {"runs": len(measured), **row,
                                  "p99_runs": [m["p99"] for m in measured], **({"ate_m": ate} if ate_text else {})}
            rows.append([label, int(row["steps"]), len(measured), f"{row['p50']:.3f}", f"{row['p99']:.3f}", f"{row['max']:.2f}",
                         ate_text])
    text = table(["variant", "steps", "runs", "p50 ms", "p99 ms", "max ms", "ATE m"], rows,
                 f"wheels fixed-lag (5 s batch warm-up): per-step latency over {duration:.0f} s (median over runs)")
    for name, d in raw.items():
        if d.get("runs", 1) > 1:
            text += f"\n{name}: p99 of each run " + ", ".join(f"{v:.3f}" for v in d["p99_runs"]) + " ms"
    return text, raw


def run(quick: bool) -> dict:
    return run_parts({"batch": lambda: batch(quick), "fixed_lag": lambda: fixed_lag(quick)})


def summary(results: dict) -> list[str]:
    lines = []
    results = results.get("raw", {})
    for name, d in results.get("batch", {}).items():
        lines.append(f"wheels batch {name}: {d['states']} states, {d['total'] - d['read']:.2f} s end to end "
                     f"(without the simulation), {(d['total'] - d['read']) / (d['native']['build'] + d['native']['solve']):.1f}x "
                     "a native odometry chain")
    fixed = results.get("fixed_lag", {})
    hand = fixed.get("hand-written GTSAM loop, same factors")
    for name, d in fixed.items():
        if name.startswith("hand-written"):
            continue
        line = "diverged" if "diverged" in d else f"p99 {d['p99']:.2f} ms per step"
        if hand and name.startswith("preintegrated") and "diverged" not in d:
            line += f" ({d['p99'] / hand['p99']:.2f}x the hand-written loop's {hand['p99']:.2f} ms)"
        lines.append(f"wheels fixed-lag {name}: {line}")
    return lines


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
