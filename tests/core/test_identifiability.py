"""The identifiability report (solve/identifiability.py): the parameters' joint covariance against the per-variable
marginals, and what it says of a wheeled robot on a square path whose fast turns slide (issue 32): a slip absorbed
into the gyro scale at chi2/dof 1, found without truth because the gyro scale rests on the axle-length prior."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fusionkit.config.loader import load_config
from fusionkit.api import parameter_indices
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config

REPO = Path(__file__).resolve().parents[2]
SQUARE = {"path": "square", "duration": 40.0}


@pytest.fixture(scope="module")
def square_runs():
    """The same square path, clean and with the fast turns sliding by 20 % (seed 1)."""
    out = {}
    for name, slip in (("clean", 0.0), ("sliding", 0.2)):
        with simulated_config("wheels.sim", {**SQUARE, "faults": {"slide": {"slip": slip}}}, seed=1) as config:
            out[name] = estimate(config)
    return out


def _index(report, name):
    return report.names.index(name)


@pytest.mark.slow
def test_joint_covariance_diagonal_and_blocks_match_the_marginals(square_runs):
    """The Schur complement on the parameters inverted = the top-down marginals, to rounding."""
    run = square_runs["sliding"]
    report = run.identifiability
    for name in report.names:
        robot, param = name.split("/")
        marginal = run.parameters[robot][param].sigma[0, 0]
        assert report.sigma[_index(report, name)] == pytest.approx(marginal, rel=1e-6), name
    assert np.allclose(report.correlation, report.correlation.T) and np.allclose(np.diag(report.correlation), 1)


@pytest.mark.slow
def test_the_sliding_square_says_the_gyro_scale_rests_on_the_axle_prior_and_how_to_separate_them(square_runs):
    """The slip moved the gyro scale (truth 1.25) by many sigma at chi2/dof about 1; the report, without truth:
    the axle length is its prior's, the gyro scale moves with that prior, and the wheels say what separates them."""
    run = square_runs["sliding"]
    scale = run.parameters["robot"]["gyro_scale"]
    assert abs(scale.values[0] - 1.25) > 10 * scale.sigma[0, 0]  # measured: 15 sigma off
    assert run.solution.chi2_per_dof < 1.2
    report = run.identifiability
    axle, gyro = _index(report, "robot/axle_length"), _index(report, "robot/gyro_scale")
    assert axle in report.prior_decides
    (moved,) = [m for i, j, m in report.rests_on if (i, j) == (gyro, axle)]
    assert abs(moved) > 0.5  # measured: 0.90 of its sigma per sigma of the axle prior
    (group,) = [d for d in report.directions if axle in d.members and gyro in d.members]
    assert any("turn both ways at several turn rates" in h for h in group.hints)
    printed = "\n".join(report.lines())
    assert "rests on the prior of robot/axle_length: robot/gyro_scale" in printed


@pytest.mark.slow
def test_the_clean_square_reports_the_same_relation(square_runs):
    """Not a false alarm: the recording cannot tell them apart whether or not it slid."""
    report = square_runs["clean"].identifiability
    axle, gyro = _index(report, "robot/axle_length"), _index(report, "robot/gyro_scale")
    assert axle in report.prior_decides and any((i, j) == (gyro, axle) for i, j, _ in report.rests_on)


@pytest.mark.slow
def test_a_camera_separates_them_and_the_report_says_nothing_of_the_pair():
    """With pose.absolute on the camera the axle and gyro scale are calibrated: no prior decides either."""
    def edit(config):
        config["factors"].append({"type": "pose.absolute", "robot": "robot", "stream": "camera",
                                  "sigma": {"rotation": 0.02, "translation": 0.0028}})
    with simulated_config("wheels.sim", {**SQUARE, "faults": {"slide": {"slip": 0.2}}}, seed=1, edit=edit) as config:
        report = estimate(config).identifiability
    axle, gyro = _index(report, "robot/axle_length"), _index(report, "robot/gyro_scale")
    assert axle not in report.prior_decides and gyro not in report.prior_decides
    assert not [d for d in report.directions if axle in d.members and gyro in d.members]


def test_one_well_determined_parameter_gives_an_empty_report(ds):
    report = estimate(load_config(ds / "config.yaml", ["output.plots=false"])).identifiability
    assert report.names == ["cam/vo_scale"] and report.lines() == []


