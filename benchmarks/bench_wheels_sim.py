"""The wheel graph against the rule-based baselines over many simulated runs (docs/models/wheels.md#results-simulation).

For each fault class (clean, roughness, bumps, stuck, slide) and each run i (seed i, path shape
PATHS[i % 5]: loop, figure eight, square, slalom, random; 30 s at 20 Hz), wheels.sim generates one run
and every method estimates its end pose from the same wheel stream:

  - the rules of plugins/wheels/rules.py with the description's nominal intrinsics and the default
    thresholds: odometry, gyrodometry, first_version, minimal_gyro, final_version;
  - the graph: the simulator's own config (the shipped per-step formulation of configs/wheels_passive.yaml:
    one wheels.encoder factor per wheel and step with over-runs down-weighted, wheels.gyro with scale and
    bias estimated, wheels.nonholonomic, dead reckoning from the passive wheel to start, batch LM);
  - its ablations: without the passive wheel (its encoder factor dropped, dead reckoning from the driven
    wheels) and without the gyro (wheels.gyro dropped).

What every method knows of the robot (`--intrinsics`):
  - `nominal`: the description's values (wheel radii, axle, passive radius; gyro scale 1, bias 0); the
    graph estimates all of them from the run itself;
  - `true_gyro`: the gyro's true scale and bias, held fixed (as after a turntable calibration; the wheels'
    intrinsics stay nominal); the graph, its gyro calibrated, lets the driven wheels' turn slip (below);
  - `calibration_run`: what a user does first: a separate clean 60 s figure eight of the same robot
    (`robot_seed`: the same true intrinsics, its own noise) with the overhead camera, every intrinsic
    estimated by the graph (wheels.encoder, wheels.gyro, wheels.nonholonomic, pose.absolute); the rules
    use the estimates, the graph takes them with their sigmas as its priors (calibration.yaml as overrides)
    and, its gyro now calibrated, lets the driven wheels' turn slip (`turn_slip`, seeded from the gyro; dead
    reckoning turns with the gyro).
A cheap gyro's scale cannot be told from a slip in turns that all slide (the square's), whatever the
method, unless it was calibrated beforehand.

Measures: the final position error (m) and the final heading error (deg) against the simulator's truth;
per class the median and 90th percentile of each method, how often the graph beats every rule, and
the ratio graph / best rule (median and worst run); the graph's uncertainty consistency: the share of
its final x, y and heading errors inside 1, 2 and 3 of its own marginal sigma (Gaussian: 68/95/99.7 %).
The fault settings were fixed before any run; the simulator's noise levels are the ones the graph's
config assumes (a self-consistency setting); the faults themselves are outside its model. A graph
solve that fails counts as a loss and is reported.

    python benchmarks/bench_wheels_sim.py [--quick] [--runs N] [--workers W]
                                          [--intrinsics nominal|true_gyro|calibration_run]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import _repository  # noqa: F401  (the repository root on sys.path: research/)
from _timing import table
from research.wheels_turn_slip import trust_the_gyro

PATHS = ("loop", "figure_eight", "square", "slalom", "random")
DURATION = 30.0
FAULTS = {"clean": {},
          "roughness": {"roughness": {"height": 0.0015, "spacing": 0.1}},   # 1.5 mm wires every 10 cm
          "bumps": {"bumps": {"count": 3, "height": 0.03}},                 # up to a 3 cm step
          "stuck": {"stuck": {"count": 2, "duration": 1.5}},
          "slide": {"slide": {"turn_rate": 0.5, "slip": 0.2}}}              # 20 % under-rotation above 0.5 rad/s
RULES = ("odometry", "gyrodometry", "first_version", "minimal_gyro", "final_version")
GRAPHS = ("graph", "graph without passive", "graph without gyro")


def _without_passive(config: dict) -> None:
    config["factors"] = [f for f in config["factors"] if f.get("wheels") != ["passive"]]
    config["initializers"][0]["forward"] = "driven"


def _without_gyro(config: dict) -> None:
    config["factors"] = [f for f in config["factors"] if f["type"] != "wheels.gyro"]


EDITS = {"graph": None, "graph without passive": _without_passive, "graph without gyro": _without_gyro}


def _end_errors(end: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(position error m, heading error deg) of an end pose (x, y, theta) against the true one."""
    heading = np.angle(np.exp(1j * (end[2] - truth[2])))
    return float(np.hypot(*(end[:2] - truth[:2]))), float(np.degrees(abs(heading)))


def _write_overrides(folder: str, entries: dict) -> str:
    """A calibration file (robot overrides) of `entries` ({name: (value, 1-sigma prior or None: fixed)})."""
    from pathlib import Path

    import yaml
    path = Path(folder) / "intrinsics.yaml"
    path.write_text(yaml.safe_dump({"fusionkit_calibration": 1, "robots": {"robot": {
        name: {"type": "scalar", "value": float(value), **({"fixed": True} if sigma is None else {"sigma": float(sigma)})}
        for name, (value, sigma) in entries.items()}}}))
    return str(path)


