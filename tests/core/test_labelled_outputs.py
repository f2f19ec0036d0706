"""Every pose, rotation and vector value and sigma carries named components in report.json, calibration.yaml and
the summary; calibration.yaml still loads as a robot-description override, and mislabelled lists are refused."""

from __future__ import annotations

import json
from pathlib import Path

import gtsam
import numpy as np
import pytest
import yaml

import fusionkit
from fusionkit.cli.main import main
from fusionkit.errors import ConfigError
from fusionkit.report.outputs import calibration_text
from fusionkit.descriptions.calibration_file import calibration_entry
from fusionkit.simulate import write_dataset

REPO = Path(__file__).resolve().parents[2]
POSE3_NAMES = ["x", "y", "z", "qx", "qy", "qz", "qw"]
POSE3_SIGMA_NAMES = ["rx", "ry", "rz", "tx", "ty", "tz"]


def test_multirobot_pose3_is_labelled_in_report_calibration_and_summary(tmp_path, capsys):
    out = tmp_path / "multi"
    assert main(["run", str(REPO / "configs" / "multirobot.yaml"), "--out", str(out), "--no-plots"]) == 0
    summary = capsys.readouterr().out.splitlines()
    entry = json.loads((out / "report.json").read_text())["parameters"]["b"]["base_in_a"]
    calibration = yaml.safe_load((out / "calibration.yaml").read_text())["other"]["b"]["base_in_a"]
    for e in (entry, calibration):
        assert e["components"] == POSE3_NAMES and e["sigma_components"] == POSE3_SIGMA_NAMES
        assert len(e["value"]) == 7 and len(e["sigma"]) == 6
    assert calibration["value"] == pytest.approx(entry["value"], rel=1e-12)
    # the sigma is rotation first: b's base frame is known to ~0.01 rad and ~0.02-0.03 m (co-registration sigmas)
    assert max(entry["sigma"][:3]) < 0.015 and min(entry["sigma"][3:]) > 0.015
    values = ", ".join(f"{n} {v:.5g}" for n, v in zip(POSE3_NAMES, entry["value"]))
    sigmas = ", ".join(f"{n} {s:.2g}" for n, s in zip(POSE3_SIGMA_NAMES, entry["sigma"]))
    line = next(s for s in summary if s.startswith("  b/base_in_a = "))
    assert line.startswith(f"  b/base_in_a = {values} ± {sigmas} (rad about, m along the body axes)")


NOMINAL = {  # extra parameters of every labelled type in the simulated camera's description
    "mount": {"type": "pose3", "value": [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0], "sigma": [0.1, 0.1, 0.1, 0.5, 0.5, 0.5]},
    "base": {"type": "pose2", "value": [1.0, 2.0, 0.3], "sigma": [0.5, 0.5, 0.1]},
    "tilt": {"type": "rot3", "value": [0.0, 0.1, 0.0], "sigma": 0.2},
    "lever": {"type": "point3", "values": [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]], "sigma": 0.1},
    "bias": {"type": "imu_bias", "value": [0.0] * 6, "sigma": [0.1, 0.1, 0.1, 0.01, 0.01, 0.01]},
}
CALIBRATED = {
    "mount": ([gtsam.Pose3(gtsam.Rot3.RzRyRx(0.1, -0.2, 0.3), np.array([0.01, -0.02, 0.12]))],
              [[0.001, 0.002, 0.003, 0.004, 0.005, 0.006]]),
    "base": ([gtsam.Pose2(1.1, 2.2, 0.35)], [[0.01, 0.02, 0.003]]),
    "tilt": ([gtsam.Rot3.RzRyRx(0.01, 0.12, -0.03)], [[0.004, 0.005, 0.006]]),
    "lever": ([np.array([0.01, 0.0, 0.02]), np.array([0.11, 0.01, 0.0])],
              [[0.001, 0.002, 0.003], [0.004, 0.005, 0.006]]),
    "bias": ([gtsam.imuBias.ConstantBias(np.array([0.01, 0.02, 0.03]), np.array([0.001, 0.002, 0.003]))],
             [[0.01, 0.01, 0.01, 0.001, 0.001, 0.001]]),
}


@pytest.fixture
def ds(tmp_path) -> Path:
    folder = tmp_path / "ds"
    write_dataset("pose.scaled_vo", folder, ["duration=2"], seed=1)
    robot = folder / "robots" / "cam.yaml"
    desc = yaml.safe_load(robot.read_text())
    desc.setdefault("parameters", {}).update(NOMINAL)
    robot.write_text(yaml.safe_dump(desc, sort_keys=False))
    return folder


def write_calibration(ds: Path) -> Path:
    """calibration.yaml with CALIBRATED, written as `fusionkit run` writes it; the config loads it as overrides."""
    params = fusionkit.load_config(ds / "config.yaml").robots["cam"].description.parameters
    entries = {name: calibration_entry(params[name], values, np.array(sigma))
               for name, (values, sigma) in CALIBRATED.items()}
    path = ds / "calibration.yaml"
    path.write_text(calibration_text({"fusionkit_calibration": 1, "robots": {"cam": entries}}))
    config = yaml.safe_load((ds / "config.yaml").read_text())
    config["robots"]["cam"]["overrides"] = "calibration.yaml"
    (ds / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    return path


def test_labelled_calibration_round_trips_as_a_description_override(ds):
    text = write_calibration(ds).read_text()
    assert "      components: [x, y, z, qx, qy, qz, qw]\n" in text
    assert "      sigma_components: [rx, ry, rz, tx, ty, tz]\n" in text
    assert "      components: [x, y, theta]\n      sigma: [0.01, 0.02, 0.003]\n      sigma_components: [tx, ty, rz]\n" \
        in text
    assert "      components: [roll, pitch, yaw]\n" in text and "      sigma_components: [rx, ry, rz]\n" in text
    assert "      components: [ax, ay, az, gx, gy, gz]\n" in text
    params = fusionkit.load_config(ds / "config.yaml").robots["cam"].description.parameters
    for name, (values, sigma) in CALIBRATED.items():
        loaded = params[name]
        np.testing.assert_allclose(loaded.sigma, sigma, rtol=0, atol=1e-15)
        for want, got in zip(values, loaded.values):
            np.testing.assert_allclose(loaded.vartype.local(want, got), 0.0, atol=1e-12)


def test_sigma_components_in_another_order_are_refused_with_the_line(ds, capsys):
    path = write_calibration(ds)
    text = path.read_text().replace("sigma_components: [rx, ry, rz, tx, ty, tz]",
                                    "sigma_components: [tx, ty, tz, rx, ry, rz]")
    path.write_text(text)
    line = next(n for n, s in enumerate(text.splitlines(), start=1) if "[tx, ty, tz, rx, ry, rz]" in s)
    with pytest.raises(ConfigError) as err:
        fusionkit.load_config(ds / "config.yaml")
    assert str(err.value) == (f"{path}:{line}: robots.cam.mount.sigma_components: got [tx, ty, tz, rx, ry, rz]; "
                              "expected [rx, ry, rz, tx, ty, tz], the order of a pose3 sigma: reorder the numbers and "
                              "their names together")
    assert main(["validate", str(ds / "config.yaml")]) == 2
    assert capsys.readouterr().err == f"fusionkit: error: {err.value}\n"
