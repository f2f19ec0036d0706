"""The simulated wheel robots' configs with the gyro trusted for turning (docs/models/wheels.md#turn-slip-for-a-calibrated-gyro): what
benchmarks/bench_wheels_sim.py compares and tests/plugins/wheels/test_turn_slip.py checks."""

from __future__ import annotations

TURN_SLIP = {"sigma": 1e-4, "k": 3.0, "seed_rate": 0.03}  # rad per step; sigmas; rad/s (docs/models/wheels.md)


def trust_the_gyro(config: dict) -> None:
    """With a calibrated gyro: the driven wheels' turn may slip (one turn slip per step, seeded where the wheels
    and the gyro disagree) and dead reckoning turns with the gyro. Nothing changes without a gyro."""
    if not any(f["type"] == "wheels.gyro" for f in config["factors"]):
        return
    for f in config["factors"]:
        if f["type"] == "wheels.encoder" and f.get("wheels") == ["left", "right"]:
            f["turn_slip"] = dict(TURN_SLIP)
    config["initializers"][0]["turn"] = "gyro"
