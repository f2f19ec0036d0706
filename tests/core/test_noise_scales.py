"""`noise_scale:` on a factor entry: a number multiplies its sigmas; `estimate` finds the multiplier from the
data by variance components (fusionkit/solve/noise_scales.py)."""

from __future__ import annotations

from pathlib import Path

import gtsam
import pytest
import yaml

import fusionkit
from fusionkit.api import FactorType, gaussian, hookimpl
from fusionkit.errors import ConfigError, DataError, PluginError
from fusionkit.testing import FactorExample
from fusionkit.simulate import write_dataset
from fusionkit.solve.noise_scales import entry_fits

BOTH = ["factors.0.noise_scale=estimate", "factors.1.noise_scale=estimate"]
VO_STATED_3X = ["factors.0.sigma.rotation=0.006", "factors.0.sigma.translation=0.0048"]  # simulated: 0.002, 0.0016


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """20 s of pose.scaled_vo (VO at 30 Hz, motion capture every 2 s), its config stating the simulator's noise."""
    folder = tmp_path_factory.mktemp("noise_scales") / "ds"
    write_dataset("pose.scaled_vo", folder, ["duration=20"], seed=1)
    return folder / "config.yaml"


@pytest.fixture(scope="module")
def plain(dataset):
    """The dataset's run as configured."""
    return fusionkit.run(dataset)


@pytest.fixture(scope="module")
def estimated(dataset):
    """The dataset's run with both entries' noise scales estimated."""
    return fusionkit.run(dataset, BOTH)


def _scales(result) -> dict[str, dict]:
    return {label.split(":")[1]: fit for label, fit in result.solution.noise_scales.items()}


def test_redundancies_of_all_factors_add_up_to_rows_minus_unknowns(plain):
    result = plain
    problem, values = result.problem, result.solution.values
    fits = entry_fits(problem, values, {r.label for r in problem.records})
    unknowns = sum(values.zeroVectors().at(k).shape[0] for k in values.keys())
    rows = sum(f.rows for f in fits.values())
    assert rows == sum(r.factor.dim() for r in problem.records)
    assert sum(f.redundancy for f in fits.values()) == pytest.approx(rows - unknowns, abs=1e-6)
    assert all(0 < f.redundancy < f.rows for f in fits.values())
    # each entry's chi-square is what the solution's cost holds of it
    assert sum(f.chi2 for f in fits.values()) == pytest.approx(2 * result.solution.final_error, rel=1e-9)


def test_noise_as_simulated_gets_scales_within_3_sigma_of_1_and_chi2_per_dof_1(estimated):
    """A self-consistency check: the data were simulated with the noise the config states."""
    result = estimated
    for name, fit in _scales(result).items():
        assert abs(fit["scale"] - 1.0) < 3 * fit["sigma"], (name, fit)  # measured: 0.93 +- 0.12, 1.40 +- 0.21
        assert fit["rounds"] <= 10
    assert result.solution.chi2_per_dof == pytest.approx(1.0, abs=0.05)


@pytest.mark.slow
def test_vo_sigmas_stated_3x_too_large_are_scaled_to_a_third_of_the_right_statement(dataset, estimated):
    """Mis-specified noise: the estimate does not depend on how wrong the statement was -- the estimated
    sigmas (stated times scale) are those estimated from the right statement, to 3 %."""
    right = _scales(estimated)
    wrong_result = fusionkit.run(dataset, BOTH + VO_STATED_3X)
    wrong = _scales(wrong_result)
    assert 3 * wrong["pose.scaled_relative"]["scale"] == pytest.approx(right["pose.scaled_relative"]["scale"], rel=0.03)
    assert wrong["pose.absolute"]["scale"] == pytest.approx(right["pose.absolute"]["scale"], rel=0.03)
    assert 1 < wrong["pose.absolute"]["rounds"] <= 20
    # without the estimate the stated noise is three times too large: chi2/dof far below 1
    assert fusionkit.run(dataset, VO_STATED_3X).solution.chi2_per_dof < 0.3
    assert wrong_result.solution.chi2_per_dof == pytest.approx(1.0, abs=0.05)


def test_a_number_multiplies_the_entrys_sigmas(dataset, plain):
    """noise_scale: 3 on sigmas a third of the stated ones is the stated noise: same estimate and cost."""
    scaled = fusionkit.run(dataset, ["factors.0.sigma.rotation=0.0006666666666666666",
                                     "factors.0.sigma.translation=0.0005333333333333333", "factors.0.noise_scale=3"])
    assert scaled.solution.final_error == pytest.approx(plain.solution.final_error, rel=1e-6)
    assert scaled.parameters["cam"]["vo_scale"].values[0] == pytest.approx(
        plain.parameters["cam"]["vo_scale"].values[0], rel=1e-9)


@pytest.mark.parametrize("override, expected", [
    (["solver.type=isam2"], "noise_scale: `estimate` needs solver.type batch (got isam2)"),
    (["factors.0.robust={kernel: huber}"], "noise_scale: `estimate` needs Gaussian noise"),
])
def test_estimate_outside_a_gaussian_batch_solve_is_refused_at_its_key(dataset, override, expected):
    with pytest.raises(ConfigError, match=r"factors\[0\]\.noise_scale|factors\.0\.noise_scale") as info:
        fusionkit.load_config(dataset, ["factors.0.noise_scale=estimate", *override])
    assert expected in str(info.value)


