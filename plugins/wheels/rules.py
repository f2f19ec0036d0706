"""Rule-based dead reckoning of a differential drive with a passive middle wheel and a gyro: the
baselines of docs/models/wheels.md#baselines.

Every rule turns per-step wheel-contact speeds (`WheelSteps`: m/s, each held over its interval dt)
into a forward speed V (m/s) and a turn rate omega (rad/s) per step; `arc_path` (fusionkit.api) composes them into
poses (x, y in m, theta in rad; exact arcs). The named functions return the (N + 1, 3) poses of N
steps, starting at `start`:

    odometry       V = V_RL, omega = omega_RL
    gyrodometry    Borenstein & Feng (1996), eq. 1: omega from the gyro where it disagrees with the
                   driven wheels by more than omega_thres, else from the wheels; V = V_RL
    first_version  the passive-wheel paper's eq. 2
    minimal_gyro   the paper's minimal use of the gyro: two agreeing wheels give omega
    final_version  the paper's final algorithm with the reconstructed gyro (exact rules: its docstring)

Speeds at the axle midpoint from a pair of wheels, with the passive wheel at lateral offset p from the
midpoint (m, positive towards the left wheel; the paper's robot has p = 0) and axle length A: a wheel
at lateral position y rolls at V - omega * y, so

    right + left    omega_RL = (V_R - V_L) / A              V_RL = (V_R + V_L) / 2
    right + middle  omega_RM = (V_R - V_M) / (A/2 + p)      V_RM = V_M + p * omega_RM
    middle + left   omega_ML = (V_M - V_L) / (A/2 - p)      V_ML = V_M + p * omega_ML

and the passive wheel alone gives V_mid = V_M + p * omega_RL (V_M itself when p = 0), which every rule
compares with V_RL ("the three wheels agree").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusionkit.api import arc_path, differential_drive_twist

V_THRES = 0.01        # m/s: V_mid and V_RL "agree" below this
OMEGA_THRES = 0.05    # rad/s: a wheel-derived turn rate and the gyro "agree" below this
D_OMEGA_THRES = 0.5   # rad/s: a change between two gyro samples above this is an impact
DV_THRES = 0.02       # m/s: the passive wheel "jumped" when V_mid exceeds the last accepted V by more


@dataclass(frozen=True)
class WheelSteps:
    """N steps of a differential drive: interval dt (s) and the wheel-contact speeds held over it
    (m/s: angle increment * radius / dt), the gyro's z rate (rad/s) or None, the axle length A (m)
    and the passive wheel's lateral offset from the axle midpoint (m, towards the left wheel)."""

    dt: np.ndarray
    left: np.ndarray
    right: np.ndarray
    axle_length: float
    middle: np.ndarray | None = None
    gyro: np.ndarray | None = None
    passive_offset: float = 0.0

    def need(self, *names: str) -> None:
        missing = [n for n in names if getattr(self, n) is None]
        if missing:
            raise ValueError(f"this rule needs the {' and '.join(missing)} readings; the steps have none")

    @property
    def rl(self) -> tuple[np.ndarray, np.ndarray]:
        """(V_RL, omega_RL): the driven wheels."""
        return differential_drive_twist(self.right, self.left, self.axle_length)

    @property
    def rm(self) -> tuple[np.ndarray, np.ndarray]:
        """(V_RM, omega_RM): the right and the passive wheel."""
        w = (self.right - self.middle) / (0.5 * self.axle_length + self.passive_offset)
        return self.middle + self.passive_offset * w, w

    @property
    def ml(self) -> tuple[np.ndarray, np.ndarray]:
        """(V_ML, omega_ML): the passive and the left wheel."""
        w = (self.middle - self.left) / (0.5 * self.axle_length - self.passive_offset)
        return self.middle + self.passive_offset * w, w

    def passive_speed(self, omega):
        """V_M + p * omega: the passive wheel's speed carried to the axle midpoint at turn rate omega."""
        return self.middle + self.passive_offset * omega

    @property
    def v_mid(self) -> np.ndarray:
        """V_mid = V_M + p * omega_RL: the passive wheel's speed at the driven wheels' turn rate."""
        return self.passive_speed(self.rl[1])


