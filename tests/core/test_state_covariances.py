"""`output: {state_covariances: true}` writes covariances/<robot>.csv (also without truth) holding GTSAM's
marginals; off, no state marginal is computed without truth. With truth, plots/error_vs_time_<robot>.png."""

from __future__ import annotations

import shutil
from pathlib import Path

import gtsam
import numpy as np
import pytest
import yaml

import fusionkit
from fusionkit.cli.main import main
from fusionkit.data.files import read_csv_stream
from fusionkit.errors import ConfigError
from fusionkit.graph.keys import STATE
from fusionkit.report.outputs import write_outputs
from fusionkit.simulate import write_dataset

POSE3_COLUMNS = ("sx", "sy", "sz", "cov_rx_rx", "cov_rx_ry", "cov_rx_rz", "cov_rx_tx", "cov_rx_ty", "cov_rx_tz",
                 "cov_ry_ry", "cov_ry_rz", "cov_ry_tx", "cov_ry_ty", "cov_ry_tz", "cov_rz_rz", "cov_rz_tx",
                 "cov_rz_ty", "cov_rz_tz", "cov_tx_tx", "cov_tx_ty", "cov_tx_tz", "cov_ty_ty", "cov_ty_tz",
                 "cov_tz_tz")


@pytest.fixture(scope="module")
def simulated(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("covariances") / "ds"
    write_dataset("pose.scaled_vo", folder, ["duration=3"], seed=2)
    return folder


def without_truth(simulated: Path, tmp_path: Path, output: dict | None) -> Path:
    """A copy of the dataset whose config has no truth (real data) and the given `output:` block."""
    folder = tmp_path / "ds"
    shutil.copytree(simulated, folder)
    config = yaml.safe_load((folder / "config.yaml").read_text())
    del config["truth"]
    if output is not None:
        config["output"] = output
    (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return folder / "config.yaml"


def test_covariance_file_holds_the_marginals_of_every_state_without_truth(simulated, tmp_path):
    result = fusionkit.run(without_truth(simulated, tmp_path, {"state_covariances": True}))
    out = tmp_path / "out"
    out.mkdir()
    write_outputs(result, out, plots=False)
    table = read_csv_stream(out / "covariances" / "cam.csv", "cov")
    assert table.columns == POSE3_COLUMNS
    states = result.problem.states["cam"]
    np.testing.assert_array_equal(table.t, states.t)  # every state, at its time
    marginals = gtsam.Marginals(result.problem.graph(), result.solution.values)  # computed here, independently
    upper = np.triu_indices(6)
    for k in (0, len(states) // 2, len(states) - 1):
        cov = marginals.marginalCovariance(states.key(k))
        np.testing.assert_allclose(table.values[k, 3:], cov[upper], rtol=1e-6, atol=1e-15)
        rot = result.solution.values.atPose3(states.key(k)).rotation().matrix()
        world = rot @ cov[3:, 3:] @ rot.T  # the position block along the world axes
        np.testing.assert_allclose(table.values[k, :3], np.sqrt(np.diag(world)), rtol=1e-6)


def test_without_the_key_no_state_marginal_is_computed_and_no_file_written(simulated, tmp_path):
    result = fusionkit.run(without_truth(simulated, tmp_path, None))
    kinds = {result.problem.keys.decode(k)[0].kind for k in result.solution.covariances}
    assert STATE not in kinds and result.solution.covariances  # the parameter (vo_scale) still has its sigma
    out = tmp_path / "out"
    out.mkdir()
    write_outputs(result, out, plots=False)
    assert not (out / "covariances").exists()


def test_state_covariances_must_be_true_or_false(simulated, tmp_path):
    config = without_truth(simulated, tmp_path, {"state_covariances": "yes"})
    line = next(n for n, s in enumerate(config.read_text().splitlines(), start=1) if "state_covariances" in s)
    with pytest.raises(ConfigError) as err:
        fusionkit.load_config(config)
    assert str(err.value) == f"{config}:{line}: output.state_covariances: got 'yes'; expected true or false"


@pytest.mark.slow
def test_error_vs_time_plot_is_written_when_truth_exists_and_not_without(simulated, tmp_path, capsys):
    out = tmp_path / "with_truth"
    assert main(["run", str(simulated / "config.yaml"), "--out", str(out)]) == 0
    png = out / "plots" / "error_vs_time_cam.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["run", str(without_truth(simulated, tmp_path, None)), "--out", str(tmp_path / "no_truth")]) == 0
    assert sorted(p.name for p in (tmp_path / "no_truth" / "plots").iterdir()) == ["residuals.png", "scene_3d.png", "trajectory.png"]
