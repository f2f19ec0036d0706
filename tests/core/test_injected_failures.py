"""Injected silent failures (issue 31, section 1): a fault planted in a config or in data the project simulates
itself must end in exit 2 (one stderr line naming what is wrong), a rejection (exit 4, report.json "status":
"rejected") or a named warning (report.json `warnings`, printed as `warning [name] (t = a .. b s): ...`), and the
test asserts which, and what it names.

Data: the pose.scaled_vo dataset of tests/conftest.py (6 s, seed 1; `ds`), wheels.sim runs (6 s and 10 s, seed 2)
and the faulty wheels run of docs/tutorials/wheeled_robot.md (20 s, seed 2, stuck wheel and bumps)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from fusionkit.cli.main import main
from test_bad_input import PREFIX, fails, line_of, rejected, run

REPO = Path(__file__).resolve().parents[2]
SCALED_VO = REPO / "configs" / "scaled_vo_mocap.yaml"
CAMERA = {"type": "pose.absolute", "robot": "robot", "stream": "camera",
          "sigma": {"rotation": 0.02, "translation": 0.0028}}  # the wheels tutorial's calibration factor
FAULTY = ["duration=20", "faults.roughness.height=0.0015", "faults.stuck.count=1", "faults.bumps.count=2"]


# ---------------------------------------------------------------- datasets and helpers


def _simulated(factory, scenario: str, overrides: list[str], seed: int) -> Path:
    from fusionkit.simulate import write_dataset
    folder = factory.mktemp(scenario.replace(".", "_")) / "ds"
    write_dataset(scenario, folder, overrides, seed=seed)
    return folder


@pytest.fixture(scope="module")
def wheels_6s(tmp_path_factory) -> Path:
    return _simulated(tmp_path_factory, "wheels.sim", ["duration=6"], 2)


@pytest.fixture(scope="module")
def wheels_10s(tmp_path_factory) -> Path:
    return _simulated(tmp_path_factory, "wheels.sim", ["duration=10"], 2)


@pytest.fixture(scope="module")
def wheels_faulty(tmp_path_factory) -> Path:
    """`fusionkit simulate wheels.sim --out out/wheels --seed 2 --set duration=20 ...` of the wheels tutorial."""
    return _simulated(tmp_path_factory, "wheels.sim", FAULTY, 2)


@pytest.fixture
def out(tmp_path) -> Path:
    return tmp_path / "out"


def copy_of(dataset: Path, tmp_path: Path) -> Path:
    """A private copy of a simulated dataset; returns its config.yaml."""
    return shutil.copytree(dataset, tmp_path / "data_copy") / "config.yaml"


def edit_config(config: Path, change) -> Path:
    data = yaml.safe_load(config.read_text())
    change(data)
    config.write_text(yaml.safe_dump(data, sort_keys=False))
    return config


def edit_tum(path: Path, change) -> None:
    """`change(row)` on every data row of a TUM file (floats t x y z qx qy qz qw), in place."""
    rows = [line.split() for line in path.read_text().splitlines() if not line.startswith("#")]
    rows = [change([float(v) for v in row]) for row in rows]
    path.write_text("# t x y z qx qy qz qw\n" + "".join(" ".join(f"{v:.9f}" for v in r) + "\n" for r in rows))


def edit_csv(path: Path, change) -> None:
    """`change(columns)` on a stream CSV's columns (name -> float array), in place."""
    lines = path.read_text().splitlines()
    names = lines[0].split(",")
    table = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    columns = {name: table[:, i].copy() for i, name in enumerate(names)}
    change(columns)
    path.write_text(",".join(names) + "\n" + "".join(",".join(repr(float(columns[n][i])) for n in names) + "\n"
                                                     for i in range(len(table))))


def report(out: Path) -> dict:
    return json.loads((out / "report.json").read_text())


