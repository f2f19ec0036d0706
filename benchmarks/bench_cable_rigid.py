"""ARAS-CAM (docs/models/cable_rigid.md) on simulated sequences: accuracy against the published figures
and speed against baselines measured in this process.

Accuracy (research/cable_rigid_experiments.py, `cable.cdpr` simulator, 750 poses at 30 Hz):
  thesis Table 4.1 -- position RMSE of forward kinematics alone, VO alone and the fused graph, per sequence
  (dynamic = 01, smooth = 12); the cable-length residual before/after refinement; the share of
  position errors inside 1/2/3 sigma pooled over the seeds; the gain of pulley pseudo-measurements.
Speed:
  Monte-Carlo initializer (750 poses x 5000 particles x 4 cables) against ONE brute-force pass of
  the exact likelihood over all particles and poses; batch refinement (fusionkit LM) against GTSAM's
  LevenbergMarquardtOptimizer on the same graph and initial values; incremental per-frame latency
  (update + calculateEstimate, what a real-time user waits for) of the fixed-lag smoother against a
  hand-written IncrementalFixedLagSmoother loop over the same factors, and of iSAM2, both against
  the 33.3 ms frame period of a 30 Hz camera.

    python benchmarks/bench_cable_rigid.py [--quick]
"""

from __future__ import annotations

import time

import gtsam
import numpy as np

from fusionkit.pipeline import build_problem, read_sources

import _repository  # noqa: F401,E402  (the repository root on sys.path: research/)
from research.cable_rigid_experiments import (SEQUENCES, loaded_sequence, pseudo_measurement_gain, run_sequence,
                                              table_4_1)
from _baselines import hand_fixed_lag, problem_data
from _timing import ms, ratio, run_parts, table, timed

FRAME_PERIOD = 1 / 30.0
SOURCE = {"dynamic": (0.036, 0.05, 0.029), "smooth": (0.035, 0.03, 0.028)}  # Table 4.1: FK, VO, fused
SOURCE_RESIDUAL = {"dynamic": (0.043, 0.0049), "smooth": (0.03, 0.005)}
FIXED_LAG = {"type": "fixed_lag", "lag": 1.0, "warmup": 14.0, "relinearize_threshold": 0.05}
ISAM2 = {"type": "isam2", "warmup": 14.0, "relinearize_threshold": 0.05}


def accuracy(seeds: range) -> tuple[str, dict]:
    rows, cons, out = [], [], {}
    for motion in SEQUENCES:
        r = table_4_1(motion, seeds)
        out[motion] = r
        e = r["errors_m"]
        fk, vo, fused = SOURCE[motion]
        rows.append([motion, f"{e['forward_kinematics']:.4f}", f"{e['visual_odometry']:.4f}", f"{e['fused']:.4f}",
                     f"{100 * r['improvement_over_fk']:.0f}% / {100 * r['improvement_over_vo']:.0f}%",
                     f"{r['fused_beats_both']}/{r['runs']}",
                     f"{r['cable_residual_m'][0]:.4f} -> {r['cable_residual_m'][1]:.5f}",
                     f"{fk} {vo} {fused}; {SOURCE_RESIDUAL[motion][0]} -> {SOURCE_RESIDUAL[motion][1]}"])
        for axis, v in r["consistency_percent"].items():
            cons.append([f"{motion} {axis}", *(f"{x:.1f}" for x in v)])
    text = table(["sequence", "FK (m)", "VO (m)", "fused (m)", "fused better than FK / VO", "fused < both",
                  "cable residual rms (m)", "thesis: FK VO fused; residual"], rows,
                 f"thesis Table 4.1: position RMSE, mean over {len(seeds)} seeds per sequence")
    text += "\n\n" + table(["sequence axis", "1 sigma", "2 sigma", "3 sigma"],
                           cons + [["ideal", "68.3", "95.4", "99.7"], ["thesis (x, y, z)", "53 71 51", "82 93 88",
                                                                         "95 97 99"]],
                           f"thesis Table 4.2: position errors inside the bound (%), pooled over {len(seeds)} seeds")
    text += "\n" + "  ".join(f"{m}: pulleys {out[m]['pulley_error_m'] * 100:.1f} cm mean error, scale z rms "
                             f"{out[m]['scale_z_rms']:.2f}, LM iterations {min(out[m]['iterations'])}-"
                             f"{max(out[m]['iterations'])}" for m in SEQUENCES)
    return text, out