def test_a_non_positive_scale_is_refused(dataset):
    with pytest.raises(ConfigError, match="noise_scale"):
        fusionkit.load_config(dataset, ["factors.0.noise_scale=0"])


class OwnNoisePrior(FactorType):
    """A prior on a robot's first state whose noise the plugin builds itself, not through ctx.noise."""

    name = "test.own_noise_prior"
    robot_fields = ("robot",)
    schema = {"type": "object", "properties": {"robot": {"type": "string"}}, "required": ["robot"],
              "additionalProperties": False}

    def build(self, ctx, spec) -> None:
        key = ctx.state_keys(spec["robot"], [0])[0]
        ctx.add(gtsam.PriorFactorPose3(key, gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1.0)), spec)

    @classmethod
    def example(cls, rng):
        values = gtsam.Values()
        values.insert(0, gtsam.Pose3())
        return FactorExample(gtsam.PriorFactorPose3(0, gtsam.Pose3(), gaussian([1.0] * 6)), values)


class OwnNoisePlugin:
    @hookimpl
    def register_factor_types(self):
        return [OwnNoisePrior]


def test_a_factor_whose_noise_ctx_noise_did_not_make_refuses_a_scale(dataset, use_plugins, tmp_path):
    use_plugins(OwnNoisePlugin())
    config = yaml.safe_load(dataset.read_text())
    config["factors"].append({"type": "test.own_noise_prior", "robot": "cam", "noise_scale": 2})
    for source in config["sources"]:
        source["path"] = str(dataset.parent / source["path"])
    config["robots"]["cam"]["description"] = str(dataset.parent / config["robots"]["cam"]["description"])
    config.pop("truth")
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(config))
    with pytest.raises(PluginError, match=r"test.own_noise_prior was given `noise_scale:` but built a factor whose "
                                          r"noise ctx.noise did not make"):
        fusionkit.run(path)


def test_a_factor_type_whose_noise_comes_from_its_model_refuses_a_scale_at_load():
    config = Path(__file__).resolve().parents[2] / "configs" / "uwb_drone_imu.yaml"
    with pytest.raises(ConfigError, match=r"factors\[1\]\.noise_scale: factor type imu.preintegrated takes no noise "
                                          r"scale \(its noise comes from its model\)"):
        fusionkit.load_config(config, ["factors.1.noise_scale=2"])


def test_the_summary_and_the_html_report_name_each_estimated_scale_with_its_sigma_and_redundancy(estimated):
    from fusionkit.report.html import report_html
    from fusionkit.report.summary import summary_text
    result = estimated
    text = summary_text(result)
    assert "  noise scale of factors[1]:pose.absolute: 1.4" in text
    assert "(estimated; redundancy 23.3 of 60 rows" in text  # measured: 1.403 ± 0.21, 8 rounds
    assert "<td>noise scale of factors[1]:pose.absolute</td><td>1.403 ± 0.21 (estimated; redundancy 23.3" in \
        report_html(result, None)


def test_noise_scale_cannot_be_changed_by_solver_refine(dataset):
    with pytest.raises(ConfigError, match=r"solver\.refine\.vo\.noise_scale: refine changes settings, not the "
                                          r"entry's noise_scale"):
        fusionkit.load_config(dataset, ["factors.0.label=vo", "solver.refine={vo: {noise_scale: estimate}}"])


def test_the_run_keeps_the_initializers_values_as_its_initial_ones(plain, estimated):
    """The rounds start from each other's estimates; the problem reported keeps the initializers' values."""
    before, after = _poses(plain.problem.initial), _poses(estimated.problem.initial)
    assert len(before) == 600 and before.keys() == after.keys()
    assert all(before[k].equals(after[k], 1e-12) for k in before)


def _poses(values) -> dict:
    return {k: values.atPose3(k) for k in values.keys() if values.exists(k) and _is_pose3(values, k)}


def _is_pose3(values, key) -> bool:
    try:
        values.atPose3(key)
        return True
    except RuntimeError:
        return False


def test_an_entry_the_estimate_absorbs_entirely_has_no_scale_to_estimate(dataset, tmp_path):
    """A parameter held fixed by its prior: the prior's one row has redundancy 0 (measured 1e-12 or less)."""
    import shutil
    folder = tmp_path / "ds"
    shutil.copytree(dataset.parent, folder)
    description = folder / "robots" / "cam.yaml"
    robot = yaml.safe_load(description.read_text())
    robot["parameters"]["vo_scale"] = {"type": "scalar", "value": 2.5, "fixed": True}
    description.write_text(yaml.safe_dump(robot))
    result = fusionkit.run(folder / "config.yaml")
    with pytest.raises(DataError, match=r"fixed:cam/vo_scale: noise_scale: estimate: the entry's factors have "
                                        r"redundancy .* in 1 rows .*give noise_scale a number"):
        entry_fits(result.problem, result.solution.values, {"fixed:cam/vo_scale"})