def warned(capsys, argv: list[str], out: Path, name: str, code: int = 0) -> dict:
    """Run the CLI; assert the exit code, the warning `name` in report.json and its line on the console; return
    the warning's report.json entry."""
    assert main(argv) == code
    printed = capsys.readouterr().out
    found = [w for w in report(out)["warnings"] if w["name"] == name]
    assert len(found) == 1, report(out)["warnings"]
    w = found[0]
    where = f" (t = {w['t_start']:.2f} .. {w['t_end']:.2f} s)" if "t_start" in w else ""
    assert f"  warning [{name}]{where}: {w['message']}" in printed.splitlines()
    return w


def ratio_in(message: str) -> float:
    """The first `chi-square per degree of freedom [up to] X` of a message."""
    return float(message.split("chi-square per degree of freedom ")[1].removeprefix("up to ").split(" ")[0])


def unconstrained(config: Path, n: int, unknowns: int, moving: str, fix: str) -> str:
    return (f"{config}: the factors leave {n} direction{'s' if n > 1 else ''} of the {unknowns} unknowns "
            "unconstrained (the whitened Jacobian is rank-deficient: |R_jj| / ||A e_j|| below 1e-09); moving without "
            f"changing any residual: {moving}; add {fix}")


@pytest.mark.parametrize("dataset", ["ds", "wheels_6s"])
def test_the_datasets_before_any_injection_run_with_exit_0_and_no_warning_of_a_fault(request, tmp_path, capsys,
                                                                                   dataset):
    """The control for every test below: the faults, not the data, cause what they assert. The wheels run's one
    warning is true of clean data: wheels and a gyro without an absolute reference leave the axle length to its
    prior (docs/models/wheels.md, residuals), and prior_only says so."""
    folder = request.getfixturevalue(dataset)
    out = tmp_path / "out"
    assert main(run(folder / "config.yaml", out)) == 0, capsys.readouterr().err
    printed = [line for line in capsys.readouterr().out.splitlines() if "warning" in line]
    assert report(out)["status"] == "accepted"
    if dataset == "ds":
        assert report(out)["warnings"] == [] and printed == []
    else:
        assert [w["name"] for w in report(out)["warnings"]] == ["prior_only"] and len(printed) == 1
        assert report(out)["warnings"][0]["message"].startswith("the data reduce the prior variance of "
                                                                "robot/axle_length by less than 1%")


# ---------------------------------------------------------------- 1-4. gauge freedom under every factorization/solver


@pytest.mark.parametrize("solver", ["solver.type=batch", "solver.factorization=qr", "solver.type=isam2",
                                    "solver.type=fixed_lag"])
def test_missing_pose_origin_is_exit_2_naming_the_three_planar_gauge_directions(wheels_6s, tmp_path, out, capsys,
                                                                               solver):
    """Wheel odometry and a gyro without pose.origin: the whole SE(2) path floats (x, y, heading). Before 793b022
    Cholesky named robot/gyro_bias instead and QR solved it with exit 0."""
    config = edit_config(copy_of(wheels_6s, tmp_path), lambda c: c["factors"].pop(0))
    message = fails(capsys, run(config, out, "--set", solver), out=out)
    assert message == unconstrained(
        config, 3, 366, "robot/pose[0..119] (all 120; tx, ty, rz): 3 directions",
        "a prior or an absolute measurement of the first state robot/pose[0] (tx, ty, rz), e.g. a pose.origin or "
        "pose.absolute factor")


# ---------------------------------------------------------------- 5. scale-free VO without a scale anchor


def _vo_without_mocap(config: Path) -> Path:
    """The scaled-VO dataset as a monocular camera alone: no motion capture (source, factor, initializers), the
    first pose fixed by pose.origin; nothing measures the VO's scale."""
    def change(c):
        c["sources"] = [s for s in c["sources"] if s["name"] != "mocap"]
        c["factors"] = [c["factors"][0], {"type": "pose.origin", "robot": "cam",
                                          "sigma": {"rotation": 0.001, "translation": 0.001}}]
        c["initializers"] = []
    return edit_config(config, change)


