"""wheels.long_horizon: dead reckoning over long windows. The exact integration agrees with the preintegrated
window and with numerical derivatives; windows anchor at every checkpoint (or each recording's start) and end at
the recording's end or the horizon; checkpoints are `spacing` m of travel apart; on a simulated clean run with an
overhead camera it calibrates the radii and axle length far inside the description's errors (the Jacobians
against numerical differences: tests/core/test_contract.py)."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.pipeline import estimate
from fusionkit.simulate import simulated_config
from fusionkit_plugins.wheels.horizon import checkpoints, long_horizon_residual, windows
from fusionkit_plugins.wheels.preintegration import dead_reckon, preintegrate


def test_dead_reckoning_ends_where_the_preintegrated_window_does_and_its_derivative_matches_differences():
    rng = np.random.default_rng(3)
    left, right = rng.uniform(-0.2, 1.5, 50), rng.uniform(-0.2, 1.5, 50)
    theta = np.array([0.041, 0.043, 0.21])
    r = dead_reckon(left, right, theta)
    window = preintegrate(np.zeros(50, int), left, right, np.full(50, 0.05), theta, 1e-3, 1e-3)
    assert np.allclose(np.r_[r.position[-1], r.heading[-1]], window.delta[0], atol=1e-12)
    for i in range(3):
        step = np.zeros(3)
        step[i] = 1e-7
        plus, minus = dead_reckon(left, right, theta + step), dead_reckon(left, right, theta - step)
        assert np.allclose((plus.position - minus.position) / 2e-7, r.d_position[:, :, i], atol=1e-5)
        assert np.allclose((plus.heading - minus.heading) / 2e-7, r.d_heading[:, i], atol=1e-5)


def test_residual_is_the_checkpoints_position_in_the_anchor_frame_minus_dead_reckoning():
    left, right = np.full(10, 1.0), np.full(10, 1.0)  # straight ahead: 10 x 0.04 m
    anchor = (1.0, 2.0, np.pi / 2)                        # facing +y
    checkpoint = np.array([[1.01, 2.4, np.pi / 2 + 0.1]])
    e, _ = long_horizon_residual(anchor, checkpoint, (0.04, 0.04, 0.2), left, right, np.array([10]), True)
    assert e == pytest.approx([0.0, -0.01, 0.1], abs=1e-12)  # 0.4 m ahead as dead-reckoned; 1 cm to the right


def test_checkpoints_are_spacing_of_travel_apart_with_the_first_and_last():
    travel = np.array([0.0, 0.2, 0.45, 0.5, 0.6, 1.2, 1.3])
    assert checkpoints(travel, 0.5).tolist() == [0, 3, 5, 6]
    assert checkpoints(travel, None).tolist() == list(range(7))


def test_windows_anchor_at_every_checkpoint_and_end_at_the_recording_or_the_horizon():
    t = np.arange(10.0)
    parts = [(0.0, 4.5), (5.0, 9.0)]  # two recordings: states 0-4 and 5-9
    ks = np.arange(10)
    assert windows(t, ks, parts, None) == [[0, 1, 2, 3, 4], [1, 2, 3, 4], [2, 3, 4], [3, 4],
                                           [5, 6, 7, 8, 9], [6, 7, 8, 9], [7, 8, 9], [8, 9]]
    assert windows(t, ks, parts, 2.0)[:3] == [[0, 1, 2], [1, 2, 3], [2, 3, 4]]
    assert windows(t, ks, parts, None, every_anchor=False) == [[0, 1, 2, 3, 4], [5, 6, 7, 8, 9]]


@pytest.mark.parametrize("path", ["square", "random"])
def test_long_horizon_with_an_overhead_camera_calibrates_radii_within_0_1_mm_and_the_axle_within_1_mm(path):
    """60 s of wheels.sim (the description's radii drawn 0.3 mm off, the axle 2 mm), no gyro or per-wheel factors:
    the camera (2.8 mm) and wheels.long_horizon (checkpoints 0.1 m apart) alone. Measured over seeds 0-2: radii
    9-87 um off, the axle 0.11-0.71 mm; seed 1: square 36 / 16 um and 0.38 mm, random 12 / 13 um and 0.12 mm."""
    def edit(config):
        config["factors"] = [f for f in config["factors"] if not f["type"].startswith("wheels.")]
        config["factors"] += [{"type": "pose.absolute", "robot": "robot", "stream": "camera",
                               "sigma": {"rotation": 0.02, "translation": 0.0028}},
                              {"type": "wheels.long_horizon", "robot": "robot", "stream": "wheels", "sigma": 0.01,
                               "spacing": 0.1}]
        config["robots"]["robot"]["states"]["every"] = 10
    with simulated_config("wheels.sim", {"duration": 60.0, "path": path}, seed=1, edit=edit) as config:
        result = estimate(config)
    errors = result.evaluation["parameters"]["robot"]
    assert errors["wheel_radius_left"]["abs_error"][0] < 1e-4
    assert errors["wheel_radius_right"]["abs_error"][0] < 1e-4
    assert errors["axle_length"]["abs_error"][0] < 1e-3
    assert any("share their wheel samples" in note for note in result.problem.notes)
