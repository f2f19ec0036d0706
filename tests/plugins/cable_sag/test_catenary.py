"""The catenary (thesis eqs. 5.1-5.4) in its cancellation-free form: equal to the printed equations
where they are computable, finite where they are not, exact Jacobians, the right limits."""

from __future__ import annotations

import numpy as np
import pytest

from fusionkit_plugins.cable_sag.catenary import catenary, catenary_spec_form

W_LARGE, W_SMALL = 0.7100703, 0.1034955  # N/m


@pytest.mark.parametrize("H, V, L, w", [(600.0, 70.0, 150.0, W_LARGE), (20.0, 10.0, 8.0, W_SMALL),
                                        (500.0, 900.0, 1.0, W_LARGE), (5.0, 5.0, 10.0, W_SMALL),
                                        (800.0, -40.0, 120.0, W_LARGE)])
def test_equals_the_printed_equations_to_1e_11_in_length_and_1e_9_in_rise(H, V, L, w):
    length, rise = catenary(H, V, L, w)
    z_pulley = 48.0
    length_spec, z_end = catenary_spec_form(H, V, L, w, z_pulley)
    assert length == pytest.approx(length_spec, rel=1e-11)
    assert rise == pytest.approx(z_pulley - z_end, rel=1e-9, abs=1e-9)


def test_printed_equations_cancel_where_this_form_does_not():
    """Towards a light cable (w -> 0) eqs. 5.1-5.4 subtract cosh values that differ by O(w) and
    scale the difference by H / w: at w = 1e-10 N/m their rise is off by 0.4 mm, their length by
    0.1 mm; this form stays on the straight-cable limit to 1e-9 m."""
    H, V, L, w = 500.0, 300.0, 100.0, 1e-10
    length, rise = catenary(H, V, L, w)
    length_spec, z_end = catenary_spec_form(H, V, L, w, 48.0)
    assert abs(rise - L * V / H) < 1e-8 and abs(length - L * np.hypot(H, V) / H) < 1e-8
    assert abs((48.0 - z_end) - L * V / H) > 1e-4


def test_printed_equations_overflow_where_this_form_stays_finite():
    """Small horizontal force on a long heavy cable: w L / H = 1065, cosh overflows in eq. 5.3."""
    length, rise = catenary(0.04, 50.0, 60.0, W_LARGE)
    assert np.isfinite(length) and np.isfinite(rise) and length > 1e100
    with np.errstate(all="ignore"):
        assert not np.all(np.isfinite(catenary_spec_form(0.04, 50.0, 60.0, W_LARGE, 48.0)))


def test_stays_finite_beyond_any_physical_cable():
    length, rise = catenary(1e-3, 500.0, 10.0, W_LARGE)  # beta = 7100: capped
    assert np.isfinite(length) and np.isfinite(rise) and length > 1e100


def test_massless_limit_is_the_straight_cable_and_vertical_length_is_the_rise():
    """w -> 0: the straight cable (l = L T0 / H, rise = L V / H); near-vertical: l -> rise."""
    H, V, L = 500.0, 300.0, 100.0
    length, rise = catenary(H, V, L, 1e-12)
    assert length == pytest.approx(L * np.hypot(H, V) / H, rel=1e-9)
    assert rise == pytest.approx(L * V / H, rel=1e-9)
    length, rise = catenary(1e-2, 400.0, 1e-6, W_LARGE)  # span 1 um under 0.01 N horizontal
    assert length == pytest.approx(rise, rel=1e-6) and rise > 0


@pytest.mark.parametrize("H, V, L, w", [(600.0, 70.0, 150.0, W_LARGE), (20.0, 10.0, 8.0, W_SMALL),
                                        (900.0, 200.0, 0.01, W_LARGE), (5000.0, 1.0, 200.0, W_LARGE)])
def test_jacobians_match_central_differences(H, V, L, w):
    x = np.array([H, V, L])
    _, _, d_length, d_rise = catenary(H, V, L, w, jacobian=True)
    for j in range(3):
        h = 1e-4 * max(1.0, abs(x[j]))
        plus = np.array(catenary(*(x + h * np.eye(3)[j]), w))
        minus = np.array(catenary(*(x - h * np.eye(3)[j]), w))
        numeric = (plus - minus) / (2 * h)
        assert d_length[j] == pytest.approx(numeric[0], rel=1e-6, abs=1e-9)
        assert d_rise[j] == pytest.approx(numeric[1], rel=1e-6, abs=1e-9)


def test_vectorized_over_cables_equals_one_cable_at_a_time():
    H, V, L = np.array([600.0, 700.0]), np.array([70.0, 90.0]), np.array([150.0, 160.0])
    length, rise = catenary(H, V, L, W_LARGE)
    for i in range(2):
        assert (length[i], rise[i]) == pytest.approx(catenary(H[i], V[i], L[i], W_LARGE))
