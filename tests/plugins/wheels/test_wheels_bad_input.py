"""Bad diff_drive descriptions and wheel entries stop `fusionkit validate` with one located line (file, key
path, what was expected) and exit code 2. The descriptions are inline in the config."""

from __future__ import annotations

import pytest

from fusionkit.api import robot_description_data
from fusionkit.cli.main import main


def config(description: dict, factors: list | None = None) -> dict:
    return {"name": "bad_wheels",
            "robots": {"robot": {"description": description, "states": {"stream": "wheels", "type": "pose2"}}},
            "sources": [{"type": "simulate", "scenario": "wheels.sim", "params": {"duration": 2.0}}],
            "factors": factors or [{"type": "wheels.encoder", "robot": "robot", "stream": "wheels", "sigma": 0.01},
                                   {"type": "wheels.gyro", "robot": "robot", "stream": "wheels", "sigma": 0.002}]}


def edit(change):
    def make() -> dict:
        desc = robot_description_data("passive_wheel_robot")
        change(desc["parameters"], desc)
        return config(desc)
    return make


def without_gyro(pars, desc):
    del pars["gyro_scale"], pars["gyro_bias"]


def two_wheels() -> dict:
    """A diff_drive description with the two driven wheels only: no passive wheel, no gyro."""
    return {"name": "two_wheels", "model": "diff_drive", "parameters": {
        n: {"type": "scalar", "value": v} for n, v in (("wheel_radius_left", 0.04), ("wheel_radius_right", 0.04),
                                                      ("axle_length", 0.25))}}


def offset(value: float):
    return {"type": "scalar", "value": value, "fixed": True}


CASES = {
    "no axle length": (edit(lambda p, d: p.pop("axle_length")),
                       "parameters: a diff_drive robot needs parameter 'axle_length'"),
    "negative radius": (edit(lambda p, d: p["wheel_radius_left"].update(value=-0.04)),
                        "parameters.wheel_radius_left.value: wheel_radius_left must be > 0 m; got -0.04"),
    "radius per wheel as a vector": (
        edit(lambda p, d: p.update(wheel_radius_right={"type": "vector2", "value": [0.04, 0.04]})),
        "parameters.wheel_radius_right: wheel_radius_right must be one scalar"),
    "offset without a passive wheel": (edit(lambda p, d: (p.pop("passive_radius"), d.pop("passive_ticks_per_revolution"),
                                                          p.update(passive_offset=offset(0.0)))),
                                       "parameters.passive_offset: passive_offset needs a passive wheel"),
    "passive wheel outside the axle": (edit(lambda p, d: p.update(passive_offset=offset(0.2))),
                                       "parameters.passive_offset.value: the passive wheel must lie between"),
    "gyro scale without bias": (edit(lambda p, d: p.pop("gyro_bias")),
                                "parameters.gyro_scale: a gyro needs both gyro_scale and gyro_bias"),
    "ticks as text": (edit(lambda p, d: d.update(ticks_per_revolution="many")),
                      "ticks_per_revolution: got 'many'; expected a number > 0"),
    "passive ticks without a passive wheel": (edit(lambda p, d: p.pop("passive_radius")),
                                              "passive_ticks_per_revolution: passive_ticks_per_revolution needs a "
                                              "passive wheel"),
    "gyro factor on a robot without gyro": (edit(without_gyro),
                                            "factors[1].robot: robot 'robot' has no gyro"),
    "passive encoder on a robot without one": (
        lambda: config(two_wheels(),
                       [{"type": "wheels.encoder", "robot": "robot", "stream": "wheels", "sigma": 0.01,
                         "wheels": ["left", "passive"]}]),
        "factors[0].wheels: robot 'robot' has no passive wheel"),
    "turn slip on the passive wheel": (
        lambda: config(robot_description_data("passive_wheel_robot"),
                       [{"type": "wheels.encoder", "robot": "robot", "stream": "wheels", "sigma": 0.01,
                         "turn_slip": {"sigma": 1e-4, "k": 3.0}}]),
        "factors[0].turn_slip: the passive wheel is turned by the floor"),
    "turn slip seeded without a gyro": (
        lambda: config(two_wheels(),
                       [{"type": "wheels.encoder", "robot": "robot", "stream": "wheels", "sigma": 0.01,
                         "wheels": ["left", "right"], "turn_slip": {"sigma": 1e-4, "k": 3.0, "seed_rate": 0.03}}]),
        "factors[0].turn_slip.seed_rate: robot 'robot' has no gyro to seed slips from"),
    "dead reckoning by a gyro the robot lacks": (
        lambda: {**config(two_wheels(), [{"type": "wheels.encoder", "robot": "robot", "stream": "wheels",
                                          "sigma": 0.01}]),
                 "initializers": [{"type": "wheels.dead_reckoning", "robot": "robot", "stream": "wheels",
                                   "turn": "gyro"}]},
        "initializers[0].turn: robot 'robot' has no gyro"),
    "a pose3 robot": (lambda: {**config(robot_description_data("passive_wheel_robot")),
                               "robots": {"robot": {"description": "passive_wheel_robot",
                                                    "states": {"stream": "wheels", "type": "pose3"}}}},
                      "factors[0].robot: robot 'robot' has pose3 states; this needs pose2"),
}


@pytest.mark.parametrize("case", CASES)
def test_bad_wheel_input_is_one_located_line(workspace, capsys, case):
    make, needle = CASES[case]
    path = workspace.config(make())
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and str(path) in err, err
