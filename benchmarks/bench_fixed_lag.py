"""Fixed-lag smoother: what holding the variables on its marginal factors at GTSAM's frozen point costs and saves
(fusionkit/solve/linear_containers.py). Each config runs with `solver.relinearize_marginal_variables` false
(the default: GTSAM's rule, one linearization point per variable) and true (fusionkit before: the Python factors on
a frozen variable relinearized at its current estimate whenever its step passes the threshold), alternating, in
this process. Per run: tracked Python factors removed and re-added per update (p50, and their share of those the
smoother held), per-update latency p50/p99 (SolveResult.step_latency), ATE, status. The median over runs.

Also the consistency of the sigmas over seeds (research/fixed_lag_nees.py), with the noise stated right and with
the VO stated twice as precise as it is.

Configs: configs/scaled_vo_mocap.yaml at 20 s with a 3 s lag (the calibration parameter: the VO scale), and the
wheels simulator's figure eight (30 s) with the camera, per wheel step at 20 Hz (2 updates per step) and
preintegrated at 2 Hz (both with a 5 s warm-up and a 5 s lag, as in bench_wheels_speed.py)."""

from __future__ import annotations

import numpy as np

from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config

from _timing import latency_percentiles, median_of, run_parts, table
from bench_wheels_speed import CAMERA, preintegrated
import _repository  # noqa: F401,E402  (the repository root on sys.path: research/)
from research.fixed_lag_nees import IDEAL, VO_SIGMA_HALVED, shares

SCALED_VO = "configs/scaled_vo_mocap.yaml"
MODES = {"held (default)": False, "relinearized": True}


def _measure(result) -> dict:
    swaps = result.solution.swaps
    lat = latency_percentiles(result.solution.step_latency * 1e3)
    ate = next(iter(result.evaluation.get("trajectories", {}).values()), {}).get("ate_rmse_m", float("nan"))
    return {"swaps_p50": swaps.get("per_update_p50", 0.0), "share_p50": swaps.get("share_p50", 0.0),
            "p50_ms": lat["p50"], "p99_ms": lat["p99"], "ate_m": ate,
            "rejected": float(result.solution.rejection is not None)}


def _scaled_vo(relinearize: bool, duration: float):
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / SCALED_VO
    config = load_config(path, [f"sources.0.params.duration={duration}", "solver={type: fixed_lag, lag: 3.0}",
                                f"solver.relinearize_marginal_variables={str(relinearize).lower()}",
                                "solver.marginals=false"])
    return estimate(config, keep_rejected=True)


def _wheels(relinearize: bool, duration: float, per_step: bool):
    def edit(config):
        if per_step:
            config["factors"].append(CAMERA)
            settings = {"lag": 5.0, "relinearize_threshold": 1e-4, "updates_per_step": 2}
        else:
            preintegrated(True)(config)
            settings = {"lag": 5.0}
        config["solver"] = {"type": "fixed_lag", "warmup": 5.0, "relinearize_marginal_variables": relinearize,
                            **settings}
    with simulated_config("wheels.sim", {"duration": duration, "path": "figure_eight"}, seed=0, edit=edit) as config:
        return estimate(config, keep_rejected=True)


def compare(name: str, run, repeats: int) -> tuple[str, dict]:
    measured = {mode: [] for mode in MODES}
    for _ in range(repeats):
        for mode, relinearize in MODES.items():
            measured[mode].append(_measure(run(relinearize)))
    raw = {mode: median_of(runs) for mode, runs in measured.items()}
    rows = [[mode, f"{m['swaps_p50']:.0f}", f"{m['share_p50'] * 100:.1f} %", f"{m['p50_ms']:.2f}", f"{m['p99_ms']:.2f}",
             f"{m['ate_m']:.4f}", "rejected" if m["rejected"] else "accepted"] for mode, m in raw.items()]
    held, old = raw["held (default)"], raw["relinearized"]
    raw["latency_ratio_p50"] = held["p50_ms"] / old["p50_ms"]
    text = table(["frozen variables", "swaps/update p50", "share p50", "latency p50 ms", "p99 ms", "ATE m", "status"],
                 rows, f"fixed-lag: {name} (median of {repeats} alternating runs; held / relinearized latency p50 "
                       f"{raw['latency_ratio_p50']:.2f}x)")
    return text, raw


def nees(seeds) -> tuple[str, dict]:
    """Inside 1/2/3 sigma over `seeds` (research/fixed_lag_nees.py), the noise stated right and the VO's halved."""
    raw = {"self-consistency": shares(seeds), "VO sigma stated half its true value": shares(seeds, VO_SIGMA_HALVED)}
    rows = [[f"{noise}: {what}", *(f"{v:.1f}" for v in r[what])] for noise, r in raw.items()
            for what in ("positions", "scale", "pooled")]
    rows.append(["Gaussian", *(f"{v:.1f}" for v in IDEAL)])
    return table(["scaled VO fixed-lag (8 s, lag 3 s)", "1 sigma %", "2 sigma %", "3 sigma %"], rows,
                 f"fixed-lag consistency over {len(seeds)} seeds (positions per axis, every 15th state)"), raw


def run(quick: bool) -> dict:
    repeats = 1 if quick else 3
    duration = 10.0 if quick else 20.0
    wheels = 20.0 if quick else 30.0
    return run_parts({
        "nees": lambda: nees(range(10 if quick else 50)),
        "scaled_vo": lambda: compare(f"scaled VO, {duration:.0f} s, lag 3 s", lambda r: _scaled_vo(r, duration),
                                     repeats),
        "wheels_per_step": lambda: compare(f"wheels per step + camera, {wheels:.0f} s, lag 5 s, 2 updates/step",
                                           lambda r: _wheels(r, wheels, True), 1),
        "wheels_preintegrated": lambda: compare(f"wheels preintegrated + camera, {wheels:.0f} s, lag 5 s",
                                                lambda r: _wheels(r, wheels, False), repeats)})


def summary(results: dict) -> list[str]:
    out = []
    for part, raw in results["raw"].items():
        if part == "nees":
            p = raw["self-consistency"]["positions"]
            out.append(f"fixed_lag consistency: positions inside 1/2/3 sigma {p[0]:.1f}/{p[1]:.1f}/{p[2]:.1f} % "
                       "(self-consistency)")
            continue
        held, old = raw["held (default)"], raw["relinearized"]
        out.append(f"fixed_lag {part}: swaps/update p50 {old['swaps_p50']:.0f} -> {held['swaps_p50']:.0f} "
                   f"(share {old['share_p50'] * 100:.0f} % -> {held['share_p50'] * 100:.0f} %), latency p50 "
                   f"{raw['latency_ratio_p50']:.2f}x, ATE {old['ate_m']:.4f} -> {held['ate_m']:.4f} m")
    return out


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
