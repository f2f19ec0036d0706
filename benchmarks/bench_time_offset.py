"""Time offsets between sensor streams, estimated in the graph (docs/models/unified_graph.md#time-offsets).

Accuracy (research/time_offset_experiments.py; simulated data, the estimator given the simulator's noise
levels -- a self-consistency check -- and, for the offset's sigma, misstated by x0.5 and x2):
  cable robot, motion capture at 4 Hz, encoders lagging 30 ms, swinging end-effector: the offset's error and
  sigma; the cable lengths predicted on the held-out second half with and without the offset, against the
  noise floor (the same prediction with the true calibration and offset);
  the offset's z-scores over 20 seeds (quick: 8), and with the noise misstated (full);
  the offset on the dense stream instead (full): one state per 4 Hz frame cannot follow the swing, so
  states at 40 Hz with the offset on the 40 Hz encoders; its bias;
  UWB with a 50 ms ranging lag: position error with and without the offset, constant biases and the
  simulator's drifting ones;
  IMU against motion capture lagging 20 ms (uwb.drone): the guess's and the graph's errors, z-scores over 20
  seeds (quick: 4), the states' IMU velocities used in the interpolation or not, and the mocap noise misstated.
Cost: linearizing a shifted factor (the state at the sample's time on the curve through four states)
against the plain native factor it wraps (cable range factor), per factor, in this process; the
calibration's solve with and without the offset.

    python benchmarks/bench_time_offset.py [--quick]
"""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.graph.noise import gaussian
from fusionkit.graph.variables import POINT3, POSE3, SCALAR
from fusionkit.time_offset.interpolation import Shift, Timing, shifted_factor

import _repository  # noqa: F401,E402  (the repository root on sys.path: research/)
from research.time_offset_experiments import DRONE_LAG, LAG, UWB, UWB_LAG, cable_case, drone_case, uwb_case
from _timing import median_time, ratio, run_parts, table, us

SELF_CONSISTENCY = "self-consistency (estimator noise = generator noise)"


def cable(seeds) -> tuple[str, dict]:
    rows, raw = [], []
    for seed in seeds:
        with_offset, without = cable_case(seed), cable_case(seed, offset=False)
        raw.append({"with": with_offset, "without": without})
        rows.append([seed, f"{with_offset['error_s'] * 1e3:+.3f}", f"{with_offset['sigma_s'] * 1e3:.3f}",
                     f"{with_offset['floor_m'] * 1e3:.3f}", f"{with_offset['heldout_m'] * 1e3:.3f}",
                     f"{with_offset['heldout_m'] / with_offset['floor_m']:.2f}", f"{without['heldout_m'] * 1e3:.2f}",
                     f"{without['heldout_m'] / with_offset['heldout_m']:.1f}x",
                     f"{with_offset['estimate_s']:.2f} / {without['estimate_s']:.2f}"])
    ratios = [r["with"]["heldout_m"] / r["with"]["floor_m"] for r in raw]
    worse = [r["without"]["heldout_m"] / r["with"]["heldout_m"] for r in raw]
    errors = np.array([r["with"]["error_s"] for r in raw])
    text = table(["seed", "offset error (ms)", "sigma (ms)", "floor (mm)", "held out (mm)", "/ floor",
                  "no offset (mm)", "worse by", "solve s (offset / none)"], rows,
                 f"Cable robot, mocap 4 Hz, encoders lag {LAG * 1e3:.0f} ms, swinging: held-out cable lengths "
                 f"({SELF_CONSISTENCY})")
    text += (f"\nheld out / floor: worst {max(ratios):.2f}; without the offset worse by {min(worse):.1f}-"
             f"{max(worse):.1f}x; largest offset error {np.abs(errors).max() * 1e3:.3f} ms")
    return text, {"runs": raw, "worst_ratio": max(ratios), "worse_by": [min(worse), max(worse)],
                  "max_error_s": float(np.abs(errors).max())}


def z_scores(seeds, noises: dict[str, dict]) -> tuple[str, dict]:
    rows, raw = [], {}
    for name, noise in noises.items():
        runs = [cable_case(seed, noise=noise) for seed in seeds]
        z = np.array([r["z"] for r in runs])
        raw[name] = {"z": z.tolist(), "mean": float(z.mean()), "std": float(z.std(ddof=1)),
                     "within": [float(np.mean(np.abs(z) <= n) * 100) for n in (1, 2, 3)]}
        rows.append([name, len(z), f"{z.mean():+.2f}", f"{z.std(ddof=1):.2f}",
                     " / ".join(f"{w:.0f}" for w in raw[name]["within"]),
                     f"{np.mean([r['sigma_s'] for r in runs]) * 1e3:.3f}"])
    text = table(["estimator noise", "seeds", "mean z", "std z", "|z| <= 1/2/3 (%)", "mean sigma (ms)"], rows,
                 "Offset z-scores (error / reported sigma); ideal mean 0, std 1, 68/95/99.7 %")
    return text, raw


