"""`fusionkit cable-lengths`: the encoder readings (and cable pulls) a calibration predicts at given poses. On a
noiseless cable.sag_static recording of cdpr_small (light cables, the taut workspace) with its true calibration,
the catenaries give the recorded lengths to 0.05 mm and the reference cable's recorded force to 1 %, where straight
cables are millimetres off; bad input is one line."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.cli.main import main
from fusionkit.simulate import write_dataset

WORKSPACE = "{min: [-0.5, -3.0, -12.0], max: [1.0, 0.0, -3.0]}"


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    folder = tmp_path_factory.mktemp("sag") / "ds"
    write_dataset("cable.sag_static", folder, ["robot=cdpr_small", "poses=15", "length_sigma=0", "force_sigma=0",
                                               "pose_sigma={rotation: 0, translation: 0}", f"workspace={WORKSPACE}"],
                  seed=2)
    return folder


def predict(folder, out, *extra) -> int:
    return main(["cable-lengths", str(folder / "robots" / "cdpr.yaml"), "--calibration",
                 str(folder / "truth" / "calibration.yaml"), "--poses", str(folder / "truth" / "cdpr.tum"),
                 "--out", str(out), *extra])


def read(path):
    return np.loadtxt(path, delimiter=",", skiprows=1)


def test_catenaries_predict_the_recorded_lengths_and_force_where_straight_cables_are_millimetres_off(recording, tmp_path):
    assert predict(recording, tmp_path / "catenary") == 0
    assert predict(recording, tmp_path / "rigid", "--rigid") == 0
    recorded = read(recording / "data" / "lengths.csv")
    catenary, rigid = read(tmp_path / "catenary" / "lengths.csv"), read(tmp_path / "rigid" / "lengths.csv")
    assert np.array_equal(catenary[:, 0], recorded[:, 0])
    assert np.abs(catenary[:, 1:] - recorded[:, 1:]).max() < 5e-5
    assert np.abs(rigid[:, 1:] - recorded[:, 1:]).max() > 1e-3
    tensions = read(tmp_path / "catenary" / "tensions.csv")  # t, H0..H3, V0..V3
    force = read(recording / "data" / "force.csv")[:, 1]     # the reference cable's (cable 0) pull, N
    np.testing.assert_allclose(np.hypot(tensions[:, 1], tensions[:, 5]), force, rtol=0.01)
    assert not (tmp_path / "rigid" / "tensions.csv").exists()


def test_a_missing_pose_file_or_parameter_is_one_line(recording, tmp_path, capsys):
    missing = main(["cable-lengths", str(recording / "robots" / "cdpr.yaml"), "--poses", str(tmp_path / "none.tum"),
                    "--out", str(tmp_path / "a")])
    assert missing == 2
    assert "none.tum" in capsys.readouterr().err
    assert predict(recording, tmp_path / "b", "--weight", "cable_weight") == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and "--weight cable_weight: the description has no such parameter" in error