def pseudo(seeds: range) -> tuple[str, dict]:
    rows, out = [], {}
    for motion in SEQUENCES:
        g = out[motion] = pseudo_measurement_gain(motion, seeds)
        rows.append([motion, f"{100 * g['without']['base_frame_m']:.1f} -> {100 * g['with']['base_frame_m']:.1f} "
                     f"({100 * g['reduction_base_frame']:.0f}%)",
                     f"{100 * g['without']['shape_m']:.2f} -> {100 * g['with']['shape_m']:.2f} "
                     f"({100 * g['reduction_shape']:.0f}%)"])
    text = table(["sequence", "pulley error, base frame (cm)", "pulley geometry after rigid alignment (cm)"], rows,
                 f"Pseudo-measurements (coplanar pulleys, 4 taped distances, 3 mm): mean over {len(seeds)} seeds")
    return text, out


def problem_of(solver: dict | None = None, motion: str = "smooth", seed: int = 0):
    """The built graph (fusionkit.graph.builder.Problem) of one simulated sequence."""
    with loaded_sequence(motion, seed, solver=solver) as config:
        streams, _ = read_sources(config)
        return build_problem(config, streams)


def brute_force_pass(problem) -> float:
    """Seconds of one exact evaluation of r = |c + s d - a| - l over 5000 particles x 750 poses,
    for each of 4 cables (what a per-particle, per-pose Monte-Carlo step costs at least)."""
    rng = np.random.default_rng(0)
    K, P = len(problem.states["cdpr"]), 5000
    c, d = rng.normal(size=(K, 3)), rng.normal(size=(K, 3))
    a, s, l = rng.normal(size=(P, 3)), rng.uniform(1, 3, P), rng.uniform(1, 3, (K,))
    tic = time.perf_counter()
    for _ in range(4):
        q = c[None] + s[:, None, None] * d[None] - a[:, None, :]
        r = np.sqrt(np.einsum("pki,pki->pk", q, q)) - l
        np.einsum("pk,pk->p", r, r)
    return time.perf_counter() - tic


def gtsam_lm(problem) -> tuple[float, int, float]:
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-6)
    params.setAbsoluteErrorTol(1e-9)
    params.setMaxIterations(100)
    opt = gtsam.LevenbergMarquardtOptimizer(problem.graph(), problem.initial, params)
    values, seconds = timed(opt.optimize)
    return seconds, opt.iterations(), problem.graph().error(values)