def dense_side(seeds) -> tuple[str, dict]:
    runs = [cable_case(seed, offset_on="encoders") for seed in seeds]
    z = np.array([r["z"] for r in runs])
    err = np.array([r["error_s"] for r in runs])
    text = table(["offset on", "seeds", "mean error (ms)", "mean z", "std z", "held out / floor (worst)"],
                 [["encoders (40 Hz, states on the mocap clock)", len(z), f"{err.mean() * 1e3:+.3f}",
                   f"{z.mean():+.2f}", f"{z.std(ddof=1):.2f}",
                   f"{max(r['heldout_m'] / r['floor_m'] for r in runs):.2f}"]],
                 "The offset on the dense stream (every sample between states)")
    return text, {"z": z.tolist(), "error_s": err.tolist()}


def uwb(seeds, duration: float) -> tuple[str, dict]:
    rows, raw = [], {}
    for model, extra in (("constant biases", {"bias_model": "constant", "bias_drift": 0.0}),
                         ("drifting biases (simulator default)", {})):
        params = {**UWB, **extra}
        runs = [{"with": uwb_case(seed, True, duration, params), "without": uwb_case(seed, False, duration, params)}
                for seed in seeds]
        raw[model] = runs
        w = np.mean([r["with"]["position_m"] for r in runs])
        wo = np.mean([r["without"]["position_m"] for r in runs])
        rows.append([model, len(runs), f"{wo * 100:.2f}", f"{w * 100:.2f}", f"{wo / w:.2f}x",
                     ", ".join(f"{r['with']['offset_s'] * 1e3:.0f}+-{r['with']['sigma_s'] * 1e3:.0f}" for r in runs),
                     f"{np.mean([r['with']['solve_s'] for r in runs]):.2f} / "
                     f"{np.mean([r['without']['solve_s'] for r in runs]):.2f}"])
    text = table(["biases", "seeds", "no offset (cm)", "offset (cm)", "gain", "offset estimates (ms)",
                  "solve s (offset / none)"], rows,
                 f"UWB, ranges lag {UWB_LAG * 1e3:.0f} ms (true offset {-UWB_LAG * 1e3:.0f} ms), {duration:.0f} s at "
                 f"10 Hz: position RMSE ({SELF_CONSISTENCY})")
    return text, raw


def drone(seeds, noises: dict[str, float]) -> tuple[str, dict]:
    rows, raw = [], {}
    for label, noise in noises.items():
        for velocities in (True, False):
            runs = [drone_case(seed, velocities, noise) for seed in seeds]
            z = np.array([r["z"] for r in runs])
            name = f"{label}, {'with' if velocities else 'without'} IMU velocities"
            raw[name] = {"runs": runs, "mean_z": float(z.mean()), "std_z": float(z.std(ddof=1))}
            rows.append([name, len(runs), f"{np.max(np.abs([r['guess_error_s'] for r in runs])) * 1e3:.2f}",
                         f"{np.sqrt(np.mean([r['error_s'] ** 2 for r in runs])) * 1e3:.3f}",
                         f"{np.mean([r['sigma_s'] for r in runs]) * 1e3:.3f}", f"{z.mean():+.2f}",
                         f"{z.std(ddof=1):.2f}", " / ".join(f"{np.mean(np.abs(z) <= n) * 100:.0f}" for n in (1, 2, 3)),
                         f"{np.mean([r['solve_s'] for r in runs]):.2f}"])
    text = table(["estimator", "seeds", "worst guess error (ms)", "rms error (ms)", "mean sigma (ms)", "mean z",
                  "std z", "|z| <= 1/2/3 (%)", "solve s"], rows,
                 f"IMU (states, 10 Hz) against motion capture (50 Hz) lagging {DRONE_LAG * 1e3:.0f} ms, uwb.drone 30 s")
    return text, raw


