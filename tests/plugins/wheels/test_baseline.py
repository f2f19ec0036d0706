"""`wheels.rule_odometry`: the rule-based baselines run from a config on the simulator's wheel stream give
exactly the rules' dead reckoning as the estimate; a method the robot cannot run is one located error."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit import load_config
from fusionkit.api import ConfigError
from fusionkit.pipeline import estimate, read_sources
from fusionkit.simulate import simulated_config
from fusionkit_plugins.wheels import rules
from fusionkit_plugins.wheels.rule_odometry import wheel_steps
from fusionkit_plugins.wheels.model import drive_of

PARAMS = {"duration": 10.0, "faults": {"stuck": {"count": 1}, "bumps": {"count": 2}}}


def baseline_only(method: str, **settings):
    def edit(config):
        config["factors"] = [config["factors"][0], {"type": "wheels.rule_odometry", "robot": "robot", "stream": "wheels",
                                                    "method": method, **settings}]
        config["initializers"] = []
        config["output"] = {"plots": False}
    return edit


@pytest.mark.parametrize("method, settings, rule", [
    ("final_version", {"thresholds": {"omega": 0.1}}, lambda s: rules.final_version(s, omega_thres=0.1)),
    ("gyrodometry", {"reconstruct": True}, lambda s: rules.gyrodometry(s, reconstruct=True))])
def test_config_estimate_is_the_rules_dead_reckoning_at_every_state(method, settings, rule):
    """pose.origin + wheels.rule_odometry: the solved trajectory equals the rule applied to the stream with the
    description's nominal radii, axle and gyro scale/bias (to 1e-9 m / rad)."""
    with simulated_config("wheels.sim", PARAMS, 3, baseline_only(method, **settings)) as config:
        result = estimate(config)
        streams, _ = read_sources(config)
        drive = drive_of(config.robots["robot"].description)
    expected = rule(wheel_steps(streams["wheels"], drive))
    traj = result.trajectories["robot"]
    np.testing.assert_allclose(traj.t, streams["wheels"].t)
    arr = traj.pose_array()
    yaw = 2.0 * np.arctan2(arr[:, 5], arr[:, 6])
    np.testing.assert_allclose(arr[:, :2], expected[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - expected[:, 2]))), 0.0, atol=1e-9)


def test_method_needing_a_gyro_on_a_robot_without_one_is_a_located_error(workspace):
    t = np.arange(0.0, 2.0, 0.05)
    source = workspace.columns("wheels", t, left=t * 2.0, right=t * 2.1)
    path = workspace.config({
        "robots": {"robot": {"description": "optiodom_robot", "states": {"stream": "wheels", "type": "pose2"}}},
        "sources": [source],
        "factors": [{"type": "pose.origin", "robot": "robot", "sigma": {"rotation": 0.001, "translation": 0.001}},
                    {"type": "wheels.rule_odometry", "robot": "robot", "stream": "wheels", "method": "gyrodometry"}]})
    with pytest.raises(ConfigError, match=r"config.yaml:\d+: factors\[1\]\.method: .*gyrodometry needs the gyro") as err:
        load_config(path)
    assert "\n" not in str(err.value)
