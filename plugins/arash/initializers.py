"""Initial base-to-base transform of two co-registered RCM arms."""

from __future__ import annotations

import gtsam
import numpy as np

from fusionkit.api import TOLERANCE_SCHEMA, Initializer, Spec, nearest

from .factors import columns_schema, check_pair, measurements
from .kinematics import tip_position
from .model import PARAMETERS, convention_of

MIN_SPREAD = 1e-6  # of the tips' second principal extent, relative to the first: below it they lie on a line


class BaseTransform(Initializer):
    name = "rcm.base_transform"
    summary = ("initial other/base_in_<robot> of two co-registered rcm_arms: rigid fit of the other arm's tips onto "
               "robot's tips plus the tool-to-tool offsets (current joint and parameter guesses)")
    robot_fields = ("robot", "other")
    stream_fields = ("stream",)
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "other": {"type": "string"}, "stream": {"type": "string"},
                             "columns": columns_schema(["dx", "dy", "dz"]), "tolerance": TOLERANCE_SCHEMA},
              "required": ["robot", "other", "stream"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        check_pair(spec, scope)
        scope.require_columns(spec, "stream", tuple(spec["columns"]))

    def initialize(self, ctx, spec: Spec) -> None:
        a, b = spec["robot"], spec["other"]
        base = ctx.base_transform(b, a, declare=False)
        if base is None:
            raise spec.error("other", f"no rcm.tool_to_tool or rcm.base_pose factor links {a!r} and {b!r}")
        stream = ctx.stream(spec["stream"])
        match_a = nearest(ctx.state_set(a, spec).t, stream.t, spec["tolerance"])
        match_b = nearest(ctx.state_set(b, spec).t, stream.t, spec["tolerance"])
        rows = np.intersect1d(match_a.row, match_b.row)
        ka = dict(zip(match_a.row.tolist(), match_a.state.tolist()))
        kb = dict(zip(match_b.row.tolist(), match_b.state.tolist()))
        convention = convention_of(ctx.robot(a))
        tips_a = np.array([self._tip(ctx, a, ka[r], convention) for r in rows.tolist()]).reshape(-1, 3)
        tips_b = np.array([self._tip(ctx, b, kb[r], convention) for r in rows.tolist()]).reshape(-1, 3)
        spread = np.linalg.svd(tips_b - tips_b.mean(axis=0), compute_uv=False) if len(rows) >= 3 else np.zeros(2)
        if spread[1] <= MIN_SPREAD * max(spread[0], 1e-300):
            raise spec.error("stream", f"stream {stream.name!r} pairs {len(rows)} configurations of {a!r} and {b!r} "
                             "whose tips do not span a plane: the transform needs three or more tips off one line")
        seen = tips_a + measurements(ctx, spec)[rows]  # b's tips in a's base frame
        ctx.set_initial(base, gtsam.Pose3.Align(seen.T, tips_b.T))

    @staticmethod
    def _tip(ctx, robot: str, k: int, convention: str) -> np.ndarray:
        q = ctx.initial_value(ctx.state_key(robot, k))
        params = [ctx.initial_value(ctx.parameter(robot, name, k=k)) for name in PARAMETERS]
        return tip_position(q, np.array(params, float), convention)


INITIALIZERS = [BaseTransform]
