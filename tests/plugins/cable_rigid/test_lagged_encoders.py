"""`cable.cdpr` with lagging encoders (`time_offset: {lengths: s}`): the encoder sample stamped t reads the
cable lengths at t + offset, the description gains the offset parameter, the truth holds its value and the
written config estimates it from a first guess."""

from __future__ import annotations

import numpy as np

from fusionkit_plugins.cable_rigid.simulator import ENCODER_OFFSET, CdprSimulator

SIM = CdprSimulator()
QUIET = {"encoder_sigma": 0.0, "tension_sigma": 0.0, "tension_resolution": 0.0, "duration": 4.0, "rate": 50.0}


def lengths(**params):
    p = SIM._params({**QUIET, **params})
    return p, SIM.simulate(p, np.random.default_rng(0))


def test_encoder_sample_stamped_t_reads_the_lengths_at_t_plus_the_offset():
    """A lag of two sample intervals: the lagged sample k is the plain sample k - 2 (same seed, no noise)."""
    _, plain = lengths()
    _, lagged = lengths(time_offset={"lengths": -2 / QUIET["rate"], "tensions": -2 / QUIET["rate"]})
    for name in ("lengths", "tensions"):
        assert np.abs(lagged.streams[name].values[2:] - plain.streams[name].values[:-2]).max() < 1e-9
        assert np.abs(lagged.streams[name].values[2:] - plain.streams[name].values[2:]).max() > 1e-3
    assert np.array_equal(lagged.streams["mocap"].values, plain.streams["mocap"].values)


def test_lagging_encoders_give_the_description_the_offset_and_the_config_its_estimate():
    p, out = lengths(time_offset={"lengths": -0.03})
    desc = SIM.robots(p)["cdpr"]
    assert desc["parameters"][ENCODER_OFFSET]["value"] == 0.0
    assert out.truth_calibration["cdpr"][ENCODER_OFFSET]["value"] == -0.03
    config = SIM.config(p)
    entry = next(f for f in config["factors"] if f["type"] == "cable.length")
    assert entry["time_offset"] == {"parameter": ENCODER_OFFSET}
    assert config["initializers"][0]["type"] == "time.offset_guess"
    plain = SIM._params(QUIET)
    assert ENCODER_OFFSET not in SIM.robots(plain)["cdpr"]["parameters"]
    assert all("time_offset" not in f for f in SIM.config(plain)["factors"])