def _range_graphs(samples: int, per_sample: int, rng) -> tuple:
    """`samples` x `per_sample` cable range factors (a 4-cable robot: 4 per sample), plain on a state and
    shifted onto the curve through 4 states; and two sets of values whose offsets differ (alternating between
    them, every linearization computes its curves anew instead of reusing the last ones)."""
    window_t, pulley, l0, delta = np.array([0.0, 0.025, 0.05, 0.075]), 5 * 10 ** 6, 6 * 10 ** 6, 7 * 10 ** 6
    plain, shifted, values = gtsam.NonlinearFactorGraph(), gtsam.NonlinearFactorGraph(), gtsam.Values()
    types = {delta: SCALAR}
    for i in range(samples):
        window = tuple(10 * i + j for j in range(4))
        for key in window:
            values.insert(key, gtsam.Pose3.Expmap(rng.normal(size=6) * 0.2))
            types[key] = POSE3
        shift = Shift(9 * 10 ** 6 + i, POSE3, Timing(0.03, 0.0, window_t), window, delta)
        for c in range(per_sample):
            types[pulley + c], types[l0 + c] = POINT3, SCALAR
            mount = gtsam.Pose3(gtsam.Rot3(), [0.1 * (c + 1), 0.0, 0.0])
            plain.add(gtsam.RangeFactorWithTransformBias3D(window[1], pulley + c, l0 + c, 3.0, gaussian([0.001]),
                                                           mount))
            inner = gtsam.RangeFactorWithTransformBias3D(shift.key, pulley + c, l0 + c, 3.0, gaussian([0.001]), mount)
            shifted.add(shifted_factor(inner, [shift], types.get))
    for c in range(per_sample):
        values.insert(pulley + c, np.array([2.0, 1.0 + c, 3.0]))
        values.insert(l0 + c, -1.0)
    values.insert(delta, 0.010)
    other = gtsam.Values(values)
    other.update(delta, 0.011)
    return plain, shifted, values, other


def cost() -> tuple[str, dict]:
    """Linearize cable range factors, plain (on the state) and shifted (on the curve through 4 states)."""
    rng, rows, raw = np.random.default_rng(0), [], {}
    for per_sample in (1, 4):
        plain, shifted, a, b = _range_graphs(1000 // per_sample, per_sample, rng)
        n = plain.size()
        t_plain = median_time(lambda: (plain.linearize(a), plain.linearize(b))) / 2
        t_shift = median_time(lambda: (shifted.linearize(a), shifted.linearize(b))) / 2
        raw[per_sample] = {"plain_s": t_plain / n, "shifted_s": t_shift / n, "ratio": t_shift / t_plain}
        rows.append([f"{per_sample} factor(s) per sample", us(t_plain / n), us(t_shift / n), ratio(t_shift, t_plain)])
    text = table(["cable range factors", "native on a state (us)", "shifted (us)", "ratio"], rows,
                 "Cost of the time-offset evaluation: linearize per factor (1000 factors, median of 5)")
    text += ("\nshifted: the state at t + offset on the curve through 4 states, computed once per sample and "
             "shared by its factors (4 cables: one curve for 4 factors)")
    return text, {"per_sample": raw, "ratio": raw[4]["ratio"]}


def run(quick: bool) -> dict:
    if quick:
        return run_parts({"cable": lambda: cable(range(2)),
                          "z_scores": lambda: z_scores(range(8), {SELF_CONSISTENCY: {}}),
                          "uwb": lambda: uwb(range(1), 30.0), "drone": lambda: drone(range(4), {SELF_CONSISTENCY: 1.0}),
                          "cost": cost})
    noises = {SELF_CONSISTENCY: {}, "encoder sigma x0.5": {"encoder": 0.5}, "encoder sigma x2": {"encoder": 2.0},
              "mocap sigma x0.5": {"mocap": 0.5}, "mocap sigma x2": {"mocap": 2.0}}
    return run_parts({"cable": lambda: cable(range(5)), "z_scores": lambda: z_scores(range(20), noises),
                      "dense_side": lambda: dense_side(range(10)), "uwb": lambda: uwb(range(3), UWB["duration"]),
                      "drone": lambda: drone(range(20), {SELF_CONSISTENCY: 1.0, "mocap sigma x2": 2.0,
                                                         "mocap sigma x0.5": 0.5}),
                      "cost": cost})


def summary(results: dict) -> list[str]:
    raw = results["raw"]
    c, z = raw["cable"], raw["z_scores"][SELF_CONSISTENCY]
    constant = raw["uwb"]["constant biases"]
    w = np.mean([r["with"]["position_m"] for r in constant])
    wo = np.mean([r["without"]["position_m"] for r in constant])
    return [f"time offset, cable (mocap 4 Hz, encoders lag 30 ms): held-out lengths <= {c['worst_ratio']:.2f}x the "
            f"noise floor with the offset, {c['worse_by'][0]:.0f}-{c['worse_by'][1]:.0f}x worse without; offset error "
            f"<= {c['max_error_s'] * 1e3:.2f} ms; z over {len(z['z'])} seeds mean {z['mean']:+.2f} std {z['std']:.2f}",
            f"time offset, UWB 50 ms lag, constant biases: position {wo * 100:.1f} -> {w * 100:.1f} cm; shifted factor "
            f"{raw['cost']['ratio']:.0f}x the native factor's linearize"]


if __name__ == "__main__":
    from _timing import section_main
    section_main(__doc__, run, summary)
