"""fusionkit.lie's Jacobians against central differences across rotation angles from 1e-8 rad to 0.5 rad,
through the switch from series to closed forms at lie.SMALL (the closed forms cancel: at 1e-4 rad they were
off by 7e-7 with the switch there)."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit import lie


@pytest.mark.parametrize("angle", [1e-8, 1e-5, 1e-4, 1e-3, 0.999 * lie.SMALL, 1.001 * lie.SMALL, 0.5])
def test_jr_and_jr_inv_match_central_differences(angle):
    rng = np.random.default_rng(1)
    xi = rng.normal(size=(100, 6))
    xi[:, :3] *= angle / np.linalg.norm(xi[:, :3], axis=1)[:, None]
    X, h = lie.exp(xi), 1e-6
    for j in range(6):
        e = np.zeros_like(xi)
        e[:, j] = h
        jr_column = (lie.log(lie.inverse(X) @ lie.exp(xi + e)) - lie.log(lie.inverse(X) @ lie.exp(xi - e))) / (2 * h)
        inv_column = (lie.log(X @ lie.exp(e)) - lie.log(X @ lie.exp(-e))) / (2 * h)
        assert np.abs(lie.jr(xi)[:, :, j] - jr_column).max() < 5e-8
        assert np.abs(lie.jr_inv(xi)[:, :, j] - inv_column).max() < 5e-9
    assert np.abs(lie.log(X) - xi).max() < 1e-14
