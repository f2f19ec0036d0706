"""Factor types of the e-puck plugin (docs/models/epuck.md): `epuck.ir`, the IR proximity readings of a
state against a known wall map, and `epuck.velocity_motion`, the velocity motion model between
consecutive states from the commanded speeds."""

from __future__ import annotations

from functools import partial

import gtsam
import numpy as np

from fusionkit.api import (FactorExample, FactorType, NAME_SCHEMA as NAME, NON_NEGATIVE_SCHEMA as NONNEG,
                           POSE_SIGMA_SCHEMA, Spec, TOLERANCE_SCHEMA, gaussian, held_intervals)

from .evaluator import IrEntryEvaluator
from .irfactor import FAR, IN, NEAR, NOISE_MODES, IrModelContext, ReadingSet
from .model import alphas, ir_layout, ir_sensor_names, shipped_layout, walls_of
from .velocity import preintegrate
from .walls import box_walls, sensor_distances

ALPHA = {"type": "array", "items": NONNEG, "minItems": 4, "maxItems": 6}
INPUT = {"enum": ["twist", "wheels"], "default": "twist"}
FLOOR_DEFAULT = {"rotation": 1e-3, "translation": 1e-4}  # per sqrt(s): rad, m


# ------------------------------------------------------------------------------------------ epuck.ir

def ir_factor(evaluator: IrEntryEvaluator, i: int, noise) -> gtsam.CustomFactor:
    """Factor i of an entry's evaluator: one state's readings, on its pose (and gains and offsets)."""
    return gtsam.CustomFactor(noise, evaluator.keys[i], partial(evaluator.error, i))


def classify(bank, sensor: np.ndarray, z: np.ndarray, gain: np.ndarray, offset: np.ndarray) -> tuple:
    """(kind, threshold) of readings z of layout sensors `sensor`, at the nominal gain and offset."""
    far = gain * bank.far_threshold[sensor] + offset
    near = gain * bank.near_threshold[sensor] + offset
    kind = np.where(z < far, FAR, np.where(z > near, NEAR, IN))
    return kind, np.where(kind == NEAR, near, far)


def reading_set(bank, z: np.ndarray, g0: np.ndarray, o0: np.ndarray, noise: str,
                out_of_range: str) -> ReadingSet | None:
    """One state's readings z (S,) (NaN: none) classified at the nominal gains and offsets; out-of-range
    ones kept (censored) or dropped; None when nothing is left."""
    sensor = np.flatnonzero(np.isfinite(z))
    kind, threshold = classify(bank, sensor, z[sensor], g0[sensor], o0[sensor])
    if out_of_range == "drop":
        sensor, kind, threshold = sensor[kind == IN], kind[kind == IN], threshold[kind == IN]
    if not len(sensor):
        return None
    sigma = np.ones(len(sensor))
    if noise == "at_reading":  # the sigma at the distance the reading's inverse lookup gives, held fixed
        d, _ = bank.inverse(((z - o0) / g0)[None, :])
        ev = bank.evaluate(np.where(np.isnan(d[0]), bank.d_max, d[0]))
        sigma = np.where(kind == IN, np.sqrt(ev.var[sensor]), 1.0)
    return ReadingSet(sensor, z[sensor], kind, threshold, sigma)


