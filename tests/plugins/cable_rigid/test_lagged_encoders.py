"""`cable.cdpr` with lagging encoders (`time_offset: {lengths: s}` or `{lengths: {offset: s, rate: s/s}}`): the
encoder sample stamped t reads the cable lengths at t + offset (+ rate (t - t0)), the description gains the
offset (and clock-rate) parameter, the truth holds its value and the written config estimates it from a first
guess; the offset and rate are recovered within 3 sigma."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.cable_rigid.simulators import ENCODER_OFFSET, ENCODER_RATE, CdprSimulator

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


def test_drifting_encoder_clock_writes_the_rate_parameter_truth_and_config():
    """`{lengths: {offset, rate}}`: the sample k stamped t_k reads the lengths at t_k + offset + rate (t_k - t_0)."""
    rate = 0.5 / QUIET["duration"]  # two samples (0.04 s) of drift over the 4 s
    _, plain = lengths()
    p, drifting = lengths(time_offset={"lengths": {"offset": 0.0, "rate": rate}})
    late = drifting.streams["lengths"].values[-30:]  # the last 30 samples lie 1.6-2 samples ahead of their stamps
    assert np.abs(late - plain.streams["lengths"].values[-30:]).max() > 1e-3
    assert drifting.truth_calibration["cdpr"][ENCODER_RATE]["value"] == rate
    assert SIM.robots(p)["cdpr"]["parameters"][ENCODER_RATE]["value"] == 0.0
    entry = next(f for f in SIM.config(p)["factors"] if f["type"] == "cable.length")
    assert entry["time_offset"] == {"parameter": ENCODER_OFFSET, "rate": ENCODER_RATE}
    constant = SIM._params({**QUIET, "time_offset": {"lengths": -0.03}})
    assert ENCODER_RATE not in SIM.robots(constant)["cdpr"]["parameters"]


@pytest.mark.slow
def test_encoder_offset_and_clock_rate_recovered_within_3_sigma():
    """Self-consistency check (the config's noise = the simulator's): encoders 30 ms late whose clock gains
    0.2 ms/s, 6 s at 60 Hz (states dense enough that the curve through them follows the motion; at 30 Hz the
    interpolation error makes the sigmas optimistic by ~1.6x, see docs/models/unified_graph.md#time-offsets).
    The rate must also differ from 0 by more than 3 sigma (the drift is seen, not just allowed)."""
    truth = {ENCODER_OFFSET: -0.03, ENCODER_RATE: 2.0e-4}
    params = {"duration": 6.0, "rate": 60.0,
              "time_offset": {"lengths": {"offset": truth[ENCODER_OFFSET], "rate": truth[ENCODER_RATE]}}}
    with simulated_config("cable.cdpr", params, seed=0, edit=lambda c: c.update(output={"plots": False})) as config:
        estimated = estimate(config).parameters["cdpr"]
    for name, value in truth.items():
        est, sigma = estimated[name].values[0], estimated[name].sigma[0][0]
        assert abs(est - value) < 3 * sigma, (name, est, sigma)
    rate = estimated[ENCODER_RATE]
    assert abs(rate.values[0]) > 3 * rate.sigma[0][0]
