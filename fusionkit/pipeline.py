"""The run pipeline: config -> sources -> graph -> initial values -> solve -> estimates -> evaluation."""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import Any

import gtsam
import numpy as np

from .components import SourceOutput
from .config.loader import RunConfig
from .config.yamlio import load_yaml
from .data.files import read_csv_stream, read_tum
from .data.stream import Stream, pose_array_from, pose_array_of, pose_stream
from .data.stamp_check import check_repeated_stamps
from .errors import DataError, SolverError
from .eval.parameters import aligned_point_errors, parameter_errors
from .eval.states import StateSeries, state_errors, state_series
from .eval.consistency import sigma_check
from .eval.notes import evaluation_notes
from .eval.timebase import check_truth_clock
from .data.association import nearest
from .data.recordings import gaps
from .eval.trajectory import (MATCH_TOLERANCE, fit_alignment, matched_positions, position_consistency,
                              trajectory_errors)
from .graph.builder import BuildContext, Problem, record_times, state_times
from .graph.context import for_plugins
from .graph.keys import STATE, TIME_VARYING, Family
from .graph.variables import POSE3
from .graph.vectorized import ValueReader
from .plugins import registry
from .progress import Progress
from .threads import one_blas_thread
from .descriptions.calibration_file import calibration_entries
from .solve import noise_scales, solve
from .solve.identifiability import Identifiability, identifiability
from .solve.result import SolveResult


@dataclass
class Truth:
    trajectories: dict[str, Stream] = field(default_factory=dict)
    calibration: dict[str, dict[str, Any]] = field(default_factory=dict)
    states: dict[str, dict[str, Stream]] = field(default_factory=dict)  # robot -> family -> true values

    def families(self, config: RunConfig) -> set[tuple[str, str]]:
        """(robot, family) of the per-state families with truth: those of `states`, and the state family
        of each robot with a true trajectory."""
        clocked = {r: setup.states["family"] for r, setup in config.robots.items() if setup.states}
        return ({(r, f) for r, fams in self.states.items() for f in fams}
                | {(r, clocked[r]) for r in self.trajectories if r in clocked})


@dataclass
class ParameterEstimate:
    """Estimated value(s) of one static or time-varying unknown with 1-sigma per tangent axis."""

    robot: str
    name: str
    family: Family
    values: list[Any]
    sigma: np.ndarray | None  # (count, dim)
    series_t: np.ndarray | None = None  # time-varying: state times of each value


@dataclass
class RunResult:
    config: RunConfig
    problem: Problem
    solution: SolveResult
    trajectories: dict[str, Stream]
    position_sigma: dict[str, np.ndarray]
    parameters: dict[str, dict[str, ParameterEstimate]]
    truth: Truth
    evaluation: dict[str, Any]
    timings: dict[str, float]
    streams: dict[str, Stream] = field(default_factory=dict)  # the data the graph was built from
    states: dict[tuple[str, str], StateSeries] = field(default_factory=dict)  # (robot, family) -> series
    identifiability: Identifiability | None = None  # what the data determine of the parameters

    @property
    def notes(self) -> list[str]:
        """What the summary and report.json `notes` list: data read with corrections (the data streams'
        notes reach problem.notes in build_problem), data not used, and the evaluation's warnings."""
        notes = [*self.problem.notes, *(n for s in self.truth.trajectories.values() for n in s.notes),
                 *evaluation_notes(self.evaluation)]
        if self.config.output["state_covariances"] and not self.config.solver["marginals"]:
            notes.append("output.state_covariances: no covariances written, solver.marginals is false")
        return notes


def _stage(progress: Progress | None, text: str) -> None:
    if progress is not None:
        progress.stage(text)