def test_vo_scale_without_prior_or_anchor_is_exit_2_naming_cam_vo_scale(ds, out, capsys):
    config = _vo_without_mocap(ds / "config.yaml")
    description = ds / "robots" / "cam.yaml"
    description.write_text(description.read_text().replace("    sigma: 10.0\n", ""))
    assert "sigma" not in description.read_text()
    assert fails(capsys, run(config, out), out=out) == unconstrained(
        config, 1, 1081, "cam/vo_scale",
        "a prior sigma for cam/vo_scale in the robot description, or a measurement of it")


def test_vo_scale_held_only_by_its_weak_prior_is_warning_prior_only(ds, out, capsys):
    """Before this check: exit 0, no warning, cam/vo_scale = 1 +- 10, its prior exactly (the weak prior keeps the
    rank full)."""
    config = _vo_without_mocap(ds / "config.yaml")
    w = warned(capsys, run(config, out), out, "prior_only")
    assert w["message"] == ("the data reduce the prior variance of cam/vo_scale by less than 1%: the values reported "
                            "are their priors -- as meant for a surveyed or known value; one meant to be calibrated "
                            "needs a recording that moves it, or a measurement of it")
    assert report(out)["parameters"]["cam"]["vo_scale"]["sigma"] == pytest.approx(10, rel=1e-3)


# ---------------------------------------------------------------- 6. a stream on the wrong clock


def test_mocap_stamped_2_5_s_late_is_rejected_naming_the_mocap_factor(ds, out, capsys):
    config = ds / "config.yaml"
    edit_tum(ds / "data" / "mocap.tum", lambda r: [r[0] + 2.5, *r[1:]])
    message = rejected(capsys, run(config, out), out)
    assert message.startswith(f"{config}: the solver stopped with a large residual: chi-square per degree of freedom ")
    assert ratio_in(message) > 50  # measured: 85.6 (clean: 1.55)
    assert "the limit is solver.max_cost_ratio=10" in message
    assert "largest contributions: factors[0]:pose.scaled_relative (" in message
    assert "factors[1]:pose.absolute (" in message.split("largest contributions: ")[1]


# ---------------------------------------------------------------- 7. swapped columns


def test_mocap_with_x_and_y_swapped_is_rejected_by_the_chi_square_gate(ds, out, capsys):
    """Swapping two axes is a reflection: no rigid motion of the trajectory absorbs it."""
    config = ds / "config.yaml"
    edit_tum(ds / "data" / "mocap.tum", lambda r: [r[0], r[2], r[1], *r[3:]])
    message = rejected(capsys, run(config, out), out)
    assert message.startswith(f"{config}: the solver stopped with a large residual: chi-square per degree of freedom ")
    assert ratio_in(message) > 100  # measured: 179
    assert report(out)["solver"]["chi2_per_dof"] == pytest.approx(ratio_in(message), rel=1e-2)


def test_left_and_right_wheel_columns_swapped_is_warning_prior_conflict_naming_the_gyro_scale(wheels_6s, tmp_path,
                                                                                             out, capsys):
    """The mirrored motion is absorbed by a negative gyro scale at chi2/dof 1.03 (before this check: exit 0 and
    no warning, ATE 0.30 m); only the prior (1 +- 0.5; truth 1.25) says it cannot be."""
    config = copy_of(wheels_6s, tmp_path)
    edit_csv(config.parent / "data" / "wheels.csv", lambda c: c.update(left=c["right"], right=c["left"]))
    w = warned(capsys, run(config, out), out, "prior_conflict")
    assert w["message"].startswith("the data pull 1 of 5 parameters beyond chance from their priors (beyond the "
                                   "1 - 0.001/5 quantile): robot/gyro_scale = -1.2")
    priors = float(w["message"].split(", ")[1].split(" prior sigmas from its prior 1 ± 0.5")[0])
    assert 4 < priors < 5  # measured: 4.53 (the test: 4.54 sigma of the difference; Bonferroni bound for 5: 3.72)
    assert " sigma of that difference" in w["message"]


