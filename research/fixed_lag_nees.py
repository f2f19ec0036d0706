"""Consistency of the fixed-lag smoother over many seeds (tests/core/test_fixed_lag_consistency.py,
benchmarks/bench_fixed_lag.py): configs/scaled_vo_mocap.yaml at 8 s, 30 Hz, lag 3 s, with the VO scale (true 2.5)
as the calibration parameter; the normalized errors of the scale and of the positions (each state as it left the
window, per axis, every EVERY-th state) and how many fall inside 1/2/3 sigma."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.stats import norm

from fusionkit.config.loader import load_config
from fusionkit.eval.trajectory import matched_positions
from fusionkit.pipeline import estimate

SCALED_VO = Path(__file__).resolve().parents[1] / "configs" / "scaled_vo_mocap.yaml"
TRUE_SCALE = 2.5
EVERY = 15  # every 15th state of 240: neighbouring states' errors are nearly the same sample
IDEAL = np.array([norm.cdf(k) - norm.cdf(-k) for k in (1, 2, 3)]) * 100  # 68.3, 95.4, 99.7
VO_SIGMA_HALVED = ["factors.0.sigma.translation=0.0008"]  # mis-specified: the VO stated twice as precise as it is


def normalized_errors(seed: int, overrides: list[str] = ()) -> tuple[float, np.ndarray]:
    """(scale error / sigma, |per-axis position errors / sigma| of every EVERY-th state) of one fixed-lag run."""
    config = load_config(SCALED_VO, [f"sources.0.seed={seed}", "sources.0.params.duration=8",
                                     "solver={type: fixed_lag, lag: 3.0}", *overrides])
    result = estimate(config, keep_rejected=True)
    scale = result.parameters["cam"]["vo_scale"]
    z_scale = (scale.values[0] - TRUE_SCALE) / scale.sigma[0, 0]
    m = matched_positions(result.trajectories["cam"], result.truth.trajectories["cam"], result.position_sigma["cam"])
    return abs(float(z_scale)), np.abs((m.error / m.sigma)[::EVERY].ravel())


def inside(z: np.ndarray) -> np.ndarray:
    """Percent of |z| inside 1, 2, 3 sigma."""
    return np.array([np.mean(z < k) for k in (1, 2, 3)]) * 100


def shares(seeds, overrides: list[str] = ()) -> dict[str, np.ndarray]:
    """Inside 1/2/3 sigma over `seeds`: the scale alone, the positions, both pooled."""
    runs = [normalized_errors(seed, overrides) for seed in seeds]
    scale = np.array([z for z, _ in runs])
    positions = np.concatenate([p for _, p in runs])
    return {"scale": inside(scale), "positions": inside(positions),
            "pooled": inside(np.concatenate([scale, positions])), "samples": len(scale) + len(positions)}
