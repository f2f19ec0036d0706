"""The OptiOdom recordings (../shared/data/diffdrive_optiodom, MIT, Sousa et al. 2022): a real
differential-drive robot, two wheel encoders at 20 Hz and OptiTrack poses, on circular runs and UMBmark
squares. No gyro and no passive wheel.

`load_session` reads a session's runs; `write_session` converts them to fusionkit's wheel-stream CSV
(`t,left,right`: cumulative wheel angles in rad) and a TUM file of the motion-capture poses, and
`graph_calibration` calibrates the radii and axle length on them with fusionkit (wheels plugin);
`path_errors` is the reference implementation's error measure (position error along the path and at
the end, dead reckoning from the true start pose); `least_squares` and `umbmark_parameters` are the
classic baselines (research/systematic.py). The published figures are in the dataset's
reference_results.csv.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from research.systematic import WheelParameters, fit_radii_and_axle, segments, umbmark

from research.external_data import external_data

NAME = "diffdrive_optiodom"
CIRCULAR, SQUARE = "circular_231220200121", "square_230620202042"
CYCLE = 0.05  # s: the odometry cycle (20 Hz)


@dataclass(frozen=True)
class Run:
    """One run: sample times t (s, N + 1), cumulative wheel angles (rad, N + 1, from 0) of the right and
    left wheel, true poses (N + 1, 3: x, y, theta unwrapped) in the start frame."""

    name: str
    t: np.ndarray
    right: np.ndarray
    left: np.ndarray
    truth: np.ndarray


@dataclass(frozen=True)
class Session:
    """A session's runs (the first half clockwise, the second counter-clockwise) and its metadata:
    nominal axle length and wheel diameters (m), wheel ticks per revolution, square side (m; 0 for the
    circular runs)."""

    name: str
    runs: list[Run]
    axle_length: float
    diameter_right: float
    diameter_left: float
    ticks_per_revolution: float
    side: float


def _metadata(path: Path) -> dict[str, list[str]]:
    with open(path, newline="") as f:
        return {row[0]: [v for v in row[1:] if v.strip()] for row in csv.reader(f) if row}


def load_session(name: str, folder: Path | None = None) -> Session:
    """Read session `name` (CIRCULAR or SQUARE) from `folder` (default: the shared data folder)."""
    folder = Path(folder or external_data(NAME)) / name
    meta = _metadata(folder / "metadata.csv")
    ticks_rev = float(meta["ngear"][0]) * float(meta["encRes"][0])
    runs = []
    for path in sorted(folder.glob("run-*.csv")):
        data = np.loadtxt(path, delimiter=",", skiprows=1)
        t, truth, ticks = data[:, 0], data[:, 1:4], data[:, 4:6]
        angles = 2.0 * np.pi * np.cumsum(ticks, axis=0) / ticks_rev
        runs.append(Run(path.stem, t, angles[:, 0], angles[:, 1], truth))
    side = float(meta["L"][0]) if meta.get("L") else 0.0
    return Session(name, runs, float(meta["Li"][0]), float(meta["Di"][0]), float(meta["Di"][1]), ticks_rev, side)


def write_session(session: Session, folder: Path, align: int = 1) -> tuple[Path, Path, list[float]]:
    """The session as one recording: `wheels.csv` (t,left,right: cumulative wheel angles, rad) and
    `mocap.tum` (the true poses, planar, z = 0). Runs follow each other one cycle apart, each run's true
    path placed at the previous run's final true pose, so the wheels stand still and the truth does not
    move between runs: every run's relative motion is kept and nothing links two runs. `align` > 1: each
    run starts at a sample index that is a multiple of `align`, after the robot stood still (one cycle apart) for
    more than `align` samples, so states every `align` samples fall on every run's first sample and on its final
    pose. Returns the two files and each run's start time (s)."""
    folder.mkdir(parents=True, exist_ok=True)
    t, left, right, poses, starts = [], [], [], [], []
    t0, angle, base = 0.0, np.zeros(2), np.zeros(3)
    for run in session.runs:
        # standing still before this run: to the next multiple of `align` samples, one state past the last run's end
        still = (-sum(map(len, t)) % align + align) if t and align > 1 else 0
        if still:
            t.append(t0 + CYCLE * np.arange(still))
            left.append(np.full(still, angle[0]))
            right.append(np.full(still, angle[1]))
            poses.append(np.tile(base, (still, 1)))
            t0 = t[-1][-1] + CYCLE
        starts.append(t0)
        c, s = np.cos(base[2] - run.truth[0, 2]), np.sin(base[2] - run.truth[0, 2])
        rel = run.truth - run.truth[0]
        poses.append(np.column_stack([base[0] + c * rel[:, 0] - s * rel[:, 1], base[1] + s * rel[:, 0] + c * rel[:, 1],
                                      base[2] + rel[:, 2]]))
        t.append(t0 + run.t - run.t[0])
        left.append(angle[0] + run.left - run.left[0])
        right.append(angle[1] + run.right - run.right[0])
        t0, angle, base = t[-1][-1] + CYCLE, np.array([left[-1][-1], right[-1][-1]]), poses[-1][-1]
    t, poses = np.concatenate(t), np.concatenate(poses)
    wheels, mocap = folder / "wheels.csv", folder / "mocap.tum"
    np.savetxt(wheels, np.column_stack([t, np.concatenate(left), np.concatenate(right)]), delimiter=",",
               header="t,left,right", comments="", fmt="%.10g")
    half = 0.5 * poses[:, 2]
    np.savetxt(mocap, np.column_stack([t, poses[:, :2], np.zeros((len(t), 3)), np.sin(half), np.cos(half)]),
               fmt="%.10g")
    return wheels, mocap, starts


