"""The checks of a solution that need no ground truth, against their formulas (solve/prior_check.py,
solve/noise_check.py, the revision check of solve/health.py) on the pose.scaled_vo simulation (6 s, seed 1:
a monocular VO of unknown scale, motion capture every 2 s, the scale's prior 1 +- 10)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2, norm

from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate
from fusionkit.solve.noise_scales import redundancies
from fusionkit.solve.prior_check import ALPHA, prior_check, prior_tests


def _run(ds, *overrides):
    return estimate(load_config(ds / "config.yaml", ["output.plots=false", *overrides]), keep_rejected=True)


def _scale(result):
    key = next(k for k in result.problem.initial.keys() if result.problem.keys.name_of(k) == "cam/vo_scale")
    return key, float(result.solution.values.atDouble(key)), float(result.solution.covariances[key][0, 0])


def test_prior_statistic_is_the_squared_residual_over_prior_minus_posterior_variance(ds):
    """Baarda's test of the prior as an observation: T = (x - mu)^2 / (sigma_p^2 - sigma^2)."""
    result = _run(ds)
    key, value, variance = _scale(result)
    (test,) = [t for t in prior_tests(result.problem, result.solution.values, result.solution.covariances)
               if t.key == key]
    assert test.dof == 1 and test.prior_only == 0
    assert test.statistic == pytest.approx((value - 1.0) ** 2 / (10.0 ** 2 - variance), rel=1e-9)
    assert test.statistic < 0.1  # 2.45 against 1 +- 10: no conflict, and no warning
    assert result.solution.warnings == []


def test_a_tight_prior_the_data_contradict_is_prior_conflict_at_the_bonferroni_bound(ds, tmp_path):
    """A prior 1 +- 0.1 on a scale the motion capture puts near 2.5: far beyond 1 - ALPHA."""
    description = ds / "robots" / "cam.yaml"
    description.write_text(description.read_text().replace("sigma: 10.0", "sigma: 0.1"))
    result = _run(ds)
    key, value, variance = _scale(result)
    (test,) = prior_tests(result.problem, result.solution.values, result.solution.covariances)
    sigmas = abs(value - 1.0) / np.sqrt(0.1 ** 2 - variance)
    assert np.sqrt(test.statistic) == pytest.approx(sigmas, rel=1e-9)
    assert sigmas > norm.isf(ALPHA / 2)  # measured: 13.8
    (w,) = [w for w in result.solution.warnings if w.name == "prior_conflict"]
    assert w.message.startswith("the data pull 1 of 1 parameters beyond chance from their priors (beyond the "
                                f"1 - 0.001/1 quantile): cam/vo_scale = {value:.5g} ± ")
    assert f"{abs(value - 1.0) / 0.1:.3g} prior sigmas from its prior 1 ± 0.1 ({sigmas:.3g} sigma of that difference" \
        in w.message


def test_a_prior_no_data_inform_is_prior_only_and_not_tested(ds):
    """The same statistic with the data's share of the information below 1 %: nothing to test, the prior named."""
    result = _run(ds, "factors.1.sigma.translation=1000", "factors.1.sigma.rotation=1000")
    key, _, variance = _scale(result)
    assert 1 - variance / 100.0 < 0.01
    (test,) = prior_tests(result.problem, result.solution.values, result.solution.covariances)
    assert (test.dof, test.prior_only) == (0, 1)
    names = [w.name for w in prior_check(result.problem, result.solution.values, result.solution.covariances)]
    assert names == ["prior_only"]


def test_redundancies_add_up_to_rows_minus_unknowns_and_chi_squares_to_the_total(ds):
    """sum r_g = m - n, sum chi2_g = 2 * cost: what makes chi2_g / r_g an entry's own variance factor."""
    result = _run(ds)
    values = result.solution.values
    fits = redundancies(result.problem, values)
    rows = sum(f.rows for f in fits.values())
    assert sum(f.redundancy for f in fits.values()) == pytest.approx(rows - values.dim(), abs=1e-6)
    assert sum(f.chi2 for f in fits.values()) == pytest.approx(2 * result.solution.final_error, rel=1e-9)


@pytest.mark.parametrize("factor, name", [(0.05, "noise_understated"), (20.0, "noise_overstated")])
def test_all_sigmas_scaled_move_the_chi_square_beyond_its_quantiles_and_warn(ds, factor, name):
    """Every sigma times `factor` divides chi2 by factor^2 (clean: 1.55 per dof; 0.05 gives 620, beyond the gate of
    10 per dof, which is raised here to let the warning speak)."""
    vo = {"factors.0.sigma.rotation": 0.002, "factors.0.sigma.translation": 0.0016}  # the dataset's sigmas
    mocap = {"factors.1.sigma.rotation": 0.01, "factors.1.sigma.translation": 0.01}
    sets = [f"{k}={v * factor}" for k, v in {**vo, **mocap}.items()]
    result = _run(ds, *sets, "solver.max_cost_ratio=1e6")
    dof = 12
    total = result.solution.chi2_per_dof * dof
    assert (total > chi2.ppf(1 - 1e-6, dof)) if name == "noise_understated" else (total < chi2.ppf(1e-6, dof))
    (w,) = [w for w in result.solution.warnings if w.name.startswith("noise_")]
    assert w.name == name
    times = float(w.message.split("the residuals scatter about ")[1].split(" ")[0])
    assert times == pytest.approx(np.sqrt(result.solution.chi2_per_dof) ** (1 if factor < 1 else -1), rel=5e-3)  # printed to 3 digits


def test_isam2_one_step_per_update_warns_incremental_jumps_where_the_scale_becomes_observable(ds):
    """The scale is unobservable until the second motion-capture sample (t = 2 s); one Gauss-Newton step there
    leaves the live estimate unconverged, and the next update moves it beyond its sigma. Three steps per update
    converge it: no warning."""
    one = _run(ds, "solver.type=isam2")
    (w,) = [w for w in one.solution.warnings if w.name == "incremental_jumps"]
    assert 2.0 <= w.span[0] < w.span[1] < 2.2
    assert "worst cam/vo_scale at t = " in w.message
    assert w.message.endswith("solver.updates_per_step: 2 or more converges each update further")
    three = _run(ds, "solver.type=isam2", "solver.updates_per_step=3")
    assert [w.name for w in three.solution.warnings] == []
    assert abs(_scale(three)[1] - _scale(one)[1]) < 0.01