# ---------------------------------------------------------------- 8. a sigma 100x too small


def test_camera_sigma_100x_too_small_is_rejected_by_the_chi_square_gate(wheels_6s, tmp_path, out, capsys):
    tight = {**CAMERA, "sigma": {"rotation": 0.0002, "translation": 0.000028}}
    config = edit_config(copy_of(wheels_6s, tmp_path), lambda c: c["factors"].append(tight))
    message = rejected(capsys, run(config, out), out)
    assert message.startswith(f"{config}: the solver stopped with a large residual: chi-square per degree of freedom ")
    assert ratio_in(message) > 50  # measured: 139; with the tutorial's camera sigma about 1
    assert "(about 1 is expected; the limit is solver.max_cost_ratio=10)" in message


def test_vo_sigma_100x_too_small_is_warning_noise_understated_saying_by_how_much(ds, out, capsys):
    """chi2/dof 5.33 on 12 degrees of freedom passes the gate of 10 per dof (before this check: exit 0, no
    warning) but is beyond chance (p = 4e-9). The VO, now near exact, leaves the misfit in the motion capture's
    residuals: the entry named is where it shows."""
    config = ds / "config.yaml"
    w = warned(capsys, run(config, out, "--set", "factors.0.sigma.rotation=0.00002",
                           "--set", "factors.0.sigma.translation=0.000016"), out, "noise_understated")
    assert report(out)["status"] == "accepted"
    assert w["message"].startswith("chi-square per degree of freedom ")
    assert 4.2 < ratio_in(w["message"]) < 10  # measured: 5.33; the 1 - 1e-6 quantile for 12 dof is 4.2 per dof
    assert "(above its 1 - 1e-06 quantile for 12 degrees of freedom)" in w["message"]
    assert "factors[1]:pose.absolute " in w["message"].split("chi-square per redundancy by entry")[1]


# ---------------------------------------------------------------- 9. a sigma 100x too large


def test_vo_sigma_100x_too_large_is_warning_noise_overstated_saying_by_how_much(ds, out, capsys):
    config = ds / "config.yaml"
    w = warned(capsys, run(config, out, "--set", "factors.0.sigma.rotation=0.2",
                           "--set", "factors.0.sigma.translation=0.16"), out, "noise_overstated")
    assert report(out)["status"] == "accepted" and "t_start" not in w
    assert w["message"].startswith("chi-square per degree of freedom ")
    assert ratio_in(w["message"]) < 0.01  # measured: 0.00169 (clean: 1.55)
    assert "(below its 1e-06 quantile for 12 degrees of freedom)" in w["message"]
    times = float(w["message"].split("the residuals scatter about ")[1].split(" ")[0])
    assert 10 < times < 100  # measured: 24.3


def test_noise_overstated_names_the_factor_whose_sigma_is_too_large_by_its_variance_factor(ds, out, capsys):
    """At de523fd the entry of largest cost share was named: prior:cam/vo_scale."""
    config = ds / "config.yaml"
    w = warned(capsys, run(config, out, "--set", "factors.0.sigma.rotation=0.2",
                           "--set", "factors.0.sigma.translation=0.16"), out, "noise_overstated")
    named = w["message"].split("chi-square per redundancy by entry")[1]
    assert named.split(": ", 1)[1].startswith("factors[0]:pose.scaled_relative ")
    factor = float(named.split("factors[0]:pose.scaled_relative ")[1].split(" ")[0])
    assert factor < 1e-2  # measured: 4.9e-4 (sigmas 45x too large; 100x for the rotation)
    assert "prior:cam/vo_scale" not in named


# ---------------------------------------------------------------- 10. an outlier burst without a robust kernel


