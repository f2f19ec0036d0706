"""The fitting tools recover simulated truths: an IR sensor's Gaussian-sum mean (its coefficients,
the number of terms, and curve sigmas that cover the truth) and the velocity-model alphas from
repeated trials, within their sigmas; the commands write what they print, and refuse bad files in
one located line."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit_plugins.epuck.fitting import fit_alphas, fit_sensor
from fusionkit_plugins.epuck.irmodel import Bank

DISTANCES = np.array([0.5, 1, 1.3, 1.6, 2, 3, 4, 5, 6, 7]) * 0.01   # m: the published protocol
# IR6 of the published table: a bump at 0.64 cm and a decay (a 4.45e17 term), and its variance
IR6_MEAN = [[2739.0, 0.638, 0.6323], [4.452e17, -172.8, 29.93]]
IR6_VAR = [[302.0, 0.8934, 0.4466], [-285.2, 0.8869, 0.4686], [9.893, -0.8852, 6.031]]


def readings(mean_terms, var_terms, per_distance: int, rng):
    bank = Bank([mean_terms], [var_terms], 0.01, 0.005, 0.07)
    d = np.repeat(DISTANCES, per_distance)
    ev = bank.evaluate(d, np.zeros(len(d), int))
    return d, ev.mean + np.sqrt(ev.var) * rng.standard_normal(len(d)), bank


def test_ir_fit_recovers_the_published_bump_of_a_two_term_mean_with_sigmas_that_cover_the_truth():
    d, z, bank = readings(IR6_MEAN, IR6_VAR, 120, np.random.default_rng(0))
    fit = fit_sensor(d, z, 0.01, max_terms=2)
    assert len(fit.mean_fit.terms) == 2 and fit.mean_fit.chi2_per_dof < 2.0      # measured: 0.75
    assert fit.mean_fit.candidates[1]["bic"] > fit.mean_fit.candidates[2]["bic"]
    bump = min(fit.mean_fit.terms, key=lambda t: abs(t[1]))
    assert bump == pytest.approx(IR6_MEAN[0], rel=0.01)                          # measured: 0.04 %, 0.03 %, 0.02 %
    truth = bank.evaluate(DISTANCES, np.zeros(10, int)).mean
    fitted = Bank([fit.mean_fit.terms], [fit.var_fit.terms], 0.01, 0.005, 0.07).evaluate(DISTANCES, np.zeros(10, int))
    assert np.max(np.abs(fitted.mean - truth) / fit.mean_fit.curve_sigma) < 3.0


def book_trials(alpha, n, rng):
    """n straight runs (10 and 20 cm), spins (2 pi, 4 pi) and turns (+90, -45, +45 deg), each one command of
    the velocity model held for 2 s: translation error = (v_hat - v) T, rotation error = (w_hat - w) T."""
    T = 2.0
    rows = []
    for kind, amounts in ((0, (0.1, 0.2)), (1, (2 * np.pi, 4 * np.pi)), (2, (np.pi / 2, -np.pi / 4, np.pi / 4))):
        for u in rng.choice(amounts, n):
            v, w = (u / T, 0.0) if kind == 0 else (0.0, u / T)
            s_v, s_w = alpha[0] * abs(v) + alpha[1] * abs(w), alpha[2] * abs(v) + alpha[3] * abs(w)
            rows.append((kind, u, rng.normal(0, s_v) * T, rng.normal(0, s_w) * T))
    return np.array(rows)


def test_alphas_from_repeated_trials_are_recovered_within_their_sigmas():
    alpha = np.array([0.045, 8.8e-5, 0.095862, 0.1181])
    trials = book_trials(alpha, 60, np.random.default_rng(1))
    fits = fit_alphas(trials[:, 0], trials[:, 1], trials[:, 2], trials[:, 3])
    for i, name in enumerate(("alpha1", "alpha2", "alpha3", "alpha4")):
        f = fits[name]
        assert abs(f.value - alpha[i]) < 3 * f.sigma and f.interval[0] < alpha[i] < f.interval[1], (name, f)
        assert abs(f.mean_ratio) < 3 * f.mean_ratio_sigma  # zero-mean errors: no systematic part


def test_fit_commands_write_a_description_fragment_and_refuse_a_bad_kind_in_one_line(tmp_path, capsys):
    rng = np.random.default_rng(2)
    trials = book_trials(np.array([0.045, 8.8e-5, 0.095862, 0.1181]), 10, rng)
    csv = tmp_path / "trials.csv"
    csv.write_text("t,kind,commanded,translation_error,rotation_error\n" +
                   "".join(f"{i},{k:g},{u:.17g},{a:.17g},{b:.17g}\n" for i, (k, u, a, b) in enumerate(trials)))
    assert main(["epuck-fit-motion", str(csv), "--out", str(tmp_path / "motion")]) == 0
    written = yaml.safe_load((tmp_path / "motion" / "velocity_noise.yaml").read_text())
    assert len(written["velocity_noise"]["alpha"]) == 4 and "alpha4 = " in capsys.readouterr().out
    csv.write_text("t,kind,commanded,translation_error,rotation_error\n0,5,0.1,0.001,0.002\n")
    assert main(["epuck-fit-motion", str(csv), "--out", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip()
    assert "kind must be 0, 1 or 2" in err and len(err.splitlines()) == 1 and not (tmp_path / "bad").exists()
    d, z, _ = readings(IR6_MEAN, IR6_VAR, 20, rng)
    ir = tmp_path / "readings.csv"
    ir.write_text("t,distance,sensor,reading\n" + "".join(f"{i},{a:.17g},6,{b:.17g}\n" for i, (a, b) in enumerate(zip(d, z))))
    assert main(["epuck-fit-ir", str(ir), "--out", str(tmp_path / "ir"), "--max-terms", "1"]) == 0
    models = yaml.safe_load((tmp_path / "ir" / "ir_models.yaml").read_text())["sensors"]
    assert list(models) == ["ir6"] and set(models["ir6"]) == {"mean", "variance"}


@pytest.mark.slow
def test_fit_ir_reads_readings_without_time_and_touching_the_wall_and_records_the_range(tmp_path, capsys):
    """A real robot backing away from a wall logs no timestamps, and its first readings touch the wall (distance 0):
    both are accepted, and the written fragment carries ir_range, the distances fitted on, so a description that
    takes it reads the models where they hold."""
    from fusionkit_plugins.epuck.model import ir_layout_from_data
    rng = np.random.default_rng(4)
    distances = np.concatenate([[0.0], DISTANCES])
    bank = Bank([IR6_MEAN], [IR6_VAR], 0.01, 0.005, 0.07)
    d = np.repeat(distances, 20)
    ev = bank.evaluate(np.maximum(d, 0.005), np.zeros(len(d), int))
    z = ev.mean + np.sqrt(ev.var) * rng.standard_normal(len(d))
    ir = tmp_path / "backing_away.csv"
    ir.write_text("distance,sensor,reading\n" + "".join(f"{a:.17g},0,{b:.17g}\n" for a, b in zip(d, z)))
    assert main(["epuck-fit-ir", str(ir), "--out", str(tmp_path / "ir")]) == 0
    assert "ir_range 0 .. 0.07 m" in capsys.readouterr().out
    fragment = yaml.safe_load((tmp_path / "ir" / "ir_models.yaml").read_text())
    assert fragment["ir_range"] == [0.0, 0.07] and fragment["ir_distance_unit"] == 0.01
    sensor = {"type": "ir_proximity", "frame": "base", **fragment["sensors"]["ir0"]}
    layout = ir_layout_from_data({"ir_range": fragment["ir_range"], "ir_distance_unit": 0.01,
                                  "sensors": {"ir0": sensor}})
    fitted = layout.bank.evaluate(DISTANCES, np.zeros(10, int)).mean
    truth = bank.evaluate(DISTANCES, np.zeros(10, int)).mean
    assert np.max(np.abs(fitted - truth) / truth) < 0.05


def test_a_start_where_the_linear_algebra_fails_does_not_stop_the_fit(monkeypatch):
    """One diverging start (LAPACK's `SVD did not converge` on a real sensor) is skipped: the fit goes on with the
    other starts and finds the same model."""
    import scipy.optimize
    d, z, _ = readings(IR6_MEAN, IR6_VAR, 40, np.random.default_rng(5))
    clean = fit_sensor(d, z, 0.01, max_terms=2)
    real, calls = scipy.optimize.least_squares, []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) in (3, 40):
            raise np.linalg.LinAlgError("SVD did not converge in Linear Least Squares")
        return real(*args, **kwargs)
    monkeypatch.setattr(scipy.optimize, "least_squares", failing)
    fit = fit_sensor(d, z, 0.01, max_terms=2)
    assert len(calls) > 40
    assert fit.mean_fit.chi2 == pytest.approx(clean.mean_fit.chi2, rel=1e-3)


def test_drop_outs_are_left_out_so_the_fitted_noise_covers_held_out_readings():
    """IR6's models with 10 % of the readings dropped to 0 (a real e-puck does so mid-range): the zeros are found
    (where a distance's median reading is not 0) and left out, and held-out readings of the same sensor (drop-outs
    aside) fall inside 1/2/3 of the fitted sigma within 5 points of 68/95/99.7 %; kept in, the zeros inflate the
    variance and drag the mean."""
    from fusionkit_plugins.epuck.fitting import distance_statistics, dropouts
    rng = np.random.default_rng(6)
    d, z, bank = readings(IR6_MEAN, IR6_VAR, 60, rng)
    gone = rng.uniform(size=len(z)) < 0.1
    z = np.where(gone, 0.0, z)
    assert np.array_equal(dropouts(d, z, 0.01), gone)
    fit = fit_sensor(d, z, 0.01, max_terms=2)
    assert fit.dropped == int(gone.sum())
    model = Bank([fit.mean_fit.terms], [fit.var_fit.terms], 0.01, 0.005, 0.07)
    d2, z2, _ = readings(IR6_MEAN, IR6_VAR, 200, np.random.default_rng(7))  # held out
    ev = model.evaluate(d2, np.zeros(len(d2), int))
    u = np.abs(z2 - ev.mean) / np.sqrt(ev.var)
    inside = [100 * np.mean(u < k) for k in (1, 2, 3)]
    assert all(abs(a - b) < 5 for a, b in zip(inside, (68.3, 95.4, 99.7))), inside
    _, _, mean_in, var_in = distance_statistics(d, z, 0.01)
    _, _, mean_out, var_out = distance_statistics(d[~gone], z[~gone], 0.01)
    assert np.all(var_in > 2 * var_out) and np.all(mean_in < mean_out)
