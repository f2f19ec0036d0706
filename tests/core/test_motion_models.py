"""Shared motion models (fusionkit.api): sample-and-hold integration intervals and the
differential-drive / unicycle increment the wheel-odometry factor integrates."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.api import differential_drive_twist, held_intervals, unicycle_increment


def test_constant_wheel_speeds_integrate_to_the_exact_arc_chord():
    """Constant wheel speeds drive a circle of radius v / omega: the increment is the chord."""
    d, vr, vl, T = 0.3, 0.6, 0.4, 2.0
    v, w = differential_drive_twist(np.full(20, vr), np.full(20, vl), d)
    assert v[0] == pytest.approx(0.5) and w[0] == pytest.approx(2 / 3)
    delta = unicycle_increment(v, w, np.full(20, T / 20))
    radius = v[0] / w[0]
    assert delta.theta() == pytest.approx(w[0] * T)
    assert delta.x() == pytest.approx(radius * np.sin(w[0] * T), abs=1e-12)
    assert delta.y() == pytest.approx(radius * (1 - np.cos(w[0] * T)), abs=1e-12)


@pytest.mark.parametrize("t0, t1, rows, dt", [
    (0.0, 0.3, [0, 1, 2], [0.1, 0.1, 0.1]),      # whole samples
    (0.05, 0.25, [0, 1, 2], [0.05, 0.1, 0.05]),  # the sample before t0 covers the start
    (0.45, 0.7, [4], [0.25]),                    # after the last sample it holds on
    (-0.2, 0.05, [0], [0.05]),                   # before the first one only from its own time
])
def test_held_intervals_cover_exactly_the_state_interval(t0, t1, rows, dt):
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    r, h = held_intervals(t, t0, t1)
    assert r.tolist() == rows
    np.testing.assert_allclose(h, dt, atol=1e-12)