def write_recordings(session: Session, folder: Path) -> tuple[list[Path], list[Path]]:
    """Each run as its own recording: `wheels-NN.csv` (t,left,right: cumulative wheel angles, rad, from 0) and
    `mocap-NN.tum` (its true poses, planar, z = 0), the runs' stamps shifted to follow each other one second
    apart (several files of one source: fusionkit links nothing across two recordings)."""
    folder.mkdir(parents=True, exist_ok=True)
    wheels, mocap, t0 = [], [], 0.0
    for i, run in enumerate(session.runs):
        t = t0 + run.t - run.t[0]
        w, m = folder / f"wheels-{i:02d}.csv", folder / f"mocap-{i:02d}.tum"
        np.savetxt(w, np.column_stack([t, run.left - run.left[0], run.right - run.right[0]]), delimiter=",",
                   header="t,left,right", comments="", fmt="%.10g")
        half = 0.5 * run.truth[:, 2]
        np.savetxt(m, np.column_stack([t, run.truth[:, :2], np.zeros((len(t), 3)), np.sin(half), np.cos(half)]),
                   fmt="%.10g")
        wheels.append(w)
        mocap.append(m)
        t0 = t[-1] + 1.0
    return wheels, mocap


def dead_reckoning(run: Run, axle_length: float, radius_right: float, radius_left: float) -> np.ndarray:
    """(N + 1, 3) poses from the true start pose, as the reference implementation integrates them: per
    cycle ds = (dsR + dsL) / 2, dth = (dsR - dsL) / L, x += ds cos(th + dth / 2), likewise y, th += dth."""
    ds_r, ds_l = radius_right * np.diff(run.right), radius_left * np.diff(run.left)
    ds, dth = 0.5 * (ds_r + ds_l), (ds_r - ds_l) / axle_length
    th = run.truth[0, 2] + np.concatenate([[0.0], np.cumsum(dth)])
    x = run.truth[0, 0] + np.concatenate([[0.0], np.cumsum(ds * np.cos(th[:-1] + 0.5 * dth))])
    y = run.truth[0, 1] + np.concatenate([[0.0], np.cumsum(ds * np.sin(th[:-1] + 0.5 * dth))])
    return np.column_stack([x, y, th])


@dataclass(frozen=True)
class PathErrors:
    """Over a set of runs: the largest position error along any path (m; the reference's `max e_d`), the
    largest final position error (m) and final heading error (deg), and the per-run final position errors."""

    max_along: float
    max_final: float
    max_final_heading_deg: float
    final: np.ndarray


def path_errors(runs: list[Run], estimates: list[np.ndarray]) -> PathErrors:
    """The reference implementation's measures (computeEvaluationMeasures.m) of dead-reckoned `estimates`
    (one (N + 1, 3) array per run) against the runs' truth."""
    along, final, heading = [], [], []
    for run, est in zip(runs, estimates):
        err = run.truth - est
        dist = np.hypot(err[:, 0], err[:, 1])
        along.append(dist.max())
        final.append(dist[-1])
        heading.append(abs(np.degrees(np.angle(np.exp(1j * err[-1, 2])))))
    return PathErrors(max(along), max(final), max(heading), np.array(final))