def speed() -> tuple[str, dict]:
    out: dict = {}
    # Monte-Carlo initializer and batch refinement, one run
    result = run_sequence("smooth", 0)
    mc = next(v for k, v in result.problem.diagnostics.items() if "monte_carlo" in k)
    brute = min(brute_force_pass(result.problem) for _ in range(3))
    lm = result.solution.seconds
    problem = problem_of()
    gt_s, gt_it, gt_cost = gtsam_lm(problem)
    out["monte_carlo_s"], out["brute_pass_s"] = mc["seconds"], brute
    out["lm_s"], out["gtsam_lm_s"] = lm, gt_s
    rows = [["Monte-Carlo init (750 x 5000 x 4)", f"{mc['seconds']:.3f}", f"{brute:.3f} (one exact pass)",
             ratio(mc["seconds"], brute), "< 1 s (source: ~60 s per cable)"],
            [f"batch LM ({result.solution.iterations} it., cost {result.solution.final_error:.1f})", f"{lm:.3f}",
             f"{gt_s:.3f} (GTSAM LM, {gt_it} it., cost {gt_cost:.1f})", ratio(lm, gt_s), "< 2 s (source: ~30 s)"]]
    # incremental
    lat_rows = []
    for name, settings in (("fixed-lag 1 s", FIXED_LAG), ("iSAM2", ISAM2)):
        for motion in SEQUENCES:
            r = run_sequence(motion, 0, solver=settings)
            lat = r.solution.step_latency
            out[f"{name} {motion}"] = {"p50": float(np.percentile(lat, 50)), "p99": float(np.percentile(lat, 99)),
                                       "max": float(lat.max()), "warmup": r.solution.warmup_seconds,
                                       "ate": r.evaluation["trajectories"]["cdpr"]["ate_rmse_m"]}
            row = out[f"{name} {motion}"]
            lat_rows.append([f"{name}, {motion}", ms(row["p50"]), ms(row["p99"]), ms(row["max"]),
                             ratio(row["p99"], FRAME_PERIOD), f"{row['warmup']:.2f}", f"{100 * row['ate']:.2f}"])
    hand = hand_fixed_lag(*problem_data(problem_of(FIXED_LAG)), FIXED_LAG)
    fk = out["fixed-lag 1 s smooth"]
    lat_rows.append(["hand-written fixed-lag, smooth", ms(np.percentile(hand, 50)), ms(np.percentile(hand, 99)),
                     ms(hand.max()), ratio(np.percentile(hand, 99), FRAME_PERIOD), "", ""])
    out["hand_fixed_lag"] = {"p50": float(np.percentile(hand, 50)), "p99": float(np.percentile(hand, 99))}
    text = table(["step", "fusionkit (s)", "baseline (s)", "ratio", "goal"], rows, "Speed: ARAS-CAM, 750 poses")
    text += "\n\n" + table(["incremental (warm-up 14 s, then per frame)", "p50 (ms)", "p99 (ms)", "max (ms)",
                            "p99 / 33.3 ms", "warm-up (s)", "ATE (cm)"], lat_rows,
                           "Incremental: per-frame latency (update + calculateEstimate) against the 30 Hz frame "
                           "period")
    text += (f"\nfixed-lag: fusionkit / hand-written loop p50 {ratio(fk['p50'], out['hand_fixed_lag']['p50'])}, "
             f"p99 {ratio(fk['p99'], out['hand_fixed_lag']['p99'])}")
    return text, out


def run(quick: bool) -> dict:
    seeds = range(5) if quick else range(30)
    return run_parts({"accuracy": lambda: accuracy(seeds), "pseudo": lambda: pseudo(range(3 if quick else 10)),
                      "speed": speed})


def summary(results: dict) -> list[str]:
    acc, spd = results["raw"]["accuracy"], results["raw"]["speed"]
    lines = []
    for m in SEQUENCES:
        e = acc[m]["errors_m"]
        lines.append(f"ARAS-CAM {m}: FK {e['forward_kinematics'] * 100:.2f} cm, VO {e['visual_odometry'] * 100:.2f} cm, "
                     f"fused {e['fused'] * 100:.2f} cm; cable residual {acc[m]['cable_residual_m'][0] * 1e3:.1f} -> "
                     f"{acc[m]['cable_residual_m'][1] * 1e3:.2f} mm")
    lines.append(f"ARAS-CAM speed: Monte-Carlo {spd['monte_carlo_s']:.2f} s, batch LM {spd['lm_s']:.2f} s "
                 f"({ratio(spd['lm_s'], spd['gtsam_lm_s'])} GTSAM's LM), fixed-lag p99 "
                 f"{spd['fixed-lag 1 s dynamic']['p99'] * 1e3:.1f} ms per frame")
    return lines


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
