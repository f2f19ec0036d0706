"""`uwb.sim` with lagging ranging (`time_offset: {ranges: s}`, or `{ranges: {offset: s, rate: s/s}}` for a drifting
clock): the range stamped t measures the tag at t + offset (+ rate (t - t0)), and the written config estimates
each robot's offset (and clock rate)."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit_plugins.uwb.simulators import LEVER_ARM, ROOM, UwbSimulator, lissajous

SIM = UwbSimulator()
QUIET = {"range_sigma": 0.0, "bias_sigma": 0.0, "bias_drift": 0.0, "wheel_sigma": 0.0, "duration": 5.0}


def test_range_stamped_t_measures_the_tag_at_t_plus_the_offset():
    p = SIM._params({**QUIET, "time_offset": {"ranges": -0.05}})
    out = SIM.simulate(p, np.random.default_rng(0))
    ranges = out.streams["ranges_a"]
    pos, heading = lissajous(ranges.t - 0.05, 0.0, np.asarray(ROOM, float))
    b = np.asarray(LEVER_ARM)
    tag = pos + np.column_stack([np.cos(heading) * b[0] - np.sin(heading) * b[1],
                                 np.sin(heading) * b[0] + np.cos(heading) * b[1]])
    expected = np.linalg.norm(tag[:, None, :] - np.asarray(ROOM)[None], axis=2)
    assert np.abs(ranges.values - expected).max() < 1e-12
    assert out.truth_calibration["a"]["uwb_time_offset"]["value"] == -0.05


def test_lagging_ranges_are_estimated_by_the_written_config():
    p = SIM._params({"time_offset": {"ranges": -0.05}})
    assert SIM.robots(p)["a"]["parameters"]["uwb_time_offset"]["sigma"] == 1.0
    entry = next(f for f in SIM.config(p)["factors"] if f["type"] == "uwb.range")
    assert entry["time_offset"] == {"parameter": "uwb_time_offset"}


def test_drifting_ranging_clock_reads_the_tag_at_stamp_plus_offset_plus_rate_and_the_config_names_the_rate():
    """`{ranges: {offset, rate}}`: the range stamped t measures the tag at t + offset + rate (t - t0); the truth,
    the descriptions and the written config carry `uwb_clock_rate`."""
    clock = {"offset": -0.05, "rate": 1.0e-3}
    p = SIM._params({**QUIET, "time_offset": {"ranges": clock}})
    out = SIM.simulate(p, np.random.default_rng(0))
    ranges = out.streams["ranges_a"]
    t = ranges.t - 0.05 + 1.0e-3 * (ranges.t - ranges.t[0])
    pos, heading = lissajous(t, 0.0, np.asarray(ROOM, float))
    b = np.asarray(LEVER_ARM)
    tag = pos + np.column_stack([np.cos(heading) * b[0] - np.sin(heading) * b[1],
                                 np.sin(heading) * b[0] + np.cos(heading) * b[1]])
    expected = np.linalg.norm(tag[:, None, :] - np.asarray(ROOM)[None], axis=2)
    assert np.abs(ranges.values - expected).max() < 1e-12
    assert out.truth_calibration["a"]["uwb_clock_rate"]["value"] == 1.0e-3
    assert out.truth_calibration["a"]["uwb_time_offset"]["value"] == -0.05
    assert SIM.robots(p)["a"]["parameters"]["uwb_clock_rate"]["value"] == 0.0
    entry = next(f for f in SIM.config(p)["factors"] if f["type"] == "uwb.range")
    assert entry["time_offset"] == {"parameter": "uwb_time_offset", "rate": "uwb_clock_rate"}


@pytest.mark.slow
def test_a_drifting_ranging_clock_is_estimated_within_3_sigma_by_the_written_config():
    """60 s, ranges 50 ms late, the ranging clock gaining 1 ms per s (self-consistency: the config's noise is
    the simulator's). Measured (seed 0): offset -52 +- 40 ms, rate 2.1 +- 1.1 ms/s; a minute pins the rate
    only to about its own size."""
    from fusionkit.pipeline import estimate
    from fusionkit.simulate import simulated_config
    truth = {"uwb_time_offset": -0.05, "uwb_clock_rate": 1.0e-3}
    clock = {"ranges": {"offset": -0.05, "rate": 1.0e-3}}
    with simulated_config("uwb.sim", {"duration": 60.0, "time_offset": clock}, seed=0) as config:
        result = estimate(config)
    for name, value in truth.items():
        est = result.parameters["a"][name]
        assert abs(est.values[0] - value) < 3 * est.sigma[0][0], (name, est.values[0], est.sigma[0][0])
    assert result.parameters["a"]["uwb_clock_rate"].sigma[0][0] < 2e-3
