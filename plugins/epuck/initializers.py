"""`epuck.dead_reckoning`: initial Pose2 states from the commanded speeds (the velocity model's mean),
optionally corrected state by state with the IR readings (sequential.py)."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import Initializer, NAME_SCHEMA as NAME, Spec, nearest

from .factors import (FLOOR_DEFAULT, MOTION_SCHEMA, check_motion_entry, commands, motion_increments, reading_set)
from .irfactor import IrModelContext
from .model import alphas, ir_layout, ir_sensor_names, walls_of
from .sequential import forward_pass

OUTLIER_K = 3.0  # the forward pass bounds each reading's pull (Cauchy, sigmas): a grazing ray must not jerk it


class DeadReckoning(Initializer):
    name = "epuck.dead_reckoning"
    summary = ("initial Pose2 states: the commanded (v, omega) integrated from the first state's current initial "
               "value (pose.origin); with `ir` and `map`, each pose corrected by its IR readings (an iterated EKF pass)")
    robot_fields = ("robot", "map")
    stream_fields = ("stream", "ir")
    schema = {"type": "object",
              "properties": {**{k: v for k, v in MOTION_SCHEMA.items()}, "ir": NAME, "map": NAME,
                             "sensors": {"type": "array", "items": NAME, "minItems": 1, "uniqueItems": True},
                             "columns": {"type": "array", "items": NAME, "minItems": 1},
                             "tolerance": {"type": "number", "minimum": 0, "default": 0.005}},
              "required": ["robot", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_motion_entry(spec, scope)
        if ("ir" in spec.data) != ("map" in spec.data):
            raise spec.error("ir" if "map" in spec.data else "map", "give both `ir` (the IR stream) and `map` (a "
                             "wall_map robot) to correct the poses with the IR readings, or neither")
        if "map" in spec.data:
            scope.require_model(spec, "map", "wall_map")
            desc = scope.robots[spec["robot"]]
            names = ir_sensor_names(desc)
            for name in spec.get("sensors", []):
                if name not in names:
                    raise spec.error("sensors", f"{name!r} is not an ir_proximity sensor of robot {spec['robot']!r}; "
                                     f"it has: {', '.join(names) or '(none)'}")
            used = spec.get("sensors") or names
            scope.require_columns(spec, "ir", tuple(spec.get("columns") or used))

    def initialize(self, ctx, spec: Spec) -> None:
        robot = spec["robot"]
        desc = ctx.robot(robot)
        states = ctx.state_set(robot, spec)
        stream = ctx.stream(spec["stream"])
        v, omega = commands(stream, spec, desc.extra)
        floor = np.array([FLOOR_DEFAULT["translation"]] * 2 + [FLOOR_DEFAULT["rotation"]]) ** 2
        alpha = np.asarray(spec.get("alpha", alphas(desc.extra)), float)
        increments = [(delta, cov + np.diag(floor * (t1 - t0))) for (delta, cov), t0, t1 in
                      zip(motion_increments(states.t, stream, v, omega, alpha), states.t[:-1], states.t[1:])]
        first = states.key(0)
        start = ctx.initial_value(first) if ctx.has_variable(first) else gtsam.Pose2()
        model, readings = None, [None] * len(states)
        if "map" in spec.data:
            layout = ir_layout(desc, spec.get("sensors"))
            model = IrModelContext(walls_of(ctx.robot(spec["map"])), layout.mounts, layout.angles, layout.bank,
                                   "full", OUTLIER_K)
            ir = ctx.stream(spec["ir"])
            z = np.column_stack([ir.column(c) for c in spec.get("columns") or layout.names])
            ones, zeros = np.ones(len(layout.names)), np.zeros(len(layout.names))
            a = nearest(states.t, ir.t, spec["tolerance"])
            for k, row in zip(a.state.tolist(), a.row.tolist()):
                readings[k] = reading_set(layout.bank, z[row], ones, zeros, "full", "censored")
        poses = forward_pass(start, increments, readings, model, np.diag(floor))
        for key, p in zip(states.family.keys(range(len(states))), poses):
            if ctx.has_variable(key):
                ctx.set_initial(key, p)


INITIALIZERS = [DeadReckoning]
