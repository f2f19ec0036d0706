"""Factor types of a differential drive (docs/models/wheels.md#factors): per state interval, one factor
per wheel encoder (`wheels.encoder`), the gyro (`wheels.gyro`) and the no-sideways-motion constraint
(`wheels.nonholonomic`); or the driven wheels preintegrated over the interval between sparser states
(`wheels.preintegrated`). States are Pose2 (the axle midpoint); intrinsics are the diff_drive
description's parameters, read at the interval's first state (time-varying ones too)."""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (DataError, FactorExample, FactorType, NAME_SCHEMA as NAME, POSITIVE_SCHEMA as SIGMA, SCALAR,
                           Spec, gaussian)

from .kinematics import GYRO, IMU_GYRO, driven_twist, gyro_integrals, gyro_turns, increments, inside, wheel_column
from .model import AXLE, GYRO_BIAS, GYRO_SCALE, PASSIVE_OFFSET, RADIUS, RADIUS_LEFT, RADIUS_RIGHT, drive_of
from .preintegration import preintegrate, preintegrated_residual
from .residuals import encoder_residual, gyro_residual, lateral_residual, over_read

EVERY = {"type": "integer", "minimum": 1, "default": 1}


def _xyt(values: gtsam.Values, key: int) -> tuple[float, float, float]:
    p = values.atPose2(key)
    return p.x(), p.y(), p.theta()


def check_drive_entry(spec: Spec, scope):
    """A diff_drive robot with Pose2 states; returns its description."""
    desc = scope.require_model(spec, "robot", "diff_drive")
    scope.require_states(spec, "robot", "pose2")
    return desc


def require_wheels(spec: Spec, scope, drive, wheels) -> None:
    """Error unless the entry's stream has the column of each of `wheels` (named by the description's
    `joints`, or `left`/`right`/`passive`)."""
    have = scope.stream_columns[spec["stream"]]
    for wheel in wheels:
        column = drive.columns[wheel]
        if column != wheel and column not in have:
            origin = scope.stream_origins.get(spec["stream"])
            raise spec.error("stream", f"robot {spec['robot']!r} names joint {column!r} for its {wheel} wheel "
                             f"(joints.{wheel}); stream {spec['stream']!r}{f' ({origin})' if origin else ''} has no "
                             f"such column; it has {', '.join(have) or '(none)'}")
    scope.require_columns(spec, "stream", tuple(drive.columns[w] for w in wheels))


def require_gyro(spec: Spec, scope, stream_key: str) -> None:
    """Error unless stream `spec[stream_key]` has a gyro: a wheel stream's `gyro` column or an IMU's `gz`."""
    have = scope.stream_columns[spec[stream_key]]
    if GYRO not in have and IMU_GYRO not in have:
        origin = scope.stream_origins.get(spec[stream_key])
        raise spec.error(stream_key, f"stream {spec[stream_key]!r}{f' ({origin})' if origin else ''} has neither "
                         f"column {GYRO!r} (a wheel stream's gyro) nor {IMU_GYRO!r} (an IMU's z rate); it has "
                         f"{', '.join(have) or '(none)'}")


def intervals(ctx, spec: Spec, stream=None) -> np.ndarray:
    """Indices k of the states whose interval (k-1, k) lies inside the stream (every interval without one);
    the intervals left out are counted in the report; DataError when none lies inside it."""
    states = ctx.state_set(spec["robot"], spec)
    ks = np.arange(1, len(states))
    if stream is None:
        return ks
    ok = inside(stream.t, states.t)
    kept = ks[ok[ks - 1] & ok[ks]]
    if len(ks) and not len(kept):
        raise DataError(f"{spec.label}: stream {stream.name!r} ({stream.origin or 'no origin'}) spans t = "
                        f"{stream.t[0]:.6f} .. {stream.t[-1]:.6f} s and the states of robot {spec['robot']!r} t = "
                        f"{states.t[0]:.6f} .. {states.t[-1]:.6f} s: no state interval lies inside the stream "
                        f"(expected streams on one clock that overlap)")
    if len(kept) < len(ks):
        ctx.note(f"{spec.label}: {len(ks) - len(kept)} of {len(ks)} state intervals of {spec['robot']!r} lie "
                         f"outside stream {stream.name!r} and get no factor from it")
    return kept