def read_sources(config: RunConfig) -> tuple[dict[str, Stream], Truth]:
    """Read every source; gather truth from simulators and from `truth:` files."""
    reg = registry()
    streams: dict[str, Stream] = {}
    truth = Truth()
    for spec in config.sources:
        out: SourceOutput = reg.get("sources", spec.type)().read(spec, config.base_dir)
        streams.update(out.streams)
        truth.trajectories.update(out.truth_trajectories or {})
        truth.calibration.update(out.truth_calibration or {})
        for robot, families in (out.truth_states or {}).items():
            truth.states.setdefault(robot, {}).update(families)
    for name, cols in config.stream_columns.items():
        if name not in streams:
            raise DataError(f"sources[{config.stream_source[name]}] did not produce stream {name!r}")
    check_repeated_stamps(config, streams)
    for robot, file in (config.truth.get("trajectories") or {}).items():
        truth.trajectories[robot] = read_tum(config.resolve(file), f"truth:{robot}")
    if "calibration" in config.truth:
        truth.calibration.update(calibration_entries(load_yaml(config.resolve(config.truth["calibration"]))))
    for robot, families in (config.truth.get("states") or {}).items():
        for family, file in families.items():
            truth.states.setdefault(robot, {})[family] = read_csv_stream(config.resolve(file), f"truth:{robot}.{family}")
    for robot, ref in truth.trajectories.items():
        states = robot in config.robots and config.robots[robot].states
        if states:
            clock = f"stream {states['stream']!r}" if "stream" in states else f"{states['rate']} Hz"
            check_truth_clock(ref, robot, state_times(states, streams), clock)
    return streams, truth


def build_problem(config: RunConfig, streams: dict[str, Stream], progress: Progress | None = None) -> Problem:
    """Every factor entry builds its factors, then initializers run in config order; then the factors of entries
    with a time offset are shifted to their samples' times (at the offset's initial value)."""
    reg = registry()
    ctx = BuildContext(config, streams)
    ctx.notes.extend(note for stream in streams.values() for note in stream.notes)
    view = for_plugins(ctx)  # what the plugins see: the BuildContext protocol
    for spec in config.factors:
        _stage(progress, f"building {spec.label}")
        reg.get("factor_types", spec.type)().build(view, spec)
    for spec in config.initializers:
        _stage(progress, f"initializing: {spec.label}")
        ctx.current_initializer = spec.label
        reg.get("initializers", spec.type)().initialize(view, spec)
    ctx.measurement_states.finish()
    ctx.require_values()
    separate_recordings(ctx, streams)
    for spec in config.factors:
        _stage(progress, f"diagnosing {spec.label}")
        reg.get("factor_types", spec.type)().diagnose(view, spec)
    return ctx.problem()


def separate_recordings(ctx: BuildContext, streams: dict[str, Stream]) -> None:
    """Leave out the factors that link states across the gap between two recordings (data/recordings.py)."""
    between = gaps(streams)
    if not between:
        return
    crossing = []
    for r in ctx.records:
        times = record_times(r, ctx.key_time)
        crossing.append(bool(times) and any(min(times) <= end and max(times) >= start for end, start in between))
    if any(crossing):
        ctx.records[:] = [r for r, c in zip(ctx.records, crossing) if not c]
        where = ", ".join(f"{start:g}" for start in sorted({round(start, 6) for _, start in between}))
        ctx.notes.append(f"{sum(crossing)} factor(s) that would link the states of two recordings (starting at t = "
                         f"{where} s) were left out: the recordings share the calibration, not their states")


def _marginal_keys(problem: Problem, state_families: set[tuple[str, str]] | bool) -> set[int]:
    """Every parameter, and the per-state variables of `state_families` ((robot, family) pairs, or all
    of them with True): those with truth to check their sigmas against, or all when asked."""
    keys = set()
    for fam, group in problem.keys.group(problem.initial.keys()):
        if fam.kind != STATE or state_families is True or (fam.robot, fam.name) in state_families:
            keys.update(k for k in group if k not in problem.fixed_keys)  # fixed: held, no uncertainty
    return keys