def final_errors(runs: list[Run], estimates: list[np.ndarray]) -> np.ndarray:
    """(n, 2) final position errors, truth minus dead reckoning (m): UMBmark's input."""
    return np.array([run.truth[-1, :2] - est[-1, :2] for run, est in zip(runs, estimates)])


def nominal(session: Session) -> WheelParameters:
    return WheelParameters(session.diameter_right / 2, session.diameter_left / 2, session.axle_length)


def evaluate(session: Session, params: WheelParameters) -> PathErrors:
    """The reference measures of dead reckoning with `params` over all runs of `session`."""
    return path_errors(session.runs, [dead_reckoning(r, params.axle_length, params.radius_right, params.radius_left)
                                      for r in session.runs])


def held_out(session: Session, fit) -> tuple[float, float]:
    """Leave one run out: each run dead-reckoned with `fit` (Session -> WheelParameters) of the session's other runs;
    the largest error along any held-out path and the largest final error (m)."""
    from dataclasses import replace
    errors = [evaluate(replace(session, runs=[run]), fit(replace(session, runs=session.runs[:i] + session.runs[i + 1:])))
              for i, run in enumerate(session.runs)]
    return max(e.max_along for e in errors), max(e.max_final for e in errors)


def least_squares(session: Session, length: int | None = None) -> WheelParameters:
    """Two-stage least squares (research/systematic.py) on the session's runs, each run one segment
    (Antonelli et al.'s experiments), or cut into segments of `length` cycles."""
    segs = []
    for r in session.runs:
        n = len(r.t) - 1
        segs += segments(np.diff(r.right), np.diff(r.left), r.truth, min(length or n, n))
    return fit_radii_and_axle(segs)


def umbmark_parameters(session: Session) -> WheelParameters:
    """UMBmark on a square session, from the return errors of dead reckoning with the nominal parameters;
    a run is clockwise when its true heading decreases over the run."""
    base = nominal(session)
    ends = final_errors(session.runs, [dead_reckoning(r, base.axle_length, base.radius_right, base.radius_left)
                                       for r in session.runs])
    cw = np.array([r.truth[-1, 2] < r.truth[0, 2] for r in session.runs])
    u = umbmark(ends[cw], ends[~cw], session.side, session.axle_length, session.diameter_right,
                session.diameter_left)
    return WheelParameters(u.diameter_right / 2, u.diameter_left / 2, u.axle_length)


CHECKPOINT_SPACING = 0.5  # m of travel between checkpoints (the reference implementation's `sampleDist`)


def checkpoint_fit(session: Session, spacing: float = CHECKPOINT_SPACING) -> WheelParameters:
    """OptiOdom's objective (Sousa et al. 2022), reimplemented: the radii and axle length minimizing the sum
    of squared position errors of dead reckoning from each run's true start, at checkpoints every `spacing`
    m of travel (placed once with the nominal parameters). The reference minimizes it by resilient
    backpropagation; here scipy's least_squares (trust region) finds the same minimum."""
    from scipy.optimize import least_squares as solve

    base = nominal(session)
    checks = []
    for r in session.runs:
        travel = np.concatenate([[0.0], np.cumsum(np.abs(0.5 * (base.radius_right * np.diff(r.right) +
                                                                 base.radius_left * np.diff(r.left))))])
        marks = np.searchsorted(travel, np.arange(spacing, travel[-1], spacing))
        checks.append(np.unique(np.append(marks[marks < len(travel)], len(travel) - 1)))

    def residuals(x):
        out = [(r.truth[c, :2] - dead_reckoning(r, x[2], x[0], x[1])[c, :2]).ravel()
               for r, c in zip(session.runs, checks)]
        return np.concatenate(out)
    fit = solve(residuals, [base.radius_right, base.radius_left, base.axle_length], x_scale=[1e-4, 1e-4, 1e-3])
    return WheelParameters(*map(float, fit.x))


def published(folder: Path | None = None) -> list[dict]:
    """reference_results.csv: one dict per (method, experiment) with the published parameters and measures."""
    with open(Path(folder or external_data(NAME)) / "reference_results.csv", newline="") as f:
        return list(csv.DictReader(f))