def drive_stream_intervals(ctx, spec: Spec):
    """(robot, its model.DiffDrive, the entry's stream, the robot's state set, the state intervals inside the stream:
    `intervals`) of a wheels entry."""
    robot = spec["robot"]
    stream = ctx.stream(spec["stream"])
    return robot, drive_of(ctx.robot(robot)), stream, ctx.state_set(robot, spec), intervals(ctx, spec, stream)


def parameter_key(ctx, spec: Spec, name: str, k: int) -> int:
    """Key of an intrinsic for the interval that starts at state k: a time-varying parameter is read at the
    last multiple of `parameter_every` (parameter.random_walk's `every`) at or before k."""
    every = spec["parameter_every"]
    return ctx.parameter(spec["robot"], name, k=k - k % every)


class Noises:
    """sigma * sqrt(dt) noise models of an entry, one per distinct interval length."""

    def __init__(self, ctx, spec: Spec, sigma: float):
        self.ctx, self.spec, self.sigma, self.made = ctx, spec, sigma, {}

    def __call__(self, dt: float) -> tuple[gtsam.noiseModel.Base, float]:
        step = round(float(dt), 9)
        if step not in self.made:
            s = self.sigma * np.sqrt(step)
            self.made[step] = (self.ctx.noise([s], self.spec), s)
        return self.made[step]


# --- wheels.encoder -------------------------------------------------------------------------------

def _encoder_error(side: float, angle: float, sigma: float, k: float | None, direction: int, has_lateral: bool,
                   has_slip: bool, this, values, H):
    """Keys: pose a, pose b, the wheel's radius, then (`has_lateral`) the axle length (side = +-1/2) or the
    passive offset (side = 1), then (`has_slip`) the interval's turn slip (rad). With `k`, over-runs in
    `direction` (residuals.over_read) are down-weighted."""
    keys = this.keys()
    lateral = side * values.atDouble(keys[3]) if has_lateral else 0.0
    slip = values.atDouble(keys[-1]) if has_slip else 0.0
    e, J = encoder_residual(_xyt(values, keys[0]), _xyt(values, keys[1]), values.atDouble(keys[2]), lateral, angle,
                            H is not None, slip)
    weight = 1.0
    if k is not None:
        e, weight = over_read(e, sigma, direction, k)
    if H is not None:
        H[0], H[1], H[2] = weight * J[0], weight * J[1], weight * J[2]
        if has_lateral:
            H[3] = (weight * side) * J[3]
        if has_slip:
            H[len(keys) - 1] = weight * J[4]
    return np.array([e])


def encoder_factor(keys: list[int], side: float, angle: float, noise, sigma: float,
                   over_read_k: float | None = None, direction: int = 0, has_lateral: bool = False,
                   has_slip: bool = False) -> gtsam.CustomFactor:
    """keys: pose a, pose b, radius[, lateral parameter (`has_lateral`)][, turn slip (`has_slip`)]."""
    return gtsam.CustomFactor(noise, keys, partial(_encoder_error, side, float(angle), sigma, over_read_k, direction,
                                                   has_lateral, has_slip))


TURN_SLIP = "turn_slip"
SLIP_FLOOR = 100.0  # a Gaussian prior this many sigmas wide keeps a slip determined where only the wheels see the turn


