"""A drifting joint offset (time-varying parameter + parameter.random_walk) tracked along a 60 s joint
trajectory at 5 Hz by batch, iSAM2 and the fixed-lag smoother, with the arm's other 48 kinematic parameters
estimated alongside. The offset of the elbow drifts by 4 mrad (a smooth S-curve); thresholds come from
measured runs (stated at each)."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.serial_arm.simulators import DRIFT_PARAMETER, drift_truth

PARAMS = {"motion": "trajectory", "duration": 60.0, "rate": 5.0, "drift": {"change": 0.004}}
SOLVERS = {"batch": {"type": "batch"}, "isam2": {"type": "isam2"}, "fixed_lag": {"type": "fixed_lag", "lag": 5.0}}
pytestmark = pytest.mark.slow  # every test reads the three 60 s runs of one fixture (11 s)


@pytest.fixture(scope="module")
def runs() -> dict:
    out = {}
    for name, solver in SOLVERS.items():
        with simulated_config("arm.sim", PARAMS, seed=2, edit=lambda c, s=solver: c.update(solver=s)) as config:
            out[name] = estimate(config)
    return out


def drift_errors(result) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(state times, estimate - truth, sigma, estimate) of the drifting offset."""
    est = result.parameters["arm"][f"{DRIFT_PARAMETER}[0]"]
    start = result.truth.calibration["arm"][DRIFT_PARAMETER]["values"][0]
    values = np.ravel(est.values).astype(float)
    return est.series_t, values - drift_truth(PARAMS, est.series_t, start), np.ravel(est.sigma), values


@pytest.mark.parametrize("solver, settled", [("batch", 0.0), ("isam2", 10.0), ("fixed_lag", 30.0)])
def test_the_drifting_offset_is_tracked_to_a_twentieth_of_its_drift(runs, solver, settled):
    """rms error below 0.2 mrad (measured over seeds 2-4: 0.08-0.10 mrad) once `settled` s have passed -- the
    fixed-lag smoother keeps the estimates it had when states left its 5 s window, made before the static
    parameters were known (measured 0.5-1.2 mrad rms over the whole run, 0.09 mrad after 30 s); |z| < 4
    there (measured 2.4-3.9)."""
    t, err, sigma, values = drift_errors(runs[solver])
    assert len(t) == 300
    late = t >= settled
    assert np.sqrt(np.mean(err[late] ** 2)) < 2e-4
    assert np.max(np.abs(err[late] / sigma[late])) < 4.0
    first = np.argmax(late)  # the change since then: most of the 4 mrad drift
    change = drift_truth(PARAMS, t, 0.0)
    assert abs((values[-1] - values[first]) - (change[-1] - change[first])) < 5e-4


@pytest.mark.parametrize("solver", SOLVERS)
def test_the_static_parameters_are_estimated_alongside(runs, solver):
    """Every estimated axis of base, marker, offsets and placements within 0.2 mm / 0.2 mrad of the truth
    (measured over seeds 2-4: 0.02-0.04 batch and iSAM2, 0.03-0.06 fixed-lag) and, for batch and iSAM2,
    within 4 sigma (measured max |z| 2.3-3.5). The fixed-lag smoother's sigmas are optimistic (measured
    max |z| 2.6-6.7): what left its window stays linearized at the estimate of that moment."""
    result = runs[solver]
    for name, ev in result.evaluation["parameters"]["arm"].items():
        sigma = np.ravel(result.parameters["arm"][name].sigma)
        z = np.ravel(ev["z_per_axis"])[sigma > 1e-6]
        assert np.all(np.abs(z * sigma[sigma > 1e-6]) < 2e-4), name
        if solver != "fixed_lag":
            assert np.all(np.abs(z) < 4.0), name


def test_incremental_solvers_record_a_latency_per_step(runs):
    for solver in ("isam2", "fixed_lag"):
        assert len(runs[solver].solution.step_latency) >= 300
