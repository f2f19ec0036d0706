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