def test_gyro_outlier_burst_is_warning_local_misfit_naming_its_second(wheels_6s, tmp_path, out, capsys):
    """Half a second of gyro readings off by 0.5 rad/s (1-sigma; the gyro factor has no robust loss)."""
    config = copy_of(wheels_6s, tmp_path)

    def burst(c):
        inside = (c["t"] >= 3.0) & (c["t"] < 3.5)
        c["gyro"][inside] += 0.5 * np.random.default_rng(0).normal(size=int(inside.sum()))
    edit_csv(config.parent / "data" / "wheels.csv", burst)
    w = warned(capsys, run(config, out), out, "local_misfit")
    assert (w["t_start"], w["t_end"]) == (3.0, 4.0)
    assert w["message"].startswith("the data in 1 of 6 windows of 1 s fit far worse than in the others: chi-square "
                                   "per degree of freedom up to ")
    assert "(t = 3.00 .. 4.00 s) against a median of " in w["message"]
    assert ratio_in(w["message"]) > 10  # measured: 22.1
    assert report(out)["status"] == "accepted"


# ---------------------------------------------------------------- 11. incremental solves that lose track


def test_scaled_vo_at_10_hz_in_a_fixed_lag_smoother_is_exit_2_the_solver_diverged(tmp_path, capsys):
    out = tmp_path / "out"
    message = fails(capsys, run(SCALED_VO, out, "--set", "sources.0.params.rate=10", "--set",
                                "sources.0.params.duration=10", "--set", "solver.type=fixed_lag"), out=out)
    assert message.startswith(f"{SCALED_VO}: the solver diverged: cost rose from ")
    initial, final = map(float, message.split("cost rose from ")[1].split(" to "))
    assert final > 10 * initial  # measured: 96.9 -> 17227.5


def test_fixed_lag_on_the_faulty_wheels_run_is_exit_2_naming_when_it_went_astray(wheels_faulty, out, capsys):
    """The wheels tutorial's fixed-lag run with new states at their dead-reckoning values."""
    config = wheels_faulty / "config.yaml"
    message = fails(capsys, run(config, out, "--set", "solver.type=fixed_lag"), out=out)
    assert message.startswith(f"{config}: the incremental solve diverged: GTSAM found the linear system indeterminate "
                              "while adding the measurements at t=")
    assert ", after the estimates had gone astray from t = 2.50 s (robot/pose[49] revised by " in message
    assert message.endswith("not a missing constraint: try solver.new_states: carried, solver.warmup, a longer "
                            "solver.lag, solver.updates_per_step: 2, or the batch solver")


@pytest.mark.slow
def test_fixed_lag_with_carried_states_on_the_faulty_wheels_run_is_rejected_with_incremental_fit(wheels_faulty, out,
                                                                                                 capsys):
    """As the wheels tutorial says: rejected, lost track after the stuck wheel (10-20 s). Before d5a7bf9: exit 0
    (the chi-square gate is off for fixed_lag) at chi2/dof 4.5e4."""
    config = wheels_faulty / "config.yaml"
    message = rejected(capsys, run(config, out, "--set", "solver.type=fixed_lag", "--set",
                                   "solver.new_states=carried"), out)
    assert message.startswith(f"{config}: the incremental run failed its health check: the estimate fits the data "
                              "in 5 of 10 windows of 2 s far worse than the best fit of the same data does")
    w = [w for w in report(out)["warnings"] if w["name"] == "incremental_fit"]
    assert len(w) == 1 and (w[0]["t_start"], w[0]["t_end"]) == (10.0, 20.0)
    assert "at t = 10.00 .. 20.00 s: the solver lost track there" in w[0]["message"]
    assert "try solver.warmup, a longer solver.lag" in w[0]["message"]  # carried is already set: not suggested


# ---------------------------------------------------------------- 12. a calibration unobservable within the lag


