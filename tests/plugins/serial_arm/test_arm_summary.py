"""What the console says of a serial arm's calibration: a parameter the identifiability analysis holds prints
`held (not identifiable with ...)`, not its value with the hold's 1e-9 sigma; the elements of the joint groups
are named by joint (`joint_offsets[shoulder_pan_joint]`) alike in validate, the run's summary, report.html and
calibration.yaml, which loads back (and refuses a reordered `elements`); a drifting offset is summed up."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest
import yaml

import fusionkit
from fusionkit.cli.main import main
from fusionkit.errors import ConfigError
from fusionkit.pipeline import estimate
from fusionkit.report.summary import summary_text
from fusionkit.simulate import simulated_config

REPO = Path(__file__).resolve().parents[3]
CONFIG = REPO / "configs" / "arm_calibration.yaml"
JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """`fusionkit validate` and `fusionkit run` of configs/arm_calibration.yaml: (validate's output, the run's
    output, the output folder)."""
    out = tmp_path_factory.mktemp("arm") / "out"
    printed = []  # (capsys is function-scoped: stdout redirected by hand)
    for argv in (["validate", str(CONFIG)], ["run", str(CONFIG), "--out", str(out), "--no-plots"]):
        with contextlib.redirect_stdout(io.StringIO()) as text:
            assert main(argv) == 0
        printed.append(text.getvalue())
    return printed[0], printed[1], out


def test_a_held_parameter_prints_held_and_why_not_its_value_and_the_holds_sigma(run):
    _, printed, _ = run
    lines = printed.splitlines()
    # the first joint's offset turns as the base turns about z; the last one's as the marker does
    assert any(x.startswith("  arm/joint_offsets[shoulder_pan_joint] = held (not identifiable with base.rz) at 0 rad")
               for x in lines)
    assert any(x.startswith("  arm/joint_offsets[wrist_3_joint] = held (not identifiable with marker.rz") for x in lines)
    # the first joint's placement moves with the base on all six axes
    assert any(x.startswith("  arm/placement[shoulder_pan_joint] = held (not identifiable with base.tx, base.ty, "
                            "base.tz, base.rx and 2 more) at [0, 0, 0, 0, 0, 0]") for x in lines)
    # partly held: the estimated axes keep value and sigma, the held ones read `held`, named after the values
    partly = next(x for x in lines if x.startswith("  arm/placement[shoulder_lift_joint] = "))
    assert "± [held, " in partly and "; tx, rx, ry held (not identifiable with base.tz, base.rz" in partly
    # estimated elements keep value ± sigma and the description's unit
    assert any(x.startswith("  arm/joint_offsets[elbow_joint] = 0.0022") and " ± 3.4e-05 rad   (error vs truth" in x
               for x in lines)
    # no hold sigma (1e-9) and no held value's rounding noise (1e-17) anywhere before the errors against truth
    assert not [x for x in lines if re.search(r"e-(09|1\d)\b", x.split("   (error vs truth")[0])]


def test_elements_are_named_by_joint_in_validate_the_summary_report_html_and_calibration_yaml(run):
    validated, printed, out = run
    assert "  held:arm/joint_offsets[shoulder_pan_joint]: 1 factors" in validated.splitlines()
    assert "joint_offsets[shoulder_pan_joint]: not identifiable" in validated
    assert [x.split(" = ")[0] for x in printed.splitlines() if x.startswith("  arm/joint_offsets")] == \
        [f"  arm/joint_offsets[{j}]" for j in JOINTS]
    for text in (validated, printed):
        assert "joint_offsets[0]" not in text and "placement[1]" not in text
    page = (out / "report.html").read_text(encoding="utf-8")
    assert all(f"<td>arm/joint_offsets[{j}]</td>" in page for j in JOINTS)
    calibration = yaml.safe_load((out / "calibration.yaml").read_text())["robots"]["arm"]
    assert calibration["joint_offsets"]["elements"] == JOINTS and calibration["placement"]["elements"] == JOINTS
    assert "elements" not in calibration["base"]


def test_calibration_yaml_with_elements_loads_back_and_a_reordered_list_is_refused(run, tmp_path):
    _, _, out = run
    written = yaml.safe_load((out / "calibration.yaml").read_text())
    config = yaml.safe_load(CONFIG.read_text())
    config["robots"]["arm"]["overrides"] = "calibration.yaml"
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    (tmp_path / "calibration.yaml").write_text((out / "calibration.yaml").read_text())
    loaded = fusionkit.load_config(tmp_path / "config.yaml").robots["arm"].description.parameters["joint_offsets"]
    assert loaded.values == pytest.approx(written["robots"]["arm"]["joint_offsets"]["values"], abs=1e-15)
    assert loaded.elements == tuple(JOINTS)
    swapped = (out / "calibration.yaml").read_text().replace(
        "elements: [shoulder_pan_joint, shoulder_lift_joint,", "elements: [shoulder_lift_joint, shoulder_pan_joint,", 1)
    (tmp_path / "calibration.yaml").write_text(swapped)
    line = next(n for n, x in enumerate(swapped.splitlines(), 1) if "[shoulder_lift_joint, shoulder_pan_joint," in x)
    with pytest.raises(ConfigError, match=rf"calibration.yaml:{line}: robots.arm.joint_offsets.elements: got "
                                          r"\[shoulder_lift_joint, shoulder_pan_joint, .*\]; expected "
                                          r"\[shoulder_pan_joint, shoulder_lift_joint, .*reorder the values"):
        fusionkit.load_config(tmp_path / "config.yaml")


def test_a_drifting_offset_is_summed_up_under_its_joints_name():
    """arm.sim's drift (the elbow's offset, its own time-varying parameter) over 10 s at 5 Hz: one line."""
    params = {"motion": "trajectory", "duration": 10.0, "rate": 5.0, "drift": {"change": 0.004}}
    with simulated_config("arm.sim", params, seed=2) as config:
        result = estimate(config)
    est = result.parameters["arm"]["drifting_offset[0]"]
    values = [float(v) for v in est.values]
    line = next(x for x in summary_text(result).splitlines() if x.startswith("  arm/drifting_offset"))
    assert line == (f"  arm/drifting_offset[elbow_joint]: time-varying over {len(values)} states, "
                    f"first {values[0]:.5g} ± {est.sigma[0][0]:.2g} rad, last {values[-1]:.5g} ± {est.sigma[-1][0]:.2g} "
                    f"rad, range {min(values):.5g}..{max(values):.5g} rad")
    assert len(values) == 50