def seeded_slips(ctx, spec: Spec, stream, ks: np.ndarray) -> np.ndarray:
    """Initial turn slips (rad) of the intervals ending at states ks: the driven wheels' turn minus the gyro's
    (both at the description's values: a calibrated gyro) where they differ by more than `seed_rate` (rad/s)
    times the interval, else 0."""
    robot = spec["robot"]
    drive = drive_of(ctx.robot(robot))
    t = ctx.state_set(robot, spec).t
    slip = driven_twist(stream, drive, t)[1] - gyro_turns(stream, drive, t)
    return np.where(np.abs(slip) > spec["turn_slip"]["seed_rate"] * np.diff(t), slip, 0.0)[ks - 1]


def turn_slips(ctx, spec: Spec, ks: np.ndarray, stream) -> list[int]:
    """One scalar variable per state interval (k-1, k): how much further (rad) the driven wheels turned the
    robot than its body turned, with a Geman-McClure prior at 0 (`turn_slip: {sigma, k}`: rad per interval,
    and the kernel's width in sigmas) and a Gaussian floor SLIP_FLOOR times wider: zero unless another sensor
    (the gyro) contradicts the wheels' turn, and then a bounded cost whose pull on the poses vanishes. Its
    initial value is 0, or (`seed_rate`) seeded_slips."""
    robot, cfg = spec["robot"], spec["turn_slip"]
    core = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.GemanMcClure.Create(cfg["k"]),
                                          gtsam.noiseModel.Isotropic.Sigma(1, cfg["sigma"]))
    floor = gtsam.noiseModel.Isotropic.Sigma(1, SLIP_FLOOR * cfg["sigma"])
    seeds = seeded_slips(ctx, spec, stream, ks) if "seed_rate" in cfg else np.zeros(len(ks))
    keys = []
    for k, seed in zip(ks.tolist(), seeds.tolist()):
        key = ctx.state_variable(robot, TURN_SLIP, SCALAR, k, float(seed))
        t = ctx.state_time(robot, k)
        ctx.add(gtsam.PriorFactorDouble(key, 0.0, core), spec, t, part="turn-slip prior")
        ctx.add(gtsam.PriorFactorDouble(key, 0.0, floor), spec, t, part="turn-slip prior")
        keys.append(key)
    return keys


def turn_direction(angle: float, sigma: float) -> int:
    """The sign of a wheel's turn (rad) when it exceeds 3 sigma, else 0 (a wheel at rest, up to noise, cannot
    over-run)."""
    return int(np.sign(angle)) if abs(angle) > 3.0 * sigma else 0


def _own(spec: Spec, parameters: list[str], *names: str) -> bool:
    """Whether the group `parameters` (full names) holds each of this entry's robot's `names`."""
    return all(f"{spec['robot']}/{name}" in parameters for name in names)


