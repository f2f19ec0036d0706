"""Round-robin ranging (uwb.sim `round_robin: true`: one anchor answers per epoch, at 40 Hz, ranges 5 % too
long, constant biases): the shipped config's initialization -- uwb.multilateration with its automatic
window -- starts every one of 20 seeds where batch LM converges (chi-square per degree of freedom near 1,
trajectory within 4 cm); a window of one epoch cannot place the robot and says so in one line. Data
simulated with the noise levels the config assumes (a self-consistency check)."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.errors import ConfigError
from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.uwb.initializers import round_window

ROUND_ROBIN = {"round_robin": True, "rate": 40.0, "duration": 15.0, "bias_model": "constant", "bias_drift": 0.0,
               "scale_error": 0.05}


def test_the_automatic_window_is_one_round_for_round_robin_ranging_and_zero_for_full_epochs():
    t = np.repeat(np.arange(100) / 40.0, 1)
    assert round_window(t, np.arange(100) % 4, 3) == pytest.approx(3 / 40.0)  # 3 anchors in turn, plus a step
    full = np.repeat(np.arange(50) / 10.0, 4)
    assert round_window(full, np.tile(np.arange(4), 50), 3) == 0.0


@pytest.mark.slow
def test_round_robin_ranging_converges_from_the_shipped_initialization_over_20_seeds():
    chi2, ate = [], []
    for seed in range(20):
        with simulated_config("uwb.sim", ROUND_ROBIN, seed=seed) as config:
            result = estimate(config)
        chi2.append(result.solution.chi2_per_dof)
        ate.append(result.evaluation["trajectories"]["a"]["ate_rmse_m"])
        assert any("round-robin ranging" in note for note in result.notes)
    assert max(chi2) < 1.3 and max(ate) < 0.04, (chi2, ate)


def test_a_window_of_one_epoch_cannot_place_a_round_robin_robot():
    def one_epoch(config):
        config["initializers"][0]["window"] = 0.0
    with simulated_config("uwb.sim", ROUND_ROBIN, seed=0, edit=one_epoch) as config:
        with pytest.raises(ConfigError, match=r"initializers\[0\]\.stream.*no state has ranges to enough known anchors"):
            estimate(config)


def test_the_field_site_ranges_one_far_beacon_at_a_time_at_walking_speed_with_drifting_odometry():
    """`site: field` (the regime of a vehicle ranging to far beacons one at a time): four beacons 10-70 m from the
    path, about 1 m/s, one range per epoch at 2 Hz, and a right wheel reading 3 % long."""
    from fusionkit.pipeline import read_sources
    params = {"site": "field", "round_robin": True, "rate": 2.0, "duration": 240.0, "wheel_scale_error": 0.03,
              "bias_model": "constant"}
    with simulated_config("uwb.sim", params, seed=1) as config:
        streams, truth = read_sources(config)
    pose = truth.trajectories["a"].pose_array()
    speed = np.linalg.norm(np.diff(pose[:, :2], axis=0), axis=1) * 2.0
    assert 0.5 < np.median(speed) < 1.5
    ranges = streams["ranges_a"].values
    assert np.all(np.count_nonzero(ranges, axis=1) == 1)
    assert 10.0 < ranges[ranges > 0].min() and ranges.max() < 75.0
    wheels = streams["wheels_a"].values
    assert np.mean(wheels[:, 0] - wheels[:, 1]) > 0.01  # the right wheel reads long: the odometry turns left