def _trajectories(problem: Problem, values: gtsam.Values, cov: dict[int, np.ndarray]):
    """Trajectories (TUM-ready pose streams) of the robots whose states are poses, with the position
    1-sigma along the world axes where covariances exist; other state types are reported as series."""
    trajs, sigmas = {}, {}
    present = set(values.keys())
    for robot, states in problem.states.items():
        vt = states.family.vartype
        if vt.name not in ("pose3", "pose2"):
            continue
        # only states some factor declared a pose for (a robot may have parameters only, or
        # states outside the span of its pose streams)
        keys = states.family.keys(range(len(states)))
        ks = [k for k, key in enumerate(keys) if key in present]
        if not ks:
            continue
        keys = [keys[k] for k in ks]
        planar = vt.name == "pose2"
        if planar:  # lifted to the plane z = 0
            read = [values.atPose2(k) for k in keys]
            arr = pose_array_from([gtsam.Pose3(gtsam.Rot3.Yaw(p.theta()), np.array([p.x(), p.y(), 0.0])) for p in read])
        else:  # every pose at once, through the type's table read
            matrices = ValueReader(values).read(POSE3, np.asarray(keys, dtype=np.int64))
            arr = pose_array_of(matrices[:, :3, :3], matrices[:, :3, 3])
        trajs[robot] = pose_stream(robot, states.t[ks], arr, f"estimate:{robot}")
        if all(k in cov for k in keys):
            rot = [gtsam.Rot2(p.theta()).matrix() for p in read] if planar else matrices[:, :3, :3]
            sigmas[robot] = np.asarray([np.sqrt(np.diag(world_position_covariance(r, cov[k], planar)))
                                        for r, k in zip(rot, keys)])
    return trajs, sigmas


def world_position_covariance(rotation: np.ndarray, tangent: np.ndarray, planar: bool) -> np.ndarray:
    """A pose's position covariance in world axes (m^2; 2x2 planar, else 3x3) from its tangent-space covariance
    (translation in body axes: Pose2 [x, y, theta], Pose3 [rotation, translation]) and its rotation matrix."""
    idx = [0, 1] if planar else [3, 4, 5]
    r = np.asarray(rotation)[:2, :2] if planar else rotation
    return r @ tangent[np.ix_(idx, idx)] @ r.T


def _parameters(problem: Problem, values: gtsam.Values, cov: dict[int, np.ndarray]):
    out: dict[str, dict[str, ParameterEstimate]] = {}
    for fam, keys in problem.keys.group(problem.initial.keys()):
        if fam.kind == STATE:
            continue
        vals = [fam.vartype.read(values, k) for k in keys]
        sig = np.array([np.sqrt(np.diag(cov[k])) for k in keys]) if all(k in cov for k in keys) else None
        series_t = None
        if fam.kind == TIME_VARYING:
            series_t = problem.states[fam.robot].t[[problem.keys.decode(k)[1] for k in keys]]
        out.setdefault(fam.robot, {})[fam.name] = ParameterEstimate(fam.robot, fam.name, fam, vals, sig, series_t)
    return out


def evaluate(config: RunConfig, trajectories, position_sigma, parameters, truth: Truth) -> dict:
    """Per robot with truth: states, matched_poses, ATE/RPE and, with sigmas, the shares inside 1/2/3 sigma
    and their verdict; parameter errors against the truth calibration."""
    ev: dict[str, Any] = {}
    align = config.truth["align"]
    for robot, ref in truth.trajectories.items():
        if robot not in trajectories:
            continue
        m = matched_positions(trajectories[robot], ref, position_sigma.get(robot))
        err: dict[str, Any] = {"states": len(trajectories[robot]), "matched_poses": len(m.t)}
        if len(m.t):
            err.update(trajectory_errors(trajectories[robot], ref, align))
        if len(m.t) and m.sigma is not None:
            err["consistency_percent"] = position_consistency(m.estimate, m.truth, m.sigma)
            err["consistency_check"] = sigma_check(m.error / m.sigma, err["consistency_percent"])
        ev.setdefault("trajectories", {})[robot] = err
    if truth.calibration:
        ev["parameters"] = parameter_errors(parameters, truth.calibration)
        fixed = [r for r, setup in config.robots.items() if not setup.states]
        if align != "none" and fixed:
            alignment = joint_alignment(trajectories, truth, align)
            if alignment is not None:
                for robot, entries in aligned_point_errors(parameters, truth.calibration, fixed, alignment).items():
                    for name, item in entries.items():
                        ev["parameters"].setdefault(robot, {}).setdefault(name, {}).update(item)
    return ev