@pytest.mark.slow
def test_cable_pulleys_and_offsets_are_grouped_with_the_cable_plugins_hint():
    """configs/cable_mocap_lengths.yaml: each pulley trades off against its cable's offset along the cable
    (|rho| up to 0.99); the cable factor says what separates them."""
    report = estimate(load_config(REPO / "configs" / "cable_mocap_lengths.yaml", ["output.plots=false"])).identifiability
    assert len(report.directions) == 4
    for i, d in enumerate(report.directions):
        assert {report.names[m].split(".")[0] for m in d.members} == {f"cdpr/pulley[{i}]", f"cdpr/offset[{i}]"}
        assert any("poses over a larger volume" in h for h in d.hints)


@pytest.mark.slow
def test_the_cable_quickstart_reports_nothing():
    """No false alarm where the data determine every parameter (issue 32)."""
    report = estimate(load_config(REPO / "configs" / "quickstart.yaml", ["output.plots=false"])).identifiability
    assert len(report.names) == 17 and report.lines() == []


def test_parameter_indices_reads_the_elements_a_group_names():
    names = ["cdpr/pulley[0]", "cdpr/offset[0]", "cdpr/pulley[12]", "other/pulley[1]", "cdpr/pulley_radius"]
    assert parameter_indices(names, "cdpr", "pulley") == {0, 12}
    assert parameter_indices(names, "cdpr", "offset") == {0}
    assert parameter_indices(names, "cdpr", "pulley_radius") == set()


def test_a_serial_arms_placement_components_are_named_by_its_descriptions_axes_and_its_analysis_joins_the_report():
    """RobotModel.axis_names: `placement[elbow_joint].tz`, not `.c2`; held axes are left out (arm_calibration holds
    tx, ty, ry of that joint). The arm's own kinematic identifiability (which axes it holds) is part of the same
    report: first in its console section (8 sentences, then how many more), in report.json `analyses`."""
    from fusionkit.report.outputs import report_document
    from fusionkit.report.summary import summary_text
    result = estimate(load_config(REPO / "configs" / "arm_calibration.yaml", ["output.plots=false"]))
    report = result.identifiability
    elbow = [n for n in report.names if n.startswith("arm/placement[elbow_joint].")]
    assert elbow == ["arm/placement[elbow_joint].tz", "arm/placement[elbow_joint].rx", "arm/placement[elbow_joint].rz"]
    assert not any(n.endswith((".c0", ".c1", ".c2")) for n in report.names)
    label = "arm: kinematic identifiability"
    verdict = result.problem.diagnostics[label]["verdict"]
    assert report_document(result)["identifiability"]["analyses"] == {label: verdict} and len(verdict) == 25
    text = summary_text(result).splitlines()
    section = text[text.index("  identifiability (what the data determine; report.json identifiability):") + 1:]
    assert section[0] == f"    {label}: {verdict[0]}"
    assert section[8] == f"    {label}: ... and 17 more (report.json diagnostics)"
    assert not any(line.startswith(f"  {label}:") for line in text)  # not again among the other diagnostics


def test_validate_reports_what_the_recording_can_tell_before_solving(tmp_path, capsys):
    """`fusionkit validate` on a square run: the same relation at the initial values, before any solve."""
    from fusionkit.cli.main import main
    folder = tmp_path / "square"
    assert main(["simulate", "wheels.sim", "--out", str(folder), "--seed", "1", "-q", "--set", "path=square",
                 "--set", "duration=20"]) == 0
    capsys.readouterr()
    assert main(["validate", str(folder / "config.yaml")]) == 0
    lines = capsys.readouterr().out.splitlines()
    start = lines.index("  identifiability at the initial values (what this recording can tell; `run` reports it at "
                        "the estimate):")
    section = "\n".join(lines[start + 1:])
    assert "rests on the prior of robot/axle_length: robot/gyro_scale" in section
    assert "to separate axle length and gyro scale: turn both ways" in section


@pytest.mark.parametrize("sets", [[], ["factors.1.sigma.rotation=0.5", "factors.1.sigma.translation=0.5"]])
def test_with_held_axes_the_report_sigmas_are_the_marginals(sets):
    """arm_calibration holds 22 axes at 1e-9 (about 1e18 of information): they are dropped before inverting, so
    the other components' sigmas equal the solver's marginals even where the data are weak (a loose marker)."""
    from fusionkit.solve.identifiability import parameter_keys
    run = estimate(load_config(REPO / "configs" / "arm_calibration.yaml", ["output.plots=false", *sets]))
    report, problem = run.identifiability, run.problem
    expected = []
    for key in parameter_keys(problem):
        held = problem.held[key].axes if key in problem.held else ()
        sigma = np.sqrt(np.diag(run.solution.covariances[key]))
        expected += [s for axis, s in enumerate(sigma) if axis not in held]
    assert report.sigma == pytest.approx(np.array(expected), rel=1e-4)
