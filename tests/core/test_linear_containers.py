"""Vectorized factors in iSAM2 and the fixed-lag smoother (fusionkit/solve/linear_containers.py): no factor
is evaluated one at a time (no Python callback from GTSAM's C++), factors are linearized again when their
variables move past the threshold, and the estimates match those of the same factors handed to the
solvers as CustomFactors, and batch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fusionkit
from fusionkit.graph.variables import POSE3
from fusionkit.graph.vectorized import VectorizedGroup, VectorizedResidual
from fusionkit.solve import linear_containers

SCALED_VO = Path(__file__).resolve().parents[2] / "configs" / "scaled_vo_mocap.yaml"
SHORT = ["sources.0.params.duration=8"]
SOLVERS = {"isam2": ["solver={type: isam2}"], "isam2_skip3": ["solver={type: isam2, relinearize_skip: 3}"],
           "fixed_lag": ["solver={type: fixed_lag, lag: 3.0}"],
           "fixed_lag_warmup": ["solver={type: fixed_lag, lag: 3.0, warmup: 2.0}"]}


def _pose_gap(a, b) -> float:
    states = a.problem.states["cam"]
    return max(float(np.abs(POSE3.local(a.solution.values.atPose3(states.key(k)),
                                        b.solution.values.atPose3(states.key(k)))).max())
               for k in range(len(states)))


@pytest.fixture(scope="module")
def runs():
    """Each incremental solver with containers (counting the residual's calls made outside a group: one
    factor at a time, as GTSAM calls a CustomFactor) and with the vectorized factors handed over one by
    one (the plain CustomFactor path), plus batch LM."""
    calls = {"group": 0, "alone": 0}
    inside = [False]
    evaluate, linear_factors, residuals = (VectorizedResidual.evaluate, VectorizedGroup.linear_factors,
                                           VectorizedGroup.residuals)

    def counted(self, x, data, jacobians):
        calls["group" if inside[0] else "alone"] += 1
        return evaluate(self, x, data, jacobians)

    def in_group(method):
        def wrapped(self, reader):
            inside[0] = True
            try:
                return method(self, reader)
            finally:
                inside[0] = False
        return wrapped

    out = {"lm": fusionkit.run(SCALED_VO, SHORT)}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(VectorizedResidual, "evaluate", counted)
        mp.setattr(VectorizedGroup, "linear_factors", in_group(linear_factors))
        mp.setattr(VectorizedGroup, "residuals", in_group(residuals))
        for name, extra in SOLVERS.items():
            calls.update(group=0, alone=0)
            out[name] = fusionkit.run(SCALED_VO, SHORT + extra + ["solver.marginals=false"])
            out[name + "_calls"] = dict(calls)
    out["fixed_lag_relinearized"] = fusionkit.run(SCALED_VO, SHORT + SOLVERS["fixed_lag"] + [
        "solver.marginals=false", "solver.relinearize_marginal_variables=true"])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(linear_containers, "tracked", lambda record: None)
        for name, extra in SOLVERS.items():
            out[name + "_one_by_one"] = fusionkit.run(SCALED_VO, SHORT + extra + ["solver.marginals=false"])
    return out


@pytest.mark.slow
@pytest.mark.parametrize("name", SOLVERS)
def test_incremental_solvers_never_evaluate_a_vectorized_factor_one_at_a_time(runs, name):
    calls = runs[name + "_calls"]
    assert sum(r.group is not None for r in runs[name].problem.records) > 100
    assert calls["alone"] == 0 and calls["group"] > 100


@pytest.mark.slow
@pytest.mark.parametrize("name", SOLVERS)
def test_incremental_estimates_with_containers_match_the_one_by_one_factors(runs, name):
    """The same linearizations in the same updates: the same path to rounding (measured 2e-15 after the last
    update; 2e-3 in the fixed-lag runs while fusionkit relinearized the variables GTSAM holds fixed)."""
    gap = _pose_gap(runs[name], runs[name + "_one_by_one"])
    assert gap < 1e-9, gap
    scale = lambda r: float(r.parameters["cam"]["vo_scale"].values[0])  # noqa: E731
    assert scale(runs[name]) == pytest.approx(scale(runs[name + "_one_by_one"]), abs=1e-9)


@pytest.mark.slow
def test_fixed_lag_relinearizes_few_tracked_factors_per_update_unless_told_to_relinearize_frozen_variables(runs):
    """GTSAM holds a variable on a marginal factor (the VO scale once the first state left the window) at its
    frozen point; so do the containers: the median update swaps a few of the tracked factors (measured 1 of 89,
    1.1 %, at 8 s), not all of them as when the frozen scale is relinearized (relinearize_marginal_variables)."""
    held, relinearized = runs["fixed_lag"].solution.swaps, runs["fixed_lag_relinearized"].solution.swaps
    assert held["updates"] > 200 and held["share_p50"] < 0.1 and held["fixed_variables_held_per_update_p50"] > 0
    assert relinearized["share_p50"] > 0.9 and relinearized["fixed_variables_held_per_update_p50"] == 0


@pytest.mark.slow
def test_isam2_relinearize_skip_checks_relinearization_every_third_update_only(runs):
    """relinearize_skip 3: the containers swap factors only at the updates where iSAM2 tests relinearization
    (and the estimates equal those of the factors handed over one by one: the equivalence test above)."""
    swaps = runs["isam2_skip3"].solution.swaps
    assert 0 < swaps["updates_with_swaps"] <= swaps["updates"] / 3 + 1
    every = runs["isam2"].solution.swaps
    assert every["updates_with_swaps"] > swaps["updates_with_swaps"]


@pytest.mark.slow
def test_isam2_with_containers_reaches_the_batch_solution(runs):
    assert _pose_gap(runs["lm"], runs["isam2"]) < 1e-3
    assert runs["isam2"].solution.final_error == pytest.approx(runs["lm"].solution.final_error, rel=1e-3)


def _preintegrated_fixed_lag(monkeypatch, track_python: bool) -> tuple:
    """20 s of wheels.preintegrated + camera poses (fixed lag 5 s after a 5 s warm-up), counting the Python
    factor's linearizations made inside the smoother's updates (between LinearContainers.step and .added)."""
    from fusionkit.pipeline import estimate
    from fusionkit.simulate import simulated_config
    from fusionkit_plugins.wheels import factors as wheel_factors

    inside, calls = [False], {"update": 0}
    error, step, added, tracked = (wheel_factors._preintegrated_error, linear_containers.LinearContainers.step,
                                   linear_containers.LinearContainers.added, linear_containers.tracked)

    def counted(*args):
        calls["update"] += inside[0] and args[-1] is not None
        return error(*args)

    def stepped(self, *args):
        out = step(self, *args)
        inside[0] = True
        return out

    def recorded(self, *args):
        inside[0] = False
        return added(self, *args)

    monkeypatch.setattr(wheel_factors, "_preintegrated_error", counted)
    monkeypatch.setattr(linear_containers.LinearContainers, "step", stepped)
    monkeypatch.setattr(linear_containers.LinearContainers, "added", recorded)
    if not track_python:
        monkeypatch.setattr(linear_containers, "tracked", lambda r: "group" if tracked(r) == "group" else None)

    def edit(config):
        config["robots"]["robot"]["states"]["every"] = 10
        config["factors"] = [config["factors"][0],
                             {"type": "wheels.preintegrated", "robot": "robot", "stream": "wheels", "sigma": 2e-4},
                             {"type": "pose.absolute", "robot": "robot", "stream": "camera",
                              "sigma": {"rotation": 0.02, "translation": 0.0028}}]
        config["initializers"] = [{"type": "pose.interpolate", "robot": "robot", "stream": "camera"}]
        config["solver"] = {"type": "fixed_lag", "lag": 5.0, "warmup": 5.0}
    with simulated_config("wheels.sim", {"duration": 20.0, "path": "figure_eight"}, seed=0, edit=edit) as config:
        return estimate(config), calls["update"]


def test_the_fixed_lag_smoother_never_calls_a_plain_python_factor_and_estimates_as_if_it_did(monkeypatch):
    """wheels.preintegrated is a plain CustomFactor: handed over as it is, iSAM2 calls it inside its updates
    (every window factor again when it re-eliminates in batch); tracked, never, with the same estimates."""
    tracked, in_update = _preintegrated_fixed_lag(monkeypatch, True)
    monkeypatch.undo()
    plain, plain_in_update = _preintegrated_fixed_lag(monkeypatch, False)
    assert in_update == 0 and plain_in_update > 50
    states = tracked.problem.states["robot"]
    gap = max(np.abs(tracked.solution.values.atPose2(states.key(k)).localCoordinates(
        plain.solution.values.atPose2(states.key(k)))).max() for k in range(len(states)))
    assert gap < 1e-4, gap
    for name in ("wheel_radius_left", "wheel_radius_right", "axle_length"):
        a, b = (r.parameters["robot"][name] for r in (tracked, plain))
        assert abs(a.values[0] - b.values[0]) < 0.05 * a.sigma[0, 0], name