def joint_alignment(trajectories, truth: Truth, align: str):
    """One alignment of every robot's matched estimated positions onto the true ones (the world frame is
    shared), of the kind `align`; None without three matched positions."""
    pairs = [matched_positions(trajectories[r], ref) for r, ref in truth.trajectories.items() if r in trajectories]
    est = np.concatenate([m.estimate for m in pairs]) if pairs else np.zeros((0, 3))
    if len(est) < 3:
        return None
    return fit_alignment(est, np.concatenate([m.truth for m in pairs]), align)


def residuals_by_entry(problem: Problem, final: gtsam.Values) -> dict[str, dict]:
    """RMS of the unwhitened residual (the factor's own units) of each entry, at the initial
    values and at the solution: e.g. the cable-length residual before and after refinement."""
    rows: dict[str, list[int]] = {}
    for i, r in enumerate(problem.records):
        rows.setdefault(r.label, []).append(i)
    residuals = [problem.evaluator().record_residuals(v) for v in (problem.initial, final)]
    out = {}
    for label, indices in rows.items():
        rms = [float(np.sqrt(np.mean(np.concatenate([at[i] for i in indices]) ** 2))) for at in residuals]
        out[label] = {"factors": len(indices), "initial_rms": rms[0], "final_rms": rms[1]}
    return out


def _solve_refined(config: RunConfig, streams: dict[str, Stream], problem: Problem, marginal_keys: set[int],
                   progress) -> tuple[Problem, SolveResult]:
    """solver.refine: solve, then solve again from that estimate with the refined factor entries
    (graduated: e.g. a model tolerance that lets the first solve travel far is tightened for the
    second). Iterations and seconds count both solves; costs, checks and covariances are the
    second's; the returned problem keeps the initializers' values as its initial ones."""
    settings = {k: v for k, v in config.solver.items() if k != "refine"}
    first = solve(problem, {**settings, "marginals": False}, set(), progress)  # judged by the second solve
    refined = build_problem(dataclasses.replace(config, factors=config.refined_factors), streams, progress)
    second = solve(dataclasses.replace(refined, initial=first.values), settings, marginal_keys, progress)
    second.iterations += first.iterations
    second.seconds += first.seconds
    return refined, second


def _solve_noise_scales(config: RunConfig, streams: dict[str, Stream], problem: Problem, marginal_keys: set[int],
                        progress) -> tuple[Problem, SolveResult]:
    """`noise_scale: estimate`: solve, estimate those entries' noise scales from the residuals and their
    redundancy (solve/noise_scales.py), rebuild the graph with them and solve again from the estimate, until
    the scales settle; a last solve from there gives the covariances. Iterations and seconds count every
    solve; the returned problem keeps the initializers' values as its initial ones (as _solve_refined's)."""
    iteration = noise_scales.ScaleIteration([spec.label for spec in config.factors
                                             if spec.get("noise_scale") == "estimate"])
    quiet = {**config.solver, "marginals": False}
    iterations = seconds = 0
    start = problem.initial
    for rounds in range(1, noise_scales.MAX_ROUNDS + 1):
        _stage(progress, f"noise scales, round {rounds}: " + ", ".join(f"{k} {v:.4g}" for k, v in iteration.scales.items()))
        problem.evaluator()  # built once, shared by the copy solved from `start`
        solution = solve(dataclasses.replace(problem, initial=start), quiet, set(), progress)
        iterations, seconds = iterations + solution.iterations, seconds + solution.seconds
        start = solution.values
        fits = noise_scales.entry_fits(problem, start, set(iteration.scales), config.solver)
        iteration.update(fits)
        if iteration.done:  # the scales of this solve fit the data
            break
        factors = [dataclasses.replace(spec, data={**spec.data, "noise_scale": iteration.scales[spec.label]})
                   if spec.label in iteration.scales else spec for spec in config.factors]
        problem = build_problem(dataclasses.replace(config, factors=factors), streams, progress)
    else:
        problem.notes.append(f"noise scales: chi-square / redundancy still off 1 after {noise_scales.MAX_ROUNDS} "
                             "rounds (by more than a tenth of its standard deviation); the last scales are used")
    final = solve(dataclasses.replace(problem, initial=start), config.solver, marginal_keys, progress)
    final.iterations += iterations
    final.seconds += seconds
    if not iteration.done:
        fits = noise_scales.entry_fits(problem, final.values, set(iteration.scales), config.solver)
    final.noise_scales = noise_scales.scale_report(iteration.scales, fits, rounds)
    return problem, final