class Encoder(FactorType):
    name = "wheels.encoder"
    summary = ("wheel encoders, one factor per wheel and state interval: angle increment = the wheel's forward "
               "travel / its radius (diff_drive; optionally down-weights readings that over-run the motion)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": SIGMA,
                             "wheels": {"type": "array", "items": {"enum": ["left", "right", "passive"]},
                                        "minItems": 1, "uniqueItems": True},
                             "over_read": SIGMA, "parameter_every": EVERY,
                             "turn_slip": {"type": "object",
                                           "properties": {"sigma": SIGMA, "k": SIGMA, "seed_rate": SIGMA},
                                           "required": ["sigma", "k"], "additionalProperties": False}},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def separation_hint(self, spec: Spec, parameters: list[str]) -> str | None:
        """Radii scaled together with the path change no wheel reading: only a length measured otherwise fixes
        their common scale (a group with the axle length is the turn geometry instead: no hint)."""
        if _own(spec, parameters, RADIUS_LEFT, RADIUS_RIGHT) and not _own(spec, parameters, AXLE):
            return ("to fix the wheels' common scale: drive a measured distance, or add an absolute position "
                    "reference (pose.absolute); wheels and gyro cannot tell larger wheels from a longer path")
        return None

    def check(self, spec: Spec, scope) -> None:
        """`wheels` (default: every wheel the robot has) are wheels of the robot and columns of the stream."""
        drive = drive_of(check_drive_entry(spec, scope))
        wheels = spec["wheels"] if "wheels" in spec.data else list(drive.wheels)
        if "passive" in wheels and not drive.has_passive:
            raise spec.error("wheels", f"robot {spec['robot']!r} has no passive wheel (no parameter 'passive_radius')")
        if "turn_slip" in spec.data and "passive" in wheels:
            raise spec.error("turn_slip", "the passive wheel is turned by the floor and turns with the body: give "
                             "`turn_slip` on an entry of the driven wheels only (`wheels: [left, right]`)")
        if "seed_rate" in spec.data.get("turn_slip", {}):
            if not drive.has_gyro:
                raise spec.error(("turn_slip", "seed_rate"), f"robot {spec['robot']!r} has no gyro to seed slips from")
            require_gyro(spec, scope, "stream")
        require_wheels(spec, scope, drive, wheels)

    def build(self, ctx, spec: Spec) -> None:
        """sigma: rad/sqrt(s) of a wheel's angle; a factor's sigma is sigma * sqrt(dt)."""
        robot = spec["robot"]
        drive = drive_of(ctx.robot(robot))
        stream = ctx.stream(spec["stream"])
        states = ctx.state_set(robot, spec)
        ks = intervals(ctx, spec, stream)
        noises = Noises(ctx, spec, spec["sigma"])
        dts = states.t[ks] - states.t[ks - 1]
        pose_keys = ctx.state_keys(robot, np.column_stack([ks - 1, ks]).ravel())
        slips = turn_slips(ctx, spec, ks, stream) if "turn_slip" in spec.data else None
        for wheel in (spec["wheels"] if "wheels" in spec.data else drive.wheels):
            angles = increments(stream.t, wheel_column(stream, drive, wheel), states.t)[ks - 1]
            lateral = {"left": (AXLE, 0.5), "right": (AXLE, -0.5)}.get(wheel, (PASSIVE_OFFSET, 1.0))
            has_lateral = lateral[0] in ctx.robot(robot).parameters
            for i, (k, angle, dt) in enumerate(zip(ks.tolist(), angles.tolist(), dts.tolist())):
                keys = pose_keys[2 * i:2 * i + 2] + [parameter_key(ctx, spec, RADIUS[wheel], k - 1)]
                if has_lateral:
                    keys.append(parameter_key(ctx, spec, lateral[0], k - 1))
                if slips is not None:
                    keys.append(slips[i])
                noise, sigma = noises(dt)
                ctx.add(encoder_factor(keys, lateral[1], angle, noise, sigma, spec.get("over_read"),
                                       turn_direction(angle, sigma), has_lateral, slips is not None),
                        spec, float(states.t[k]))

    @classmethod
    def example(cls, rng):
        """A random motion, radius, axle (or offset), and the angle that makes the residual zero; half the
        examples with the over-read loss (perturbed values fall on either of its branches), half with a turn
        slip."""
        a = rng.normal(scale=[1.0, 1.0, 2.0])
        b = a + rng.normal(scale=[0.05, 0.05, 0.3])
        radius, length = rng.uniform(0.05, 0.1), rng.uniform(0.1, 0.6)
        side = rng.choice([0.5, -0.5, 1.0])
        slip = rng.normal(scale=0.05) if rng.uniform() < 0.5 else None
        angle, _ = encoder_residual(a, b, radius, side * length, 0.0, slip=slip or 0.0)
        values = gtsam.Values()
        for key, v in enumerate((gtsam.Pose2(*a), gtsam.Pose2(*b), radius, length) + ((slip,) if slip is not None else ())):
            values.insert(key, v)
        factor = encoder_factor(list(range(4 + (slip is not None))), side, angle, gaussian([0.02]), 0.02,
                                1.0 if rng.uniform() < 0.5 else None, int(np.sign(angle)), True, slip is not None)
        return FactorExample(factor, values, perturbation=0.01)  # the radius stays well above 0


# --- wheels.gyro ----------------------------------------------------------------------------------