# The graph calibration's settings. INCREMENTS, fixed before looking at the results: motion capture
# (OptiTrack: about 1 mm and 0.01 rad per pose), wheel travel noise 1 mm/sqrt(s) (ten times the encoder
# quantization of 0.17 mm/sqrt(s) at 20 Hz: slip and floor unevenness), no sideways slip beyond that, the wheels
# preintegrated between states 1 s apart. LONG_HORIZON, the documented systematic calibration: the wheels
# dead-reckoned from every checkpoint (0.5 m of travel apart: the reference implementation's spacing) to the end of
# its run (wheels.long_horizon, 1 cm per checkpoint), the motion capture's noise scale estimated from the data.
INCREMENTS = {"objective": "increments", "state_every": 20, "wheel_sigma": 0.001,
              "mocap": {"rotation": 0.01, "translation": 0.001}}
LONG_HORIZON = {"objective": "long_horizon", "state_every": 20, "long_sigma": 0.01, "spacing": 0.5,
                "mocap": {"rotation": 0.01, "translation": 0.001}, "mocap_scale": "estimate"}
GRAPH = LONG_HORIZON


def graph_config(wheels: list[Path], mocap: list[Path], settings: dict = GRAPH) -> dict:
    """A fusionkit config calibrating optiodom_robot's radii and axle length from recordings (`wheels`, `mocap`:
    one file per run): states every `state_every` cycles, the motion-capture poses at them, and the wheels as
    `objective` says: "increments" (wheels.preintegrated between consecutive states), "long_horizon"
    (wheels.long_horizon: `long_sigma` m per checkpoint, `spacing` m, `horizon` s and `anchors` if given) or both
    ("increments+long_horizon"). `mocap_scale` "estimate": the motion capture's noise scale estimated from the data
    (`noise_scale: estimate`); `noise_scales`: every entry's."""
    every = "estimate" if settings.get("noise_scales") else None
    scale = {"noise_scale": every} if every else {}
    mocap_scale = settings.get("mocap_scale") or every
    factors = [{"type": "pose.absolute", "robot": "robot", "stream": "mocap", "sigma": settings["mocap"],
                **({"noise_scale": mocap_scale} if mocap_scale else {})}]
    if "increments" in settings["objective"]:
        factors.append({"type": "wheels.preintegrated", "robot": "robot", "stream": "wheels",
                        "sigma": settings["wheel_sigma"], **scale})
    if "long_horizon" in settings["objective"]:
        factors.append({"type": "wheels.long_horizon", "robot": "robot", "stream": "wheels",
                        "sigma": settings["long_sigma"], "spacing": settings["spacing"],
                        **{k: settings[k] for k in ("horizon", "anchors") if settings.get(k)}, **scale})
    return {"name": "optiodom_calibration",
            "robots": {"robot": {"description": "optiodom_robot",
                                 "states": {"stream": "wheels", "every": settings["state_every"], "type": "pose2"}}},
            "sources": [{"type": "csv", "name": "wheels", "path": [str(f) for f in wheels]},
                        {"type": "tum", "name": "mocap", "path": [str(f) for f in mocap]}],
            "factors": factors,
            "initializers": [{"type": "pose.interpolate", "robot": "robot", "stream": "mocap"}],
            "solver": {"type": "batch", "method": "lm"}, "output": {"plots": False}}


def graph_calibration(session: Session, settings: dict = GRAPH):
    """(WheelParameters, their 1-sigma (r_R, r_L, A), the fusionkit RunResult) of the graph calibration
    on all runs of `session`, each run its own recording."""
    import tempfile

    import yaml

    from fusionkit import run as fusionkit_run
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        wheels, mocap = write_recordings(session, folder)
        path = folder / "config.yaml"
        path.write_text(yaml.safe_dump(graph_config(wheels, mocap, settings), sort_keys=False))
        result = fusionkit_run(path)
    est = result.parameters["robot"]
    names = ("wheel_radius_right", "wheel_radius_left", "axle_length")
    values = [float(est[n].values[0]) for n in names]
    sigma = [float(est[n].sigma[0][0]) if est[n].sigma is not None else float("nan") for n in names]
    return WheelParameters(*values), sigma, result
