"""fusionkit.geometry: the range-origin fit shared by cable pulleys and UWB anchors."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit.geometry import fit_range_origin

PULLEY = np.array([2.0, -1.5, 3.2])
OFFSET = -2.9


def _ranges(points: np.ndarray, noise: float, rng) -> np.ndarray:
    return np.linalg.norm(points - PULLEY, axis=1) + OFFSET + rng.normal(0.0, noise, len(points))


def test_exact_ranges_give_the_origin_and_offset():
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, (50, 3)) + [0, 0, 1.3]
    a, c, rms = fit_range_origin(q, _ranges(q, 0.0, rng))
    assert np.abs(a - PULLEY).max() < 1e-9 and abs(c - OFFSET) < 1e-9 and rms < 1e-9


def test_noisy_ranges_at_1_mm_fit_the_origin_within_1_cm_and_rms_at_the_noise():
    rng = np.random.default_rng(1)
    q = rng.uniform(-1, 1, (750, 3)) + [0, 0, 1.3]
    a, c, rms = fit_range_origin(q, _ranges(q, 0.001, rng))
    assert np.linalg.norm(a - PULLEY) < 0.01 and abs(c - OFFSET) < 0.01
    assert 0.0008 < rms < 0.0013


@pytest.mark.parametrize("points", [np.c_[np.random.default_rng(2).uniform(-1, 1, (40, 2)), np.ones(40)],
                                    np.outer(np.linspace(0, 1, 40), [1.0, 0.5, 0.2])],
                         ids=["plane", "line"])
def test_degenerate_points_are_refused(points):
    with pytest.raises(ValueError, match="do not span 3-D"):
        fit_range_origin(points, _ranges(points, 0.0, np.random.default_rng(0)))


def test_too_few_points_are_refused():
    q = np.random.default_rng(0).normal(size=(4, 3))
    with pytest.raises(ValueError, match="at least 5"):
        fit_range_origin(q, np.ones(4))
