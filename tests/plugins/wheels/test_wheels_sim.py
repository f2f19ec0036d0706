"""wheels.sim injects each fault class as documented, checked against its own truth: a stuck robot's driven
wheels spin while the passive wheel and the gyro see no motion; a wheel crossing an obstacle of height h
turns 2 r (beta - sin beta) further than it advances; fast turns under-rotate; a low-cost gyro reads
(rate - bias) / scale; the camera's noise is 2.8 mm; a drifting radius changes by `change`."""

from __future__ import annotations

from pathlib import Path

import gtsam
import numpy as np
import pytest

from fusionkit.config.yamlio import Document
from fusionkit.plugins import registry

TICK = 2 * np.pi / 2048  # rad: passive_wheel_robot's encoders


def simulate(seed: int = 0, **params):
    cls = registry().get("simulators", "wheels.sim")
    full = cls.resolve(params, Document(params, Path("<test>")))
    out = cls().simulate(full, np.random.default_rng(seed))
    cal = {k: v["value"] for k, v in out.truth_calibration["robot"].items()}
    return out.streams, out.truth_trajectories["robot"], cal


def planar(traj) -> np.ndarray:
    return np.array([[p.x(), p.y(), p.rotation().yaw()] for p in traj.poses()])


def true_travel(poses: np.ndarray, lateral: float) -> np.ndarray:
    """Per interval: the forward travel (m) of the axle point at `lateral`, from the true poses."""
    xi = np.array([gtsam.Pose2.Logmap(gtsam.Pose2(*a).between(gtsam.Pose2(*b))) for a, b in zip(poses[:-1], poses[1:])])
    return xi[:, 0] - lateral * xi[:, 2]


def over_edge(h: float, r: float) -> float:
    beta = np.arccos(1 - h / r)
    return r * (beta - np.sin(beta))


def test_stuck_robot_spins_its_driven_wheels_while_the_passive_wheel_and_gyro_stand():
    streams, truth, cal = simulate(duration=12.0, faults={"stuck": {"count": 1, "duration": 2.0}})
    wheels, poses = streams["wheels"], planar(truth)
    still = np.flatnonzero(np.all(np.diff(poses, axis=0) == 0, axis=1) & (wheels.t[:-1] > 1.5))
    assert len(still) == 40  # 2 s at 20 Hz
    ticks = {w: np.diff(wheels.column(w))[still] for w in ("left", "right", "passive")}
    assert np.all(ticks["left"] > 30) and np.all(ticks["right"] > 30)   # ~60 ticks per step commanded
    assert np.all(np.abs(ticks["passive"]) <= 3)                          # noise: 0.6 tick per step
    rest_rate = cal["gyro_scale"] * wheels.column("gyro")[still + 1] + cal["gyro_bias"]
    assert abs(rest_rate.mean()) < 0.01 and abs(wheels.column("gyro")[still + 1].mean()) > 0.015


@pytest.mark.parametrize("fault", ["bumps", "roughness"])
def test_obstacles_add_their_over_the_edge_travel_to_the_wheels_that_cross_them(fault):
    faults = {"bumps": {"count": 1}} if fault == "bumps" else {"roughness": {"height": 0.0015}}
    streams, truth, cal = simulate(1, duration=15.0, wheel_noise=0.0, faults=faults)
    wheels, poses = streams["wheels"], planar(truth)
    excess = {}
    for w, lateral, radius in (("left", 0.5 * cal["axle_length"], cal["wheel_radius_left"]),
                               ("right", -0.5 * cal["axle_length"], cal["wheel_radius_right"]),
                               ("passive", 0.0, cal["passive_radius"])):
        rim = np.diff(wheels.column(w)) * TICK * radius
        excess[w] = (rim.sum() - true_travel(poses, lateral).sum(), radius, lateral)
    if fault == "bumps":  # one wheel meets one obstacle of 1.5..3 cm; the others: quantization only
        bumped = [w for w, (e, r, _) in excess.items() if e > 4 * TICK * r]
        assert len(bumped) == 1
        e, r, _ = excess[bumped[0]]
        assert 2 * over_edge(0.015, r) - 2 * TICK * r < e < 2 * over_edge(min(0.03, 0.9 * r), r) + 2 * TICK * r
    else:  # every crossing of a wire (lines x = 0.1 k) costs 2 r (beta - sin beta)
        for w, (e, r, lateral) in excess.items():
            x = poses[:, 0] - lateral * np.sin(poses[:, 2])
            crossings = np.abs(np.diff(np.floor(x / 0.1))).sum()
            assert crossings >= 5
            assert e == pytest.approx(crossings * 2 * over_edge(0.0015, r), abs=2 * TICK * r)


