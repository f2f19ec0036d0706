"""`fusionkit crossval`'s work: build the config's graph once, cut it into folds, run each fold (train, hold
the calibration, predict the held-out measurements) here or on the sweep's backends, and pool the scores."""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..components import ResidualPart
from ..config.loader import RunConfig, load_config
from ..errors import ConfigError, FusionkitError
from ..graph.builder import Problem
from ..graph.context import for_plugins
from ..parallel import run_tasks
from ..pipeline import build_problem, read_sources
from ..plugins import registry
from ..threads import one_blas_thread
from .folds import Plan, Units, folds, partition, units
from .predict import Roles, predict, train
from .scores import fold_scores, pooled

UNSUPPORTED = "each fold is one solve with the sigmas as stated"


@dataclass
class Built:
    """What every fold shares: the config, its graph, the units, the entries' roles and residual parts."""

    config: RunConfig
    problem: Problem
    units: Units
    roles: Roles
    parts: dict[str, list[ResidualPart]]


_BUILT: dict[tuple, Built] = {}  # the last graph built in this process: forked workers inherit the parent's


def built(config_path: str, overrides: tuple[str, ...], plan: Plan, reference: tuple[str, ...]) -> Built:
    key = (config_path, overrides, plan, reference)
    if key not in _BUILT:
        _BUILT.clear()  # one at a time: a process that cross-validates many configs keeps none of the others
        _BUILT[key] = _build(load_config(config_path, list(overrides)), plan, reference)
    return _BUILT[key]


def _build(config: RunConfig, plan: Plan, reference: tuple[str, ...]) -> Built:
    _check_config(config, reference)
    reg = registry()
    entries = [(reg.get("factor_types", spec.type)(), spec) for spec in config.factors]
    roles = Roles({spec.label: tuple(spec[f] for f in ft.stream_fields if spec.get(f)) for ft, spec in entries},
                  set(reference))
    if not any(roles.predicted(spec.label) for spec in config.factors):  # before reading any data
        raise ConfigError(f"--reference {', '.join(reference)}: nothing to predict; every entry that reads a stream "
                          "reads a reference (leave out the streams to predict)")
    streams, _ = read_sources(config)
    problem = build_problem(config, streams)
    parts = {spec.label: ft.residual_parts(for_plugins(problem.context), spec) for ft, spec in entries}
    return Built(config, problem, units(problem, plan), roles, parts)


def _check_config(config: RunConfig, reference: tuple[str, ...]) -> None:
    """One line for what crossval cannot do with this config, before any work."""
    if config.refined_factors:
        raise ConfigError(f"{config.name}: solver.refine is not supported by crossval ({UNSUPPORTED}); remove it "
                          "with --set, or cross-validate the refined entries' settings directly")
    scaled = [spec.label for spec in config.factors if spec.get("noise_scale") == "estimate"]
    if scaled:
        raise ConfigError(f"{config.name}: `noise_scale: estimate` on {', '.join(scaled)} is not supported by crossval "
                          f"({UNSUPPORTED}); give the scale as a number")
    unknown = [name for name in reference if name not in config.stream_columns]
    if unknown:
        raise ConfigError(f"--reference {', '.join(unknown)}: not a stream of the config (it has: "
                          f"{', '.join(sorted(config.stream_columns))})")


def run_folds(config_path: str, overrides: tuple[str, ...], plan: Plan, reference: tuple[str, ...],
              fold_ids: list[int]) -> list[dict]:
    """The results of folds `fold_ids` (a worker's share; the graph built once per process)."""
    with one_blas_thread():
        b = built(config_path, overrides, plan, reference)
        held = folds(b.units.plan, len(b.units.labels))
        return [run_fold(b, i, held[i]) for i in fold_ids]


def run_fold(b: Built, index: int, held_units) -> dict:
    """One fold: {fold, held_out (unit labels), training {...}, entries (scores), seconds} or {fold, error}."""
    tic = time.perf_counter()
    training_ids, held_ids, across = partition(b.units.of_record, held_units)
    out = {"fold": index, "held_out": [b.units.labels[u] for u in held_units.tolist()], "cut_factors": across}
    try:
        training = train(b.problem, training_ids, b.config.solver)
        held = predict(b.problem, training, held_ids, b.roles, b.config.solver)
    except FusionkitError as exc:
        return {**out, "error": str(exc).splitlines()[0], "seconds": time.perf_counter() - tic}
    out["training"] = {"factors": len(training_ids), "chi2_per_dof": training.chi2_per_dof,
                       "status": "rejected" if training.rejection else "accepted", "rejection": training.rejection,
                       "warnings": training.warnings}
    out["parameters"] = calibration(b.problem, training)
    out["anchored_by"] = held.anchored
    out["unpredicted"] = held.unpredicted
    out["entries"] = fold_scores(held, b.parts)
    out["seconds"] = time.perf_counter() - tic
    return out


def calibration(problem: Problem, training) -> dict[str, object]:
    """The fold's estimate of every static variable, by name, as calibration.yaml writes values."""
    out = {}
    for k in training.static:
        vartype = problem.keys.decode(k)[0].vartype
        out[problem.keys.name_of(k)] = vartype.to_list(vartype.read(training.values, k))
    return out


@dataclass
class Outcome:
    """The folds' results (run_fold's dicts, in fold order), pooled per entry (scores.pooled), and the plan with
    its `by` resolved."""

    plan: Plan
    reference: tuple[str, ...]
    folds: list[dict]
    pooled: dict[str, dict]
    seconds: float


def crossval(config_path: str, overrides: list[str], plan: Plan, reference: list[str], backend: str = "local",
             workers: int = 1) -> Outcome:
    """Every fold of `plan`, on `workers` local processes (each an interleaved share of the folds) or Ray."""
    tic = time.perf_counter()
    key = (config_path, tuple(overrides), plan, tuple(reference))
    b = built(*key)  # here first: a config or data error is one line before any worker starts
    count = len(folds(b.units.plan, len(b.units.labels)))
    shares = max(1, min(workers, count)) if backend == "local" else count
    tasks = [(*key, list(range(count))[i::shares]) for i in range(shares)]
    results = [fold for share in run_tasks(run_folds, tasks, backend, workers) for fold in share]
    results.sort(key=lambda f: f["fold"])
    return Outcome(b.units.plan, tuple(reference), results, pooled(results), time.perf_counter() - tic)
