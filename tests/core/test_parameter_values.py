"""Robot-description parameters held fixed (`fixed: true`) or given no value (an initializer
supplies it): solved, reported and round-tripped through calibration.yaml; contradictions and a
value nobody supplies are one located line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from fusionkit.cli.main import main
from fusionkit.simulate import write_dataset

FAST = ["--no-plots", "-q"]


@pytest.fixture(scope="module")
def project(tmp_path_factory) -> Path:
    """A scaled-VO dataset (true scale 2.5) with descriptions: scale fixed at the truth, scale without value."""
    folder = tmp_path_factory.mktemp("params") / "sim"
    write_dataset("pose.scaled_vo", folder, ["duration=5"], seed=3)
    text = (folder / "robots" / "cam.yaml").read_text()
    assert "    value: 1.0\n    sigma: 10.0\n" in text
    (folder / "robots" / "fixed.yaml").write_text(text.replace("    value: 1.0\n    sigma: 10.0\n",
                                                               "    value: 2.5\n    fixed: true\n"))
    (folder / "robots" / "novalue.yaml").write_text(text.replace("    value: 1.0\n    sigma: 10.0\n", ""))
    return folder


def run(project: Path, out: Path, *extra: str) -> int:
    return main(["run", str(project / "config.yaml"), "--out", str(out), *FAST, *extra])


def test_fixed_parameter_keeps_its_value_has_no_sigma_and_reloads(project, tmp_path, capsys):
    out = tmp_path / "fixed"
    assert run(project, out, "--set", "robots.cam.description=robots/fixed.yaml") == 0
    report = json.loads((out / "report.json").read_text())
    scale = report["parameters"]["cam"]["vo_scale"]
    assert scale["value"] == pytest.approx(2.5, abs=1e-9) and scale["fixed"] is True and "sigma" not in scale
    assert report["evaluation"]["trajectories"]["cam"]["ate_rmse_m"] < 0.05
    entry = yaml.safe_load((out / "calibration.yaml").read_text())["robots"]["cam"]["vo_scale"]
    assert entry == {"type": "scalar", "value": pytest.approx(2.5, abs=1e-9), "fixed": True}
    # calibration.yaml as an override: the scale stays fixed in the next run
    again = tmp_path / "again"
    assert run(project, again, "--set", f"robots.cam.overrides={out / 'calibration.yaml'}") == 0
    assert json.loads((again / "report.json").read_text())["parameters"]["cam"]["vo_scale"]["fixed"] is True


def test_parameter_without_value_is_set_by_the_initializer_named_by_validate(project, tmp_path, capsys):
    assert main(["validate", str(project / "config.yaml"), "--set", "robots.cam.description=robots/novalue.yaml"]) == 0
    assert ("  cam/vo_scale: no value in the description; initial value from initializers[0]:pose.scale_from_absolute"
            in capsys.readouterr().out)
    out = tmp_path / "novalue"
    assert run(project, out, "--set", "robots.cam.description=robots/novalue.yaml") == 0
    scale = json.loads((out / "report.json").read_text())["parameters"]["cam"]["vo_scale"]
    assert abs(scale["value"] - 2.5) < 3 * scale["sigma"] + 0.01  # no prior at all: the data alone


def test_parameter_without_value_and_no_initializer_is_one_located_line(project, tmp_path, capsys):
    assert run(project, tmp_path / "o", "--set", "robots.cam.description=robots/novalue.yaml",
               "--set", "initializers=[]") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{project / 'robots' / 'novalue.yaml'}:" in err
    assert ("parameters.vo_scale: robot 'cam': parameter vo_scale has no value and no initializer set cam/vo_scale; "
            "give `value:`/`values:` in the description, or add an initializer that estimates it") in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("entry, needle", [
    ("{type: scalar, value: 1.0, sigma: 0}", "parameters.p.sigma: sigmas must be positive and finite (to hold a "
                                            "parameter at its value, write `fixed: true` instead of a sigma)"),
    ("{type: scalar, value: 1.0, sigma: 0.1, fixed: true}", "parameters.p.sigma: a fixed parameter is held at its "
                                                            "value: it has no sigma"),
    ("{type: scalar, fixed: true}", "parameters.p.fixed: `fixed` needs the parameter's value"),
    ("{type: scalar, sigma: 0.1}", "parameters.p.sigma: `sigma` needs the parameter's value"),
    ("{type: scalar, count: 2, values: [1, 2]}", "parameters.p.count: give one of value, values or count (not "
                                                 "values and count)"),
])
def test_contradictory_parameter_entries_are_refused(project, tmp_path, capsys, entry, needle):
    assert main(["validate", str(project / "config.yaml"), "--set",
                 f"robots.cam.description={{name: c, parameters: {{vo_scale: {{type: scalar, value: 1, sigma: 9}}, "
                 f"p: {entry}}}}}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