def test_fast_turns_slide_the_robot_turns_less_than_its_wheels_say():
    """Square path: 90 degree corners on the spot at 1.5 rad/s; with slip 0.3 the robot turns 63 degrees."""
    streams, truth, cal = simulate(duration=9.0, path="square", wheel_noise=0.0, faults={"slide": {"slip": 0.3}})
    wheels, poses = streams["wheels"], planar(truth)
    turned = np.unwrap(poses[:, 2])[-1]
    wheel_turn = (np.diff(wheels.column("right")) * cal["wheel_radius_right"]
                  - np.diff(wheels.column("left")) * cal["wheel_radius_left"]).sum() * TICK / cal["axle_length"]
    assert wheel_turn == pytest.approx(np.pi / 2, abs=0.01)   # one corner within 9 s
    assert turned == pytest.approx(0.7 * np.pi / 2, abs=0.01)


def test_gyro_reads_the_true_rate_minus_bias_over_scale_with_its_noise():
    streams, truth, cal = simulate(duration=20.0, path="slalom")
    poses, gyro = planar(truth), streams["wheels"].column("gyro")
    rate = np.diff(np.unwrap(poses[:, 2])) / 0.05
    slope, offset = np.polyfit(rate, gyro[1:], 1)
    assert slope == pytest.approx(1 / 1.25, rel=0.02) and offset == pytest.approx(-0.03 / 1.25, abs=0.002)
    assert np.std(gyro[1:] - (rate - 0.03) / 1.25) == pytest.approx(0.002 / np.sqrt(0.05), rel=0.1)
    assert cal["gyro_scale"] == 1.25 and cal["gyro_bias"] == 0.03


def test_camera_sees_the_truth_with_2_8_mm_noise_and_a_drifting_radius_changes_by_its_change():
    streams, truth, cal = simulate(duration=40.0, drift={"wheel": "right", "change": -0.001})
    camera, true = streams["camera"], truth.pose_array()
    rows = np.searchsorted(truth.t, camera.t)
    error = camera.pose_array()[:, :2] - true[rows, :2]
    assert np.std(error) == pytest.approx(0.0028, rel=0.1)
    radii = streams["radius_truth"]
    assert radii.column("right")[-1] - radii.column("right")[0] == pytest.approx(-0.001)
    assert np.ptp(radii.column("left")) == 0.0 and radii.column("right")[0] == cal["wheel_radius_right"]


def test_robot_seed_gives_the_intrinsics_of_the_run_with_that_seed_and_its_own_noise():
    _, _, mission = simulate(seed=4, duration=5.0, path="loop")
    calibration_streams, _, calibration = simulate(seed=11, duration=5.0, path="square", robot_seed=4)
    _, _, other = simulate(seed=11, duration=5.0, path="square")
    same_seed_streams = simulate(seed=4, duration=5.0, path="square")[0]
    assert calibration == mission                       # the same robot, bit for bit
    assert calibration["axle_length"] != other["axle_length"]
    noise = np.diff(calibration_streams["wheels"].values - same_seed_streams["wheels"].values, axis=0)
    assert np.abs(noise).max() > 0                      # the same robot and path, other noise