def estimate(config: RunConfig, progress: Progress | None = None, keep_rejected: bool = False) -> RunResult:
    """Run everything short of writing files (with one BLAS thread, see fusionkit.threads);
    `progress` hears of each stage and solver iteration. A solution the chi-square gate refuses
    raises SolverError, or with `keep_rejected` is returned complete with `solution.rejection` set
    (to write it out for inspection)."""
    with one_blas_thread():
        result = _estimate(config, progress)
    if result.solution.rejection and not keep_rejected:
        raise SolverError(result.solution.rejection)
    return result


def _estimate(config: RunConfig, progress: Progress | None) -> RunResult:
    timings = {}
    tic = time.perf_counter()
    _stage(progress, "reading the data")
    streams, truth = read_sources(config)
    timings["read_s"] = time.perf_counter() - tic
    tic = time.perf_counter()
    problem = build_problem(config, streams, progress)
    timings["build_s"] = time.perf_counter() - tic
    tic = time.perf_counter()
    marginal_keys = _marginal_keys(problem, config.output["state_covariances"] or truth.families(config))
    if config.refined_factors:
        problem, solution = _solve_refined(config, streams, problem, marginal_keys, progress)
    elif any(spec.get("noise_scale") == "estimate" for spec in config.factors):
        problem, solution = _solve_noise_scales(config, streams, problem, marginal_keys, progress)
    else:
        solution = solve(problem, config.solver, marginal_keys, progress)
    timings["solve_and_marginals_s"] = time.perf_counter() - tic
    if problem.measurement_states is not None:  # time offsets whose estimate left their samples' windows
        problem.notes.extend(problem.measurement_states.beyond_windows(solution.values))
    reg = registry()
    baselines: dict[str, dict[str, Stream]] = {}
    if solution.rejection:  # a model error diagnosed from an estimate that does not fit would mislead
        problem.notes.append("the factor types' checks of the estimate (e.g. range biases that grow with distance) "
                             "were not made: the solve was rejected, its estimate is no basis for them")
    problem.context.record_marginals(solution.covariances)  # ctx.sigma in the reviews
    for spec in config.factors:  # what each entry's factor type says of the estimate, and its sensor alone
        factor_type = reg.get("factor_types", spec.type)()
        if not solution.rejection:
            problem.notes.extend(factor_type.review(for_plugins(problem.context), spec, solution.values))
        if spec.get("robot") in truth.trajectories:
            for name, stream in factor_type.baseline(for_plugins(problem.context), spec, solution.values).items():
                baselines.setdefault(spec["robot"], {})[name] = stream
    timings["solve_s"] = solution.seconds
    report = _identifiability(config, problem, solution)
    _stage(progress, "evaluating")
    trajectories, position_sigma = _trajectories(problem, solution.values, solution.covariances)
    parameters = _parameters(problem, solution.values, solution.covariances)
    states = state_series(problem, solution.values, solution.covariances)
    evaluation = evaluate(config, trajectories, position_sigma, parameters, truth)
    evaluation.update(_state_evaluation(states, truth))
    evaluation["residuals_by_entry"] = residuals_by_entry(problem, solution.values)
    if baselines:
        evaluation["baselines"] = baseline_errors(baselines, trajectories, truth)
    return RunResult(config, problem, solution, trajectories, position_sigma, parameters, truth, evaluation,
                     timings, streams, states, report)


