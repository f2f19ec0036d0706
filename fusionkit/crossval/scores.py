"""Held-out prediction errors per entry and residual part: per fold, and pooled over the folds.

Each prediction's error in a part is the norm of its residual's rows of that part (a position error in m, an
orientation error in rad, a range error in m); its expected square is the trace of its predicted covariance's block.
Per fold: count, RMS, largest, the last in time (`final`: the end of a held-out stretch of trajectory), and the RMS
the model predicts; e^T S^-1 e summed with its dimension for the predictive check. Pooled: the RMS over every
held-out prediction of every fold, the largest, the spread of the folds' RMS, and the check's ratio.
"""

from __future__ import annotations

import numpy as np

from ..components import ResidualPart
from .predict import HeldOut
from ..solve import chi_square

CHECK_P = 1e-3     # the predictive check fails beyond the chi-square's two-sided 1 - CHECK_P interval ...
CHECK_FACTOR = 2.0  # ... and when the ratio is also beyond this factor (or below its inverse)


def whole(dim: int) -> list[ResidualPart]:
    """The default part: the whole residual, in its stream's units."""
    return [ResidualPart("residual", "", tuple(range(dim)))]


def fold_scores(held: HeldOut, parts: dict[str, list[ResidualPart]]) -> dict[str, dict]:
    """entry label -> {count, chi2, dim, parts: name -> {unit, count, sum_sq, rmse, max, final, expected_sq,
    predicted_rmse}} of one fold's predictions."""
    out: dict[str, dict] = {}
    by_entry: dict[str, list] = {}
    for p in held.predictions:
        by_entry.setdefault(p.label, []).append(p)
    for label, predictions in by_entry.items():
        predictions.sort(key=lambda p: p.time)
        dim = len(predictions[0].residual)
        chi2s = [p.chi2 for p in predictions if np.isfinite(p.chi2)]
        entry = {"count": len(predictions), "chi2": float(np.sum(chi2s)), "dim": dim * len(chi2s), "parts": {}}
        for part in parts.get(label) or whole(dim):
            rows = list(part.rows)
            norms = np.array([np.linalg.norm(p.residual[rows]) for p in predictions])
            expected = np.array([np.trace(p.covariance[np.ix_(rows, rows)]) for p in predictions])
            entry["parts"][part.name] = {
                "unit": part.unit, "count": len(norms), "sum_sq": float(np.sum(norms ** 2)),
                "rmse": float(np.sqrt(np.mean(norms ** 2))), "max": float(norms.max()), "final": float(norms[-1]),
                "expected_sq": float(np.sum(expected)), "predicted_rmse": float(np.sqrt(np.mean(expected)))}
        out[label] = entry
    return out


def predictive_check(chi2_sum: float, dim: int) -> str | None:
    """Why the held-out errors and the model's sigmas disagree, or None (module constants)."""
    if dim == 0:
        return None
    ratio = chi2_sum / dim
    low, high = chi_square.quantile(CHECK_P / 2, dim), chi_square.quantile(1 - CHECK_P / 2, dim)
    if chi2_sum > high and ratio > CHECK_FACTOR:
        return (f"held-out errors {np.sqrt(ratio):.2g}x what the model's sigmas predict: the calibrated model "
                "misses something the training data did not show, or the noise sigmas are too small")
    if chi2_sum < low and ratio < 1 / CHECK_FACTOR:
        return (f"held-out errors {np.sqrt(ratio):.2g}x what the model's sigmas predict: the noise sigmas are "
                "stated too large")
    return None


def pooled(folds: list[dict]) -> dict[str, dict]:
    """entry label -> {count, chi2_per_dim, check, parts: name -> pooled figures} over the folds that ran."""
    out: dict[str, dict] = {}
    for fold in folds:
        for label, entry in fold.get("entries", {}).items():
            into = out.setdefault(label, {"count": 0, "chi2": 0.0, "dim": 0, "parts": {}})
            into["count"] += entry["count"]
            into["chi2"] += entry["chi2"]
            into["dim"] += entry["dim"]
            for name, part in entry["parts"].items():
                p = into["parts"].setdefault(name, {"unit": part["unit"], "count": 0, "sum_sq": 0.0, "max": 0.0,
                                                    "expected_sq": 0.0, "fold_rmse": []})
                p["count"] += part["count"]
                p["sum_sq"] += part["sum_sq"]
                p["expected_sq"] += part["expected_sq"]
                p["max"] = max(p["max"], part["max"])
                p["fold_rmse"].append(part["rmse"])
    for entry in out.values():
        entry["chi2_per_dim"] = entry["chi2"] / entry["dim"] if entry["dim"] else None
        entry["check"] = predictive_check(entry["chi2"], entry["dim"])
        for p in entry["parts"].values():
            p["rmse"] = float(np.sqrt(p["sum_sq"] / p["count"]))
            p["predicted_rmse"] = float(np.sqrt(p["expected_sq"] / p["count"]))
            p["fold_std"] = float(np.std(p["fold_rmse"], ddof=1)) if len(p["fold_rmse"]) > 1 else 0.0
    return out