def _true_gyro() -> dict:
    from fusionkit_plugins.wheels.simulators import WheelsSimulator
    gyro = WheelsSimulator.defaults["gyro"]
    return {"gyro_scale": (gyro["scale"], None), "gyro_bias": (gyro["bias"], None)}


CALIBRATION = {"duration": 60.0, "path": "figure_eight"}  # the clean calibration run, with the camera
CALIBRATION_SEED = 100_000                                 # + the run's seed: its own noise


def calibration_run(seed: int) -> dict:
    """{intrinsic: (value, 1-sigma)} the graph estimates from a clean run of robot `seed` (the same true
    intrinsics as evaluation run `seed`, other noise) with the overhead camera."""
    from fusionkit.pipeline import estimate
    from fusionkit.simulate import simulated_config
    from fusionkit_plugins.wheels.simulators import WheelsSimulator

    def with_camera(config):
        config["factors"].append({"type": "pose.absolute", "robot": "robot", "stream": "camera",
                                  "sigma": WheelsSimulator.defaults["camera"]["sigma"]})
    with simulated_config("wheels.sim", {**CALIBRATION, "robot_seed": seed}, seed=CALIBRATION_SEED + seed,
                          edit=with_camera) as config:
        result = estimate(config)
    return {name: (float(est.values[0]), float(est.sigma[0, 0])) for name, est in result.parameters["robot"].items()}


def one_run(job: tuple[str, int, float, str, dict | None]) -> dict:
    """Every method's end-pose errors on run `seed` of fault class `fault`; the graph's end-pose z-scores;
    `intrinsics` says what every method knows of the robot (module docstring)."""
    import tempfile

    from fusionkit.api import SolverError
    from fusionkit.pipeline import estimate
    from fusionkit.simulate import simulated_config
    from fusionkit_plugins.wheels.rule_odometry import rule_poses, wheel_steps
    from fusionkit_plugins.wheels.rule_odometry import THRESHOLDS
    from fusionkit_plugins.wheels.model import drive_of

    fault, seed, duration, intrinsics, calibrated = job
    params = {"duration": duration, "path": PATHS[seed % len(PATHS)], "faults": FAULTS[fault]}
    thresholds = {k: s["default"] for k, (s, _) in THRESHOLDS.items()}
    out: dict = {"fault": fault, "seed": seed, "path": params["path"], "errors": {}, "failed": []}
    folder = tempfile.TemporaryDirectory()
    known = _true_gyro() if intrinsics == "true_gyro" else calibrated  # None with nominal intrinsics
    overrides = _write_overrides(folder.name, known) if known else None
    for name, variant in EDITS.items():
        def edit(config, variant=variant):
            if variant:
                variant(config)
            if overrides:
                config["robots"]["robot"]["overrides"] = overrides
            if intrinsics != "nominal":  # the gyro is calibrated
                trust_the_gyro(config)
        with simulated_config("wheels.sim", params, seed=seed, edit=edit) as config:
            try:
                result = estimate(config, keep_rejected=True)
            except SolverError as exc:
                out["failed"].append(f"{name}: {str(exc).splitlines()[0]}")
                out["errors"][name] = (np.inf, np.inf)
                continue
        truth = result.truth.trajectories["robot"]
        q = truth.pose_array()[-1]
        true_end = np.array([q[0], q[1], 2 * np.arctan2(q[5], q[6])])
        p = result.trajectories["robot"].pose_array()[-1]
        end = np.array([p[0], p[1], 2 * np.arctan2(p[5], p[6])])
        out["errors"][name] = _end_errors(end, true_end)
        if name == "graph":
            states = result.problem.states["robot"]
            key = states.family.keys([len(states) - 1])[0]
            sigma_xy = result.position_sigma["robot"][-1]
            sigma_theta = np.sqrt(result.solution.covariances[key][2, 2])
            err = end - true_end
            err[2] = np.angle(np.exp(1j * err[2]))
            out["z"] = (err / np.r_[sigma_xy, sigma_theta]).tolist()
        if RULES[0] not in out["errors"]:  # the rules on the same stream, from the first variant that solved
            steps = wheel_steps(result.streams["wheels"], drive_of(result.config.robots["robot"].description))
            for rule in RULES:
                out["errors"][rule] = _end_errors(rule_poses(rule, steps, thresholds, False)[-1], true_end)
    folder.cleanup()
    return out


def _cell(values: np.ndarray, digits: int) -> str:
    return f"{np.median(values):.{digits}f} / {np.percentile(values, 90):.{digits}f}"