class IrProximity(FactorType):
    name = "epuck.ir"
    summary = ("e-puck IR proximity readings against a known wall map: z ~ N(g F_mean(d) + o, F_var(d)), d along "
               "each sensor's axis (heteroscedastic, exact negative log-likelihood); out-of-range readings censored")
    robot_fields = ("robot", "map")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": NAME, "map": NAME, "stream": NAME,
                             "sensors": {"type": "array", "items": NAME, "minItems": 1, "uniqueItems": True},
                             "columns": {"type": "array", "items": NAME, "minItems": 1},
                             "noise": {"enum": list(NOISE_MODES), "default": "full"},
                             "out_of_range": {"enum": ["censored", "drop"], "default": "censored"},
                             "gain": NAME, "offset": NAME, "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "map", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        """An epuck robot with pose2 states, a wall_map; named sensors are its ir_proximity sensors, one
        column each; gain and offset parameters are scalars with one value per IR sensor of the robot."""
        desc = scope.require_model(spec, "robot", "epuck")
        scope.require_model(spec, "map", "wall_map")
        scope.require_states(spec, "robot", "pose2")
        names = ir_sensor_names(desc)
        if not names:
            raise spec.error("robot", f"robot {spec['robot']!r} has no ir_proximity sensor")
        for name in spec.get("sensors", []):
            if name not in names:
                raise spec.error("sensors", f"{name!r} is not an ir_proximity sensor of robot {spec['robot']!r}; "
                                 f"it has: {', '.join(names)}")
        used = spec.get("sensors") or names
        columns = spec.get("columns") or used
        if len(columns) != len(used):
            raise spec.error("columns", f"{len(columns)} columns for {len(used)} sensors ({', '.join(used)})")
        scope.require_columns(spec, "stream", tuple(columns))
        for key in ("gain", "offset"):
            if key in spec.data:
                scope.require_parameter(spec, "robot", key, "scalar")
                count = desc.parameters[spec[key]].count
                if count != len(names):
                    raise spec.error(key, f"{spec['robot']}/{spec[key]} has {count} value(s); expected one per IR "
                                     f"sensor of the robot ({len(names)}: {', '.join(names)})")

    def build(self, ctx, spec: Spec) -> None:
        """One factor per state with readings; readings that are NaN are skipped."""
        robot = spec["robot"]
        desc = ctx.robot(robot)
        everyone = ir_sensor_names(desc)
        layout = ir_layout(desc, spec.get("sensors"))
        model = IrModelContext(walls_of(ctx.robot(spec["map"])), layout.mounts, layout.angles, layout.bank,
                               spec["noise"])
        stream = ctx.stream(spec["stream"])
        z_all = np.column_stack([stream.column(c) for c in spec.get("columns") or layout.names])
        index = np.array([everyone.index(n) for n in layout.names])  # into the description's parameters
        nominal = {key: np.array([float(v) for v in desc.parameters[spec[key]].values])[index]
                   for key in ("gain", "offset") if key in spec.data}
        g0, o0 = nominal.get("gain", np.ones(len(index))), nominal.get("offset", np.zeros(len(index)))
        a = ctx.associate(stream, robot, spec)
        counts, sets, keys, states = np.zeros(3, int), [], [], []
        for k, row in zip(a.state.tolist(), a.row.tolist()):
            readings = reading_set(layout.bank, z_all[row], g0, o0, spec["noise"], spec["out_of_range"])
            if readings is None:
                continue
            counts += np.bincount(readings.kind, minlength=3)
            s = index[readings.sensor]
            gains = [ctx.parameter(robot, spec["gain"], int(i), k) for i in s] if "gain" in spec.data else []
            offsets = [ctx.parameter(robot, spec["offset"], int(i), k) for i in s] if "offset" in spec.data else []
            sets.append(readings)
            keys.append([ctx.pose_key(robot, k)] + gains + offsets)
            states.append(k)
        evaluator = IrEntryEvaluator(model, sets, keys, ("gain" in spec.data, "offset" in spec.data))
        for i, (k, readings) in enumerate(zip(states, sets)):
            noise = ctx.noise([1.0] * len(readings.rows(spec["noise"])[0]), spec)
            ctx.add(ir_factor(evaluator, i, noise), spec, ctx.state_time(robot, k))
        ctx.note(f"{spec.label}: {counts[IN]} IR readings in range, {counts[FAR]} beyond it (nothing "
                         f"within {layout.bank.d_max:g} m) and {counts[NEAR]} closer than {layout.bank.d_min:g} m"
                         + (" (censored)" if spec["out_of_range"] == "censored" else " (dropped)"))

    @classmethod
    def example(cls, rng):
        """Readings of all eight e-puck sensors exactly at their model mean in a walled box (in range,
        whitened: a residual that can vanish), with gains and offsets; tests check the censored rows and
        the log-variance term against numerical derivatives separately."""
        layout = shipped_layout()
        walls = box_walls(0.12, 0.10)
        model = IrModelContext(walls, layout.mounts, layout.angles, layout.bank, "whitened")
        pose = np.array([rng.uniform(0.055, 0.065), rng.uniform(0.045, 0.055), rng.uniform(-np.pi, np.pi)])
        gain, offset = rng.uniform(0.9, 1.1, layout.bank.size), rng.normal(0.0, 20.0, layout.bank.size)
        sensor = np.arange(layout.bank.size)
        readings = ReadingSet(sensor, np.zeros(len(sensor)), np.full(len(sensor), IN), np.zeros(len(sensor)),
                              np.ones(len(sensor)))
        d = sensor_distances(walls, pose[None], layout.mounts, layout.angles)[0]
        readings.z = gain * model.bank.evaluate(d).mean + offset
        values = gtsam.Values()
        values.insert(0, gtsam.Pose2(*pose))
        for j, v in enumerate(np.concatenate([gain, offset])):
            values.insert(1 + j, float(v))
        K = len(sensor)
        evaluator = IrEntryEvaluator(model, [readings], [list(range(1 + 2 * K))], (True, True))
        factor = ir_factor(evaluator, 0, gaussian([1.0] * K))
        return FactorExample(factor, values, perturbation=0.002)


# ------------------------------------------------------------------------------ epuck.velocity_motion

def commands(stream, spec: Spec, extra: dict) -> tuple[np.ndarray, np.ndarray]:
    """Commanded speed v (m/s) and turn rate omega (rad/s) per stream row: the `v`/`omega` columns, or
    (`input: wheels`) the wheels' angular speeds (rad/s) through the description's wheel radius and axle."""
    if spec["input"] == "wheels":
        r, axle = float(extra["wheel_radius"]), float(extra["axle_length"])
        right, left = r * stream.column(spec["right"]), r * stream.column(spec["left"])
        return 0.5 * (right + left), (right - left) / axle
    return stream.column(spec["v"]), stream.column(spec["omega"])


def motion_increments(state_t: np.ndarray, stream, v: np.ndarray, omega: np.ndarray, alpha: np.ndarray):
    """Per state interval: the commands held in it (sample and hold), integrated (Pose2, covariance)."""
    out = []
    for t0, t1 in zip(state_t[:-1], state_t[1:]):
        rows, dt = held_intervals(stream.t, float(t0), float(t1))
        out.append(preintegrate(v[rows], omega[rows], dt, alpha))
    return out


MOTION_SCHEMA = {"robot": NAME, "stream": NAME, "input": INPUT, "v": {**NAME, "default": "v"},
                 "omega": {**NAME, "default": "omega"}, "right": {**NAME, "default": "right"},
                 "left": {**NAME, "default": "left"}, "alpha": ALPHA}


def check_motion_entry(spec: Spec, scope) -> None:
    scope.require_model(spec, "robot", "epuck")
    scope.require_states(spec, "robot", "pose2")
    names = (spec["right"], spec["left"]) if spec["input"] == "wheels" else (spec["v"], spec["omega"])
    scope.require_columns(spec, "stream", names)
    if len(spec.get("alpha", [])) == 5:
        raise spec.error("alpha", "5 values: expected alpha1-4, or alpha1-6")


class VelocityMotion(FactorType):
    name = "epuck.velocity_motion"
    summary = ("velocity motion model between consecutive Pose2 states from commanded (v, omega): the arc, with "
               "the alpha1-6 control noise as a full body-frame covariance (native BetweenFactorPose2)")
    robot_fields = ("robot",)
    stream_fields = ("stream",)
    accepts_robust = False  # the noise comes from the model (a full covariance per interval)
    schema = {"type": "object",
              "properties": {**MOTION_SCHEMA,
                             "floor": {**POSE_SIGMA_SCHEMA, "default": FLOOR_DEFAULT}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_motion_entry(spec, scope)

    def build(self, ctx, spec: Spec) -> None:
        """Commands held until the next sample; per state interval the arc and its covariance, plus the
        floor (per sqrt(s), m and rad) that keeps it positive definite when the robot stands still."""
        robot = spec["robot"]
        extra = ctx.robot(robot).extra
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        v, omega = commands(stream, spec, extra)
        alpha = np.asarray(spec.get("alpha", alphas(extra)), float)
        floor = np.array([spec["floor"]["translation"]] * 2 + [spec["floor"]["rotation"]]) ** 2
        for k, (delta, cov) in enumerate(motion_increments(states.t, stream, v, omega, alpha), start=1):
            noise = gtsam.noiseModel.Gaussian.Covariance(cov + np.diag(floor * (states.t[k] - states.t[k - 1])))
            ctx.add(gtsam.BetweenFactorPose2(ctx.pose_key(robot, k - 1), ctx.pose_key(robot, k), delta, noise),
                    spec, ctx.state_time(robot, k))

    @classmethod
    def example(cls, rng):
        """A straight line (omega = 0) for half the seeds, an arc for the others."""
        return velocity_example(rng, 0.0 if rng.uniform() < 0.5 else rng.normal(0.0, 1.0))


def velocity_example(rng, omega: float) -> FactorExample:
    a = gtsam.Pose2(*rng.normal(size=3))
    v = np.full(3, rng.uniform(-0.1, 0.1))
    delta, cov = preintegrate(v, np.full(3, omega), np.full(3, 0.1), np.array([0.045, 8.8e-5, 0.0959, 0.118]))
    values = gtsam.Values()
    values.insert(0, a)
    values.insert(1, a.compose(delta))
    noise = gtsam.noiseModel.Gaussian.Covariance(cov + np.diag([1e-6, 1e-6, 1e-4]))
    return FactorExample(gtsam.BetweenFactorPose2(0, 1, delta, noise), values)


FACTOR_TYPES = [IrProximity, VelocityMotion]