def _gyro_error(integral: float, dt: float, this, values, H):
    keys = this.keys()
    e, J = gyro_residual(_xyt(values, keys[0]), _xyt(values, keys[1]), values.atDouble(keys[2]),
                         values.atDouble(keys[3]), integral, dt, H is not None)
    if H is not None:
        H[0], H[1], H[2], H[3] = J
    return np.array([e])


def gyro_factor(keys: list[int], integral: float, dt: float, noise) -> gtsam.CustomFactor:
    return gtsam.CustomFactor(noise, keys, partial(_gyro_error, float(integral), float(dt)))


class Gyro(FactorType):
    name = "wheels.gyro"
    summary = ("z gyro per state interval: heading change = gyro_scale * integrated reading + gyro_bias * dt "
               "(diff_drive; the wheel stream's gyro column or an IMU stream's gz; the bias may drift: "
               "parameter.random_walk)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": SIGMA, "parameter_every": EVERY},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def separation_hint(self, spec: Spec, parameters: list[str]) -> str | None:
        """A longer axle turns the robot less per wheel reading, a larger gyro scale more per gyro reading: wheels
        and gyro see only their ratio, and whatever else changes the heading (a slip in fast turns) moves it."""
        if _own(spec, parameters, AXLE, GYRO_SCALE):
            return ("to separate axle length and gyro scale: turn both ways at several turn rates, slow turns too "
                    "(a slip in fast turns is then seen against the gyro instead of absorbed by its scale), or add "
                    "an absolute heading or pose reference (pose.absolute)")
        if _own(spec, parameters, GYRO_SCALE, GYRO_BIAS):
            return ("to separate gyro scale and bias: turn both ways (the scale changes sign with the turn, the bias "
                    "does not) and stand still for a while (the bias alone)")
        return None

    def check(self, spec: Spec, scope) -> None:
        if not drive_of(check_drive_entry(spec, scope)).has_gyro:
            raise spec.error("robot", f"robot {spec['robot']!r} has no gyro: its description needs parameters "
                             f"{GYRO_SCALE!r} and {GYRO_BIAS!r}")
        require_gyro(spec, scope, "stream")

    def build(self, ctx, spec: Spec) -> None:
        """sigma: rad/sqrt(s) of the integrated reading (angle random walk in the gyro's own units); a
        factor's sigma is sigma * sqrt(dt). The stream's `gyro` column holds interval means, its `gz`
        column (an IMU stream) instantaneous samples, integrated by the trapezoid rule (kinematics.py)."""
        robot = spec["robot"]
        stream = ctx.stream(spec["stream"])
        states = ctx.state_set(robot, spec)
        ks = intervals(ctx, spec, stream)
        integrals = gyro_integrals(stream, states.t)[ks - 1]
        dts = states.t[ks] - states.t[ks - 1]
        pose_keys = ctx.state_keys(robot, np.column_stack([ks - 1, ks]).ravel())
        noises = Noises(ctx, spec, spec["sigma"])
        for i, (k, integral, dt) in enumerate(zip(ks.tolist(), integrals.tolist(), dts.tolist())):
            keys = pose_keys[2 * i:2 * i + 2] + [parameter_key(ctx, spec, GYRO_SCALE, k - 1),
                                                 parameter_key(ctx, spec, GYRO_BIAS, k - 1)]
            ctx.add(gyro_factor(keys, integral, dt, noises(dt)[0]), spec, float(states.t[k]))

    @classmethod
    def example(cls, rng):
        a = rng.normal(scale=[1.0, 1.0, 2.0])
        b = a + rng.normal(scale=[0.05, 0.05, 0.3])
        scale, bias, dt = rng.uniform(0.7, 1.4), rng.normal(scale=0.05), rng.uniform(0.01, 0.2)
        integral = gyro_residual(a, b, scale, bias, 0.0, dt)[0]
        values = gtsam.Values()
        for key, v in enumerate((gtsam.Pose2(*a), gtsam.Pose2(*b), scale, bias)):
            values.insert(key, v)
        return FactorExample(gyro_factor([0, 1, 2, 3], integral, dt, gaussian([0.003])), values)