def _identifiability(config: RunConfig, problem: Problem, solution) -> Identifiability | None:
    """The identifiability report of a solve with covariances (solve/identifiability.py); the fixed-lag
    smoother's estimate is not the whole graph's, so it has none."""
    if not config.solver["marginals"] or config.solver["type"] == "fixed_lag":
        return None
    report = identifiability_report(config, problem, solution.values, solution.factorization == "qr",
                                    solution.linear)
    if report is not None and solution.sigmas_scaled:
        report.scaled(solution.sigma0)
    return report


def identifiability_report(config: RunConfig, problem: Problem, values: gtsam.Values, qr: bool = False,
                           linear: gtsam.GaussianFactorGraph | None = None) -> Identifiability | None:
    """solve/identifiability.py's report at `values` (`run`: the estimate; `validate`: the initial values), with
    the factor types' hints and the descriptions' units and component names."""
    reg = registry()
    factor_types = [(reg.get("factor_types", spec.type)(), spec) for spec in config.factors]

    def hints(parameters: list[str]) -> list[str]:
        found = (factor_type.separation_hint(spec, parameters) for factor_type, spec in factor_types)
        return list(dict.fromkeys(h for h in found if h))

    def parameter(robot: str, name: str):
        return config.robots[robot].description.parameters.get(name) if robot in config.robots else None
    try:
        return identifiability(problem, values, qr, hints, parameter, linear)
    except (RuntimeError, np.linalg.LinAlgError) as exc:  # a system GTSAM cannot eliminate even by QR there
        problem.notes.append(f"identifiability report not computed: {str(exc).splitlines()[0][:200]}")
        return None


def baseline_errors(baselines: dict[str, dict[str, Stream]], trajectories: dict[str, Stream], truth: Truth) -> dict:
    """robot -> baseline name -> position RMSE (m) against the truth at the baseline's times (nearest true
    pose within 0.01 s, no alignment), beside the fused estimate's at the same times."""
    def rms(error: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(error ** 2, axis=1))))

    out: dict[str, dict] = {}
    for robot, named in baselines.items():
        fused = trajectories.get(robot)
        for name, stream in named.items():
            m = matched_positions(stream, truth.trajectories[robot])
            if not len(m.t):
                continue
            entry = {"position_rmse_m": rms(m.error), "matched": int(len(m.t))}
            if fused is not None:  # the fused states at the baseline's matched times
                f = nearest(fused.t, m.t, MATCH_TOLERANCE)
                if len(f.row) == len(m.t):
                    entry["fused_position_rmse_m"] = rms(fused.pose_array()[f.state, :3] - m.truth[f.row])
            out.setdefault(robot, {})[name] = entry
    return out


def _state_evaluation(states: dict[tuple[str, str], StateSeries], truth: Truth) -> dict:
    """{"states": robot -> family -> errors} for each family with a truth series."""
    out: dict[str, dict] = {}
    for robot, families in truth.states.items():
        for family, ref in families.items():
            series = states.get((robot, family))
            if series is None:
                raise DataError(f"{ref.origin or ref.name}: truth for {robot}.{family}, but robot {robot!r} has no "
                                f"state family {family!r} (it has: "
                                f"{', '.join(f for r, f in states if r == robot) or 'none'})")
            try:
                out.setdefault(robot, {})[family] = state_errors(series, ref)
            except ValueError as exc:
                raise DataError(f"{ref.origin or ref.name}: {exc}; expected columns t, "
                                f"{', '.join(series.vartype.names()[0])}") from None
    return {"states": out} if out else {}