def test_vo_scale_unobservable_within_the_lag_is_rejected_with_incremental_fit(ds, out, capsys):
    """Mocap every 2 s and a 2-s lag: the scale is seen only while two mocap samples share the window, and is held
    at that linearization point once they leave it (solver.relinearize_marginal_variables: false, the default since
    d5a7bf9); the last window fits far worse than the best fit. The rejection is right: the scale is far off the
    truth. (With relinearize_marginal_variables: true, the behaviour before d5a7bf9, the run fits: exit 0,
    chi2/dof 4.6, scale 2.45 +- 0.06.)"""
    config = ds / "config.yaml"
    message = rejected(capsys, run(config, out, "--set", "solver.type=fixed_lag"), out)
    assert message.startswith(f"{config}: the incremental run failed its health check: the estimate fits the data "
                              "in 1 of 2 windows of 2 s far worse than the best fit of the same data does: chi-square "
                              "per degree of freedom up to ")
    assert "(t = 4.00 .. 6.00 s; " in message
    w = [w for w in report(out)["warnings"] if w["name"] == "incremental_fit"]
    assert len(w) == 1 and (w[0]["t_start"], w[0]["t_end"]) == (4.0, 6.0)
    scale = report(out)["parameters"]["cam"]["vo_scale"]
    truth = yaml.safe_load((ds / "truth" / "calibration.yaml").read_text())["robots"]["cam"]["vo_scale"]["value"]
    assert abs(scale["value"] - truth) > 5 * scale["sigma"]  # measured: 2.156 ± 0.026 against 2.5


# ---------------------------------------------------------------- 13. duplicated timestamps


def test_duplicated_vo_row_is_exit_2_naming_the_stream_and_the_stamp(ds, out, capsys):
    config, vo = ds / "config.yaml", ds / "data" / "vo.tum"
    lines = vo.read_text().splitlines()
    i = next(n for n, line in enumerate(lines) if line.startswith("5.000000000 "))
    vo.write_text("\n".join(lines[:i + 1] + lines[i:]) + "\n")
    assert fails(capsys, run(config, out), out=out) == (
        f"{config}:{line_of(config, 'stream: vo')}: robots.cam.states.stream: stream 'vo' ({vo}) stamps 1 sample(s) "
        "like the one before (first at t = 5.000000 s); one state per sample needs strictly increasing stamps: clock "
        "the states by another stream or by `rate:`")


# ---------------------------------------------------------------- 14-15. a wrong unit


def test_mocap_in_centimetres_is_rejected_naming_the_vo_scale_prior_first(ds, out, capsys):
    """Positions 100x too large: the VO scale follows them (to about 220) against its prior 1 ± 10."""
    config = ds / "config.yaml"
    edit_tum(ds / "data" / "mocap.tum", lambda r: [r[0], *[100 * v for v in r[1:4]], *r[4:]])
    message = rejected(capsys, run(config, out), out)
    assert message.startswith(f"{config}: the solver stopped with a large residual: chi-square per degree of freedom ")
    assert ratio_in(message) > 10  # measured: 43
    assert "largest contributions: prior:cam/vo_scale (" in message
    assert report(out)["parameters"]["cam"]["vo_scale"]["value"] > 50


def test_gyro_in_degrees_per_second_is_warning_ill_conditioned_with_covariances_from_qr(wheels_10s, tmp_path, out,
                                                                                     capsys):
    """The gyro scale absorbs the unit (0.0219 = 1.25 * pi / 180); Cholesky finds the system at that estimate
    indeterminate. At de523fd: exit 3 (internal error) in the covariances after the solve."""
    config = copy_of(wheels_10s, tmp_path)
    edit_csv(config.parent / "data" / "wheels.csv", lambda c: c.update(gyro=np.degrees(c["gyro"])))
    w = warned(capsys, run(config, out), out, "ill_conditioned")
    assert w["message"].startswith("at the estimate: GTSAM's Cholesky declared the system indeterminate, but the "
                                   "whitened Jacobian has full rank: ill-conditioned, not unconstrained")
    assert "the covariances at the estimate come from QR instead" in w["message"]
    scale = report(out)["parameters"]["robot"]["gyro_scale"]
    assert scale["value"] == pytest.approx(1.25 * np.pi / 180, rel=0.05) and 0 < scale["sigma"] < 1e-3