def report(runs: list[dict]) -> tuple[str, dict]:
    """The tables: errors per class and method, the graph against the best rule, consistency."""
    methods = RULES + GRAPHS
    parts, raw = [], {}
    for measure, index, digits, unit in (("position", 0, 3, "m"), ("heading", 1, 2, "deg")):
        rows = []
        for fault in FAULTS:
            rs = [r for r in runs if r["fault"] == fault]
            errs = {m: np.array([r["errors"].get(m, (np.nan, np.nan))[index] for r in rs]) for m in methods}
            best_rule = np.min([errs[m] for m in RULES], axis=0)
            ratio = errs["graph"] / best_rule
            raw.setdefault(fault, {})[measure] = {
                "runs": len(rs), **{m: {"median": float(np.median(errs[m])), "p90": float(np.percentile(errs[m], 90))}
                                    for m in methods},
                "graph_best": int(np.sum(ratio < 1)), "ratio_median": float(np.median(ratio)),
                "ratio_worst": float(np.max(ratio))}
            rows.append([fault, len(rs)] + [_cell(errs[m], digits) for m in methods]
                        + [f"{np.sum(ratio < 1)}/{len(rs)}", f"{np.median(ratio):.2f}", f"{np.max(ratio):.2f}"])
        worst = {m: max(FAULTS, key=lambda f: raw[f][measure][m]["median"]) for m in methods}
        raw.setdefault("worst_class", {})[measure] = {
            m: {"class": worst[m], "median": raw[worst[m]][measure][m]["median"]} for m in methods}
        rows.append(["worst class", len(runs)] + [f"{raw[worst[m]][measure][m]['median']:.{digits}f} ({worst[m]})"
                                                  for m in methods] + ["", "", ""])
        parts.append(table(["class", "runs"] + list(methods) + ["graph best", "ratio med", "ratio worst"], rows,
                           f"final {measure} error ({unit}), median / 90th percentile; ratio = graph / best rule per "
                           "run; worst class: each method's largest class median"))
    rows = []
    for label, faults in (("clean", ["clean"]), ("faulty", [f for f in FAULTS if f != "clean"])):
        z = np.abs(np.array([r["z"] for r in runs if r["fault"] in faults and "z" in r]))
        if not len(z):
            continue
        shares = [[float(np.mean(z[:, axis] < k)) for k in (1, 2, 3)] for axis in range(3)]
        raw.setdefault("consistency", {})[label] = {"runs": len(z), "x": shares[0], "y": shares[1], "heading": shares[2]}
        rows.append([label, len(z)] + ["/".join(f"{100 * s:.0f}" for s in sh) for sh in shares])
    parts.append(table(["runs", "n", "x in 1/2/3 sigma %", "y %", "heading %"], rows,
                       "graph final-pose consistency (Gaussian: 68/95/100 %)"))
    failed = [f"{r['fault']} seed {r['seed']} ({r['path']}): {m}" for r in runs for m in r["failed"]]
    raw["failed"] = failed
    if failed:
        parts.append("failed solves (counted as losses):\n  " + "\n  ".join(failed))
    return "\n\n".join(parts), raw


INTRINSICS = {"nominal": "nominal intrinsics",
              "true_gyro": "gyro calibrated (true scale and bias given to every method)",
              "calibration_run": "intrinsics from a calibration run (the graph's estimates from a clean 60 s run of "
                                 "the same robot with the camera, given to every method)"}


def run(quick: bool, runs: int | None = None, workers: int = 1, intrinsics: str = "nominal") -> dict:
    runs = runs or (2 if quick else 50)
    duration = 15.0 if quick else DURATION
    with ProcessPoolExecutor(workers) as pool:
        calibrated = (list(pool.map(calibration_run, range(runs))) if intrinsics == "calibration_run"
                      else [None] * runs)  # one calibration run per robot, shared by the fault classes
        jobs = [(fault, seed, duration, intrinsics, calibrated[seed]) for fault in FAULTS for seed in range(runs)]
        results = list(pool.map(one_run, jobs))
    text, raw = report(results)
    head = (f"wheels on simulation: {runs} runs per class, {duration:.0f} s each (paths {', '.join(PATHS)} in turn), "
            f"{INTRINSICS[intrinsics]}")
    return {"text": f"{head}\n\n{text}", "raw": raw, "runs": results}


def summary(results: dict) -> list[str]:
    lines = []
    for fault in FAULTS:
        d = results["raw"][fault]["position"]
        lines.append(f"wheels sim {fault}: graph best in {d['graph_best']}/{d['runs']} runs (final position), "
                     f"graph / best rule median {d['ratio_median']:.2f}, worst {d['ratio_worst']:.2f}")
    return lines


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--runs", type=int, help="runs per fault class (default 50; --quick 2)")
    ap.add_argument("--workers", type=int, default=1, help="processes")
    ap.add_argument("--intrinsics", choices=list(INTRINSICS), default="nominal",
                    help="what every method knows of the robot's intrinsics")
    args = ap.parse_args()
    print(run(args.quick, args.runs, args.workers, args.intrinsics)["text"])