def odometry(steps: WheelSteps, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Plain odometry of the driven wheels: V_RL, omega_RL."""
    return arc_path(*steps.rl, steps.dt, start)


def gyrodometry_rates(steps: WheelSteps, omega_thres: float = OMEGA_THRES, reconstruct: bool = False,
                      d_omega_thres: float = D_OMEGA_THRES, initial_rate: float = 0.0):
    """(V, omega) of gyrodometry (Borenstein & Feng 1996, eq. 1): omega = gyro where |gyro - omega_RL| >
    omega_thres (rad/s), else omega_RL; V = V_RL always. With `reconstruct`, the gyro is first
    replaced by its reconstruction (see `final_version`; `d_omega_thres`, `initial_rate` as there)."""
    steps.need("gyro")
    v, w_rl = steps.rl
    if not reconstruct:
        return v, np.where(np.abs(steps.gyro - w_rl) > omega_thres, steps.gyro, w_rl)
    omega = np.empty_like(w_rl)
    prev, g_prev = float(initial_rate), float(steps.gyro[0])
    for i, (g, w) in enumerate(zip(steps.gyro.tolist(), w_rl.tolist())):
        g_rec = reconstructed_gyro(prev, g - g_prev, (w,), d_omega_thres)
        prev = omega[i] = g_rec if abs(g_rec - w) > omega_thres else w
        g_prev = g
    return v, omega


def gyrodometry(steps: WheelSteps, omega_thres: float = OMEGA_THRES, reconstruct: bool = False,
                d_omega_thres: float = D_OMEGA_THRES, initial_rate: float = 0.0,
                start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses of gyrodometry (`gyrodometry_rates`)."""
    return arc_path(*gyrodometry_rates(steps, omega_thres, reconstruct, d_omega_thres, initial_rate),
                     steps.dt, start)


def first_version_rates(steps: WheelSteps, v_thres: float = V_THRES):
    """(V, omega) of the paper's eq. 2 (assumes real speed <= encoder speed, one faulty wheel at a time):
    |V_mid - V_RL| < v_thres: V_mid, omega_RL;  V_mid > V_RL: V_RL, gyro;  V_mid < V_RL: V_M + p gyro
    (the passive wheel at the gyro's rate; V_M when p = 0), gyro."""
    steps.need("middle", "gyro")
    v_rl, w_rl = steps.rl
    v_mid, g = steps.v_mid, steps.gyro
    agree = np.abs(v_mid - v_rl) < v_thres
    v = np.select([agree, v_mid > v_rl], [v_mid, v_rl], steps.passive_speed(g))
    return v, np.where(agree, w_rl, g)


def first_version(steps: WheelSteps, v_thres: float = V_THRES, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses of the paper's first version (`first_version_rates`)."""
    return arc_path(*first_version_rates(steps, v_thres), steps.dt, start)


def minimal_gyro_rates(steps: WheelSteps, v_thres: float = V_THRES, omega_thres: float = OMEGA_THRES):
    """(V, omega) of the paper's minimal use of the gyro ("if one wheel is in error, the other two give
    omega"): |V_mid - V_RL| < v_thres or V_mid > V_RL: omega_RL (with V_mid, resp. V_RL); V_mid < V_RL:
    (V_RM, omega_RM) if |gyro - omega_RM| < omega_thres, else (V_ML, omega_ML) if |gyro - omega_ML| <
    omega_thres, else (V_M + p gyro, gyro)."""
    steps.need("middle", "gyro")
    (v_rl, w_rl), (v_rm, w_rm), (v_ml, w_ml) = steps.rl, steps.rm, steps.ml
    v_mid, g = steps.v_mid, steps.gyro
    agree = np.abs(v_mid - v_rl) < v_thres
    low = ~agree & (v_mid < v_rl)
    use_rm = low & (np.abs(g - w_rm) < omega_thres)
    use_ml = low & ~use_rm & (np.abs(g - w_ml) < omega_thres)
    v = np.select([agree, ~low, use_rm, use_ml], [v_mid, v_rl, v_rm, v_ml], steps.passive_speed(g))
    omega = np.select([~low, use_rm, use_ml], [w_rl, w_rm, w_ml], g)
    return v, omega


def minimal_gyro(steps: WheelSteps, v_thres: float = V_THRES, omega_thres: float = OMEGA_THRES,
                 start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses of the paper's minimal-gyro version (`minimal_gyro_rates`)."""
    return arc_path(*minimal_gyro_rates(steps, v_thres, omega_thres), steps.dt, start)


def reconstructed_gyro(prev_omega: float, gyro_change: float, wheel_rates, d_omega_thres: float) -> float:
    """A cheap gyro's reading made usable (rad/s): the previously accepted turn rate plus the gyro's
    change since the previous sample; after an impact (|change| > d_omega_thres) instead the
    wheel-derived rate closest to the previously accepted one."""
    if abs(gyro_change) > d_omega_thres:
        return min(wheel_rates, key=lambda w: abs(w - prev_omega))
    return prev_omega + gyro_change


def final_version_rates(steps: WheelSteps, v_thres: float = V_THRES, omega_thres: float = OMEGA_THRES,
                        d_omega_thres: float = D_OMEGA_THRES, dv_thres: float = DV_THRES,
                        initial_rate: float = 0.0, initial_speed: float = 0.0):
    """(V, omega, reconstructed gyro) per step of the paper's final algorithm, as fusionkit states it.

    Step i, with V_prev, omega_prev the values accepted at step i-1 (`initial_speed`, `initial_rate`
    before the first step: by default the robot starts at rest):
    0. gyro reconstruction: g = omega_prev + (gyro_i - gyro_{i-1}) (gyro_{-1} = gyro_0); if that change
       exceeds d_omega_thres (an impact), g = whichever of omega_RL, omega_RM, omega_ML is closest to
       omega_prev.
    1. the wheels agree, |V_mid - V_RL| < v_thres: no wheel erred, V = V_mid, omega = omega_RL (which
       re-anchors the reconstructed gyro to the wheels).
    2. otherwise one hypothesis per faulty-wheel case, each giving (V, omega) from the wheels it trusts:
       V_mid < V_RL (the driven wheels read more than the passive one):
           left wheel over-reads (V_RM, omega_RM); right over-reads (V_ML, omega_ML); both driven wheels
           over-read alike, spinning or stuck (V_mid, omega_RL). The passive wheel is never suspected
           of under-reading: it turns by floor friction alone and keeps contact.
       V_mid > V_RL:
           left under-reads (V_RM, omega_RM); right under-reads (V_ML, omega_ML); omega_RL with V = V_RL
           if the passive wheel jumped (V_mid - V_prev > dv_thres: it over-reads, d_m > 0), else V_mid
           (both driven wheels under-read, e.g. sliding).
       Phase 1: the hypothesis whose omega is closest to g, if within omega_thres.
       Phase 2 (none is): omega = g, and V from the wheels the omega_RL hypothesis of the case trusts:
       V_RL, or the passive wheel at the gyro's rate, V_M + p g.
    """
    steps.need("middle", "gyro")
    (v_rl, w_rl), (v_rm, w_rm), (v_ml, w_ml) = steps.rl, steps.rm, steps.ml
    n = len(steps.dt)
    v_out, w_out, g_out = np.empty(n), np.empty(n), np.empty(n)
    v_prev, w_prev, g_prev = float(initial_speed), float(initial_rate), float(steps.gyro[0])
    p = steps.passive_offset
    rows = zip(v_rl.tolist(), w_rl.tolist(), v_rm.tolist(), w_rm.tolist(), v_ml.tolist(), w_ml.tolist(),
               steps.middle.tolist(), steps.gyro.tolist())
    for i, (vrl, wrl, vrm, wrm, vml, wml, vm, gyro) in enumerate(rows):
        g = reconstructed_gyro(w_prev, gyro - g_prev, (wrl, wrm, wml), d_omega_thres)
        vmid = vm + p * wrl
        if abs(vmid - vrl) < v_thres:
            v, w = vmid, wrl
        else:
            passive = vmid < vrl or vmid - v_prev <= dv_thres  # trust the passive wheel's speed
            v, w = min(((vrm, wrm), (vml, wml), (vmid if passive else vrl, wrl)), key=lambda h: abs(h[1] - g))
            if abs(w - g) >= omega_thres:
                v, w = (vm + p * g if passive else vrl), g
        v_out[i], w_out[i], g_out[i] = v, w, g
        v_prev, w_prev, g_prev = v, w, gyro
    return v_out, w_out, g_out


def final_version(steps: WheelSteps, v_thres: float = V_THRES, omega_thres: float = OMEGA_THRES,
                  d_omega_thres: float = D_OMEGA_THRES, dv_thres: float = DV_THRES, initial_rate: float = 0.0,
                  initial_speed: float = 0.0, start=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Poses of the paper's final algorithm (`final_version_rates`)."""
    v, omega, _ = final_version_rates(steps, v_thres, omega_thres, d_omega_thres, dv_thres, initial_rate,
                                      initial_speed)
    return arc_path(v, omega, steps.dt, start)
