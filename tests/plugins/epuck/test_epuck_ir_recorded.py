"""IR model fitting on readings as a real e-puck logs them (docs/models/epuck.md#fitting-the-models): a robot backing
away from a wall, three readings per millimetre of distance, integer counts that saturate near the wall and clip at 0
far from it, and drop-outs to 0 anywhere. The files are generated here from a known sensor: the fit finds the
saturation, the drop-out probability and where the signal gets weak; its mean never rises with distance; the drop-out
mixture brings held-out coverage within 5 points of 68/95/99.7 % where the Gaussian alone is overconfident; the IR
factor's censored residual with a drop-out probability is the mixture's negative log-likelihood."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit_plugins.epuck.fitting import coverage, fit_sensor, sensor_bank
from fusionkit_plugins.epuck.irfactor import censored_residual
from fusionkit_plugins.epuck.irmodel import Bank

MEAN = [[4000.0, -0.5, 1.2], [900.0, -3.0, 3.5]]    # counts: 3790 at the wall, 17 at 4 cm
VARIANCE = [[300.0, 0.0, 1.5], [20.0, 0.0, 20.0]]   # counts^2: sigma 17.8 at the wall, 4.4 at 4 cm
SATURATION, DROPOUT = 3500.0, 0.05
SENSOR = Bank([MEAN], [VARIANCE], 0.01, 0.0, 0.07)


def backing_away(rng) -> tuple[np.ndarray, np.ndarray]:
    """One run: distances 0 .. 6.6 cm every 2 mm, three readings each, integer counts clipped to 0 .. SATURATION,
    DROPOUT of them 0."""
    d = np.repeat(np.arange(0.0, 0.0661, 0.002), 3)
    ev = SENSOR.evaluate(d, np.zeros(len(d), int))
    z = np.clip(np.round(ev.mean + np.sqrt(ev.var) * rng.standard_normal(len(d))), 0.0, SATURATION)
    z[rng.uniform(size=len(d)) < DROPOUT] = 0.0
    return d, z


def fitted_bank(fit, unit: float = 0.01, dropout: bool = True) -> Bank:
    model = {"mean": fit.mean_fit.terms, "variance": fit.var_fit.terms, "saturation": fit.saturation,
             "dropout": fit.dropout if dropout else 0.0}
    return sensor_bank(model, unit, (fit.x[0] * unit, fit.x[-1] * unit))


@pytest.mark.slow
def test_fit_finds_saturation_dropouts_and_the_weak_end_and_its_mean_never_rises():
    """Three runs: measured saturation 3500 (the nearest distance left out), drop-out probability 0.071 (14 of 198 readings; truth 0.05),
    the fitted range 0.2 .. 4.2 cm (the first distance with a reading clipped at 0 ends it), mean chi2/dof 0.62."""
    rng = np.random.default_rng(0)
    runs = [backing_away(rng) for _ in range(3)]
    fit = fit_sensor(np.concatenate([r[0] for r in runs]), np.concatenate([r[1] for r in runs]), 0.01, max_terms=2)
    assert fit.saturation == SATURATION and fit.saturated == 1
    assert abs(fit.dropout - DROPOUT) < 0.05 and fit.dropped > 0  # 3 binomial sigma of ~200 readings: 0.046
    assert 3.5 < fit.x[-1] < 5.5 and fit.clipped > 5  # cm: beyond, readings near 0 clip
    assert fit.mean_fit.chi2_per_dof < 2.0
    bank = fitted_bank(fit)
    grid = np.linspace(0.0, 0.07, 2000)
    assert np.all(np.diff(bank.evaluate(grid, np.zeros(len(grid), int)).mean) <= 1e-9)


def test_a_sum_rising_between_fitted_distances_is_held_flat_and_agrees_at_them():
    """IR6's published mean rises 71 counts from 0.5 to 0.64 cm: the model holds it flat there and is the sum itself
    at every distance of the published protocol."""
    ir6 = Bank([[[2739.0, 0.638, 0.6323], [4.452e17, -172.8, 29.93]]], [[[1.0, 0.0, 1.0]]], 0.01, 0.005, 0.07)
    assert ir6.sum_rise[0] == pytest.approx(71.1, abs=0.1)
    grid = np.linspace(0.005, 0.07, 3000)
    assert np.all(np.diff(ir6.evaluate(grid, np.zeros(3000, int)).mean) <= 1e-9)
    protocol = np.array([0.5, 1, 1.3, 1.6, 2, 3, 4, 5, 6, 7]) * 0.01
    from fusionkit_plugins.epuck.irmodel import gaussian_sum
    raw = gaussian_sum(ir6.mean_terms, protocol[:, None] / 0.01)[0][:, 0]  # x in cm
    assert ir6.evaluate(protocol, np.zeros(10, int)).mean == pytest.approx(raw, rel=1e-12)


@pytest.mark.slow
def test_dropout_mixture_covers_held_out_runs_within_5_points_where_the_gaussian_alone_does_not():
    """Four runs, each predicted by the models fitted on the other three. Measured (pooled): 66.4/92.9/99.2 % inside
    1/2/3 sigma with the drop-out probability, 61.2/87.9/95.6 % without (the zeros mid-range fall outside)."""
    rng = np.random.default_rng(0)
    runs = [backing_away(rng) for _ in range(4)]
    mixed, plain = [], []
    for k, (d, z) in enumerate(runs):
        train = [r for i, r in enumerate(runs) if i != k]
        fit = fit_sensor(np.concatenate([r[0] for r in train]), np.concatenate([r[1] for r in train]), 0.01, 2)
        mixed.append(coverage(fitted_bank(fit), d, z))
        plain.append(coverage(fitted_bank(fit, dropout=False), d, z))
    mixed, plain = np.mean(mixed, axis=0), np.mean(plain, axis=0)
    assert np.all(np.abs(mixed - [68.3, 95.4, 99.7]) < 5), mixed
    assert plain[2] < mixed[2] - 2 and plain[1] < mixed[1] - 3, plain


def test_coverage_of_the_true_model_is_68_95_997():
    """The coverage measure on the generating model itself (eight runs): 67.2/95.1/99.7 %."""
    rng = np.random.default_rng(0)
    runs = [backing_away(rng) for _ in range(8)]
    truth = Bank([MEAN], [VARIANCE], 0.01, 0.002, 0.042, [DROPOUT], [SATURATION])
    inside = coverage(truth, np.concatenate([r[0] for r in runs]), np.concatenate([r[1] for r in runs]))
    assert np.all(np.abs(inside - [68.3, 95.4, 99.7]) < 2), inside


@pytest.mark.slow
def test_fit_ir_writes_dropout_saturation_and_range_and_prints_held_out_coverage(tmp_path, capsys):
    rng = np.random.default_rng(0)
    files = []
    for i in range(2):
        d, z = backing_away(rng)
        path = tmp_path / f"run{i}.csv"
        path.write_text("distance,sensor,reading\n" + "".join(f"{a:.4f},7,{b:g}\n" for a, b in zip(d, z)))
        files.append(path)
    assert main(["epuck-fit-ir", str(files[0]), "--out", str(tmp_path / "ir"), "--held-out", str(files[1]),
                 "--max-terms", "2"]) == 0
    out = capsys.readouterr().out
    assert "1 saturated at 3500" in out and "held-out readings" in out
    fragment = yaml.safe_load((tmp_path / "ir" / "ir_models.yaml").read_text())
    sensor = fragment["sensors"]["ir7"]
    assert sensor["saturation"] == SATURATION and 0.0 < sensor["dropout"] < 0.2
    assert fragment["ir_range"][0] == pytest.approx(0.002) and 0.035 < fragment["ir_range"][1] < 0.055


def test_censored_residual_with_a_dropout_is_the_mixtures_negative_log_likelihood():
    from scipy.stats import norm
    u = np.linspace(-6.0, 6.0, 49)
    pi = np.full(len(u), 0.05)
    e, de = censored_residual(u, pi)
    assert 0.5 * e ** 2 == pytest.approx(-np.log(pi + (1 - pi) * norm.cdf(-u)), rel=1e-9, abs=1e-12)
    step = 1e-6
    numeric = (censored_residual(u + step, pi)[0] - censored_residual(u - step, pi)[0]) / (2 * step)
    assert de == pytest.approx(numeric, rel=1e-5, abs=1e-6)
    assert e.max() <= np.sqrt(-2 * np.log(0.05)) + 1e-12  # a drop-out costs at most -log pi
    plain, _ = censored_residual(u)
    assert censored_residual(u, np.zeros(len(u)))[0] == pytest.approx(plain)