# --- wheels.nonholonomic ----------------------------------------------------------------------------

def _lateral_error(this, values, H):
    keys = this.keys()
    e, J = lateral_residual(_xyt(values, keys[0]), _xyt(values, keys[1]), H is not None)
    if H is not None:
        H[0], H[1] = J
    return np.array([e])


def lateral_factor(keys: list[int], noise) -> gtsam.CustomFactor:
    return gtsam.CustomFactor(noise, keys, _lateral_error)


class Nonholonomic(FactorType):
    name = "wheels.nonholonomic"
    summary = ("no sideways motion of the axle midpoint between consecutive states: the lateral component of "
               "Log(X_k-1^-1 X_k) is zero (Pose2 states)")
    robot_fields = ("robot",)
    schema = {"type": "object", "properties": {"robot": NAME, "sigma": SIGMA},
              "required": ["robot", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_states(spec, "robot", "pose2")

    def build(self, ctx, spec: Spec) -> None:
        """sigma: m/sqrt(s) of sideways slip; a factor's sigma is sigma * sqrt(dt)."""
        robot = spec["robot"]
        states = ctx.state_set(robot, spec)
        ks = intervals(ctx, spec)
        pose_keys = ctx.state_keys(robot, np.column_stack([ks - 1, ks]).ravel())
        noises = Noises(ctx, spec, spec["sigma"])
        for i, (k, dt) in enumerate(zip(ks.tolist(), (states.t[ks] - states.t[ks - 1]).tolist())):
            ctx.add(lateral_factor(pose_keys[2 * i:2 * i + 2], noises(dt)[0]), spec, float(states.t[k]))

    @classmethod
    def example(cls, rng):
        a = gtsam.Pose2(*rng.normal(scale=[1.0, 1.0, 2.0]))
        b = a.compose(gtsam.Pose2.Expmap(np.array([rng.normal(scale=0.1), 0.0, rng.normal(scale=0.5)])))
        values = gtsam.Values()
        values.insert(0, a)
        values.insert(1, b)
        return FactorExample(lateral_factor([0, 1], gaussian([0.001])), values)


# --- wheels.preintegrated ---------------------------------------------------------------------------

def _preintegrated_error(keys: tuple, delta: tuple, jacobian: tuple, nominal: tuple, whiten: tuple, this, values, H):
    pi, pj = values.atPose2(keys[0]), values.atPose2(keys[1])
    theta = (values.atDouble(keys[2]), values.atDouble(keys[3]), values.atDouble(keys[4]))
    e, J = preintegrated_residual((pi.x(), pi.y(), pi.theta()), (pj.x(), pj.y(), pj.theta()), theta, delta, jacobian,
                                  nominal, whiten, H is not None)
    if H is not None:
        H[0], H[1], H[2], H[3], H[4] = J
    return e


def _as_tuples(a) -> tuple:
    """An array as (nested) tuples of floats: preintegrated_residual's scalar arithmetic."""
    a = np.asarray(a, float)
    return tuple(map(tuple, a.tolist())) if a.ndim == 2 else tuple(a.tolist())


def preintegrated_factor(keys: list[int], delta, jacobian, nominal, covariance, noise) -> gtsam.CustomFactor:
    """Keys: pose i, pose j, r_L, r_R, A. The residual is whitened by the window's covariance (its unit: sigmas)."""
    whiten = np.linalg.inv(np.linalg.cholesky(covariance))
    data = (_as_tuples(a) for a in (delta, jacobian, nominal, whiten))
    return gtsam.CustomFactor(noise, keys, partial(_preintegrated_error, tuple(keys), *data))


def sample_windows(stream_t: np.ndarray, state_t: np.ndarray, ks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sample boundaries of every interval (k-1, k): its two state times and the stream stamps inside;
    returns (boundaries, the interval each sub-interval belongs to (index into ks), -1 if none)."""
    lo, hi = state_t[ks[0] - 1], state_t[ks[-1]]
    bounds = np.union1d(state_t[ks[0] - 1:ks[-1] + 1], stream_t[(stream_t > lo) & (stream_t < hi)])
    start_state = np.searchsorted(state_t, bounds[:-1], side="right") - 1
    lookup = np.full(len(state_t), -1)
    lookup[ks - 1] = np.arange(len(ks))
    return bounds, lookup[start_state]


class Preintegrated(FactorType):
    name = "wheels.preintegrated"
    summary = ("driven-wheel odometry preintegrated between consecutive states, with its Jacobian in the wheel "
               "radii and axle length (drifting intrinsics; diff_drive)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "stream": NAME, "sigma": SIGMA, "lateral_sigma": SIGMA,
                             "parameter_every": EVERY},
              "required": ["robot", "stream", "sigma"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        require_wheels(spec, scope, drive_of(check_drive_entry(spec, scope)), ("left", "right"))

    def build(self, ctx, spec: Spec) -> None:
        """sigma: m/sqrt(s) of each wheel's travel; lateral_sigma: m/sqrt(s) of sideways slip (absent:
        sigma). Preintegrated at the description's nominal intrinsics."""
        robot, drive, stream, states, ks = drive_stream_intervals(ctx, spec)
        if len(ks) == 0:
            return
        bounds, window = sample_windows(stream.t, states.t, ks)
        used = window >= 0
        left, right = (increments(stream.t, wheel_column(stream, drive, w), bounds)[used]
                       for w in ("left", "right"))
        nominal = [drive.nominal[n] for n in (RADIUS_LEFT, RADIUS_RIGHT, AXLE)]
        pre = preintegrate(window[used], left, right, np.diff(bounds)[used], nominal, spec["sigma"],
                           spec.get("lateral_sigma", spec["sigma"]))
        noise = ctx.noise([1.0, 1.0, 1.0], spec)
        pose_keys = ctx.state_keys(robot, np.column_stack([ks - 1, ks]).ravel())
        for i, k in enumerate(ks.tolist()):
            keys = pose_keys[2 * i:2 * i + 2] + [parameter_key(ctx, spec, n, k - 1)
                                                 for n in (RADIUS_LEFT, RADIUS_RIGHT, AXLE)]
            ctx.add(preintegrated_factor(keys, pre.delta[i], pre.jacobian[i], pre.nominal, pre.covariance[i], noise),
                    spec, float(states.t[k]))

    @classmethod
    def example(cls, rng):
        """Ten samples of random wheel increments; intrinsics away from the preintegration point."""
        nominal = np.array([rng.uniform(0.03, 0.06), rng.uniform(0.03, 0.06), rng.uniform(0.2, 0.4)])
        theta = nominal * rng.uniform(0.97, 1.03, 3)
        left, right = rng.uniform(-0.5, 2.0, 10), rng.uniform(-0.5, 2.0, 10)
        window = np.zeros(10, dtype=int)
        pre = preintegrate(window, left, right, np.full(10, 0.05), nominal, 0.002, 0.001)
        xi = gtsam.Pose2(*rng.normal(scale=[1.0, 1.0, 2.0]))
        delta = gtsam.Pose2(*pre.delta[0]).compose(gtsam.Pose2.Expmap(pre.jacobian[0] @ (theta - nominal)))
        values = gtsam.Values()
        for key, v in enumerate((xi, xi.compose(delta), *theta.tolist())):
            values.insert(key, v)
        return FactorExample(preintegrated_factor([0, 1, 2, 3, 4], pre.delta[0], pre.jacobian[0], pre.nominal,
                                                  pre.covariance[0], gaussian([1.0] * 3)), values, perturbation=0.02)


FACTOR_TYPES = [Encoder, Gyro, Nonholonomic, Preintegrated]
