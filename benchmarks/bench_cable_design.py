"""Designed against random static poses for a cable robot's pulley and offset calibration
(docs/models/cable_rigid.md#pose-selection): `select-cable-poses`'s D-optimal choice of N poses from 500 taut
candidates, against the first N, 2N and 3N candidates in random order, each calibrated by fusionkit from simulated
measurements (motion capture 1 mm / 2 mrad, encoders 1 mm; the estimator's noise is the simulator's: a
self-consistency check), over 24 seeds (4 with --quick) for N = 8 and 12: the pulleys' error (RMS over their
axes and over the seeds), the RMS sigma the design predicted for those poses, the offsets' error, and the
reported sigmas against the predicted ones (all axes, all seeds).

    python benchmarks/bench_cable_design.py [--quick]
"""

from __future__ import annotations

import numpy as np

import _repository  # noqa: F401,E402  (the repository root on sys.path: research/)
from research.cable_design_experiments import case
from _timing import run_parts, table, timed


def comparison(seeds, counts) -> tuple[str, dict]:
    rows, raw = [], {}
    for count in counts:
        cases, seconds = timed(lambda: [case(seed, count) for seed in seeds])
        for label in cases[0]:
            pulley = np.array([c[label]["pulley_rms_m"] for c in cases])
            offset = np.array([c[label]["offset_rms_m"] for c in cases])
            predicted = np.array([np.sqrt(np.mean(c[label]["predicted"][:12] ** 2)) for c in cases])
            ratio = np.concatenate([c[label]["reported"] / c[label]["predicted"] for c in cases])
            poses = count * (1 if label == "designed" else int(label.split("x")[1]))
            entry = {"poses": poses, "pulley_rms_mm": 1e3 * float(np.sqrt(np.mean(pulley ** 2))),
                     "predicted_mm": 1e3 * float(np.sqrt(np.mean(predicted ** 2))),
                     "offset_rms_mm": 1e3 * float(np.sqrt(np.mean(offset ** 2))),
                     "reported_over_predicted": (float(ratio.min()), float(ratio.max())),
                     "rejected": sum(c[label]["status"] != "accepted" for c in cases)}
            raw[f"N={count} {label}"] = entry
            rows.append([f"N={count} {label}", poses, f"{entry['pulley_rms_mm']:.2f}", f"{entry['predicted_mm']:.2f}",
                         f"{entry['offset_rms_mm']:.2f}", "%.2f .. %.2f" % entry["reported_over_predicted"],
                         entry["rejected"]])
        raw[f"N={count} seconds"] = seconds
    return table(["poses chosen", "poses", "pulley error rms (mm)", "design predicted (mm)", "offset error rms (mm)",
                  "reported / predicted sigma", "rejected"], rows,
                 f"designed vs random static poses, ARAS-CAM, {len(seeds)} seeds"), raw


def run(quick: bool) -> dict:
    return run_parts({"comparison": lambda: comparison(range(4 if quick else 24), (8,) if quick else (8, 12))})


def summary(results: dict) -> list[str]:
    raw = results["raw"]["comparison"]
    d, r2 = raw["N=8 designed"], raw["N=8 random x2"]
    return [f"cable pose design: 8 designed poses {d['pulley_rms_mm']:.2f} mm pulley error rms (predicted "
            f"{d['predicted_mm']:.2f}), 16 random {r2['pulley_rms_mm']:.2f} mm"]


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
