"""A dwell-and-swing recording (cable.sag_static `swing`: each static pose held 3 s at 4 Hz while the
end-effector swings 5 cm about its equilibrium at constant cable lengths) calibrated through the
`static_segments` source: one averaged sample per dwell, pulleys within 15 cm. (Every sample taken as a
static pose instead, 20 poses of 5 s: chi-square per degree of freedom 5.5e7, pulleys 0.9-9.4 m off, 57 s;
docs/models/cable_sag.md#swinging-end-effector.)"""

from __future__ import annotations

import yaml

from fusionkit.cli.main import main
from fusionkit.config.loader import load_config
from fusionkit.pipeline import estimate

SWING = "swing={dwell: 3.0, rate: 4.0, amplitude: 0.05, period: 2.0, decay: 5.0}"


def test_static_segments_of_a_swinging_recording_calibrate_the_sag_model(tmp_path):
    sim = tmp_path / "sim"
    assert main(["simulate", "cable.sag_static", "--out", str(sim), "--set", "robot=cdpr_small", "--set", "poses=12",
                 "--set", SWING]) == 0
    config = yaml.safe_load((sim / "config.yaml").read_text())
    config["sources"] = [{"type": "static_segments", "segments_from": {"name": "lengths", "path": "data/lengths.csv"},
                          "also": [{"name": "poses", "path": "data/poses.tum"},
                                   {"name": "force", "path": "data/force.csv"}],
                          "tolerance": 0.01, "min_duration": 2.0}]
    config["truth"] = {"calibration": "truth/calibration.yaml"}
    (sim / "static.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    result = estimate(load_config(sim / "static.yaml"))
    assert len(result.streams["poses"]) == 12
    assert any("12 static stretch(es)" in note for note in result.notes)
    assert result.evaluation["parameters"]["cdpr"]["pulley"]["mean_abs_error"] < 0.15
