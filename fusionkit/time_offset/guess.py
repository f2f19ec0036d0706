"""`time.offset_guess`: a first time offset from the data, before the graph refines it.

Both streams see the same motion: a pose stream its speed (m/s) or turn rate (rad/s; `signal: turn_rate`),
another stream the rate of change of its columns (cable lengths, ranges, joint angles; `signal: rate`), or
the size of its values when they are rates already (wheel speeds, gyro; `signal: magnitude`), each averaged
over `window` seconds (noise); `columns` / `reference_columns` pick the columns a signal uses (an IMU's gyro).
With the sample stamped t taken at t + delta on the reference's clock, the stream's motion signal m_s(t) equals the reference's m_r(t + delta) up to a
change of scale; delta is the shift that maximizes the correlation of the two standardized signals
(searched on the finer stream's sampling interval over +-max_offset, refined by a parabola through the
peak). A robot at rest, or moving at constant speed, shows no motion to align: the correlation stays low
and the offset is left at its description value, with a verdict saying so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..hookspecs import hookimpl
from ..components import Initializer, Spec
from ..data.stream import POSE_COLUMNS, Stream

SIGNALS = ("auto", "speed", "turn_rate", "rate", "magnitude")
MIN_CORRELATION = 0.5  # below it the streams share too little motion for a guess


def motion_signal(stream: Stream, how: str = "auto", window: float = 1.0,
                  columns: list[str] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(times, motion) of a stream, averaged over `window` seconds centred on each stamp (the same box filter
    for every stream, so it shifts none against another): `speed` (pose streams: |change of position| / window),
    `turn_rate` (pose streams: angle of the rotation over the window / window), `rate` (|change of the values|
    / window over its columns) or `magnitude` (mean |values| over the window); `auto`: speed for pose
    streams, else rate. `columns`: the columns `rate` and `magnitude` use (default: all)."""
    if how == "auto":
        how = "speed" if stream.is_pose else "rate"
    t, half = stream.t, 0.5 * window
    inner = (t - half >= t[0]) & (t + half <= t[-1])
    tc = t[inner]
    if how == "turn_rate":
        return tc, _turn_angles(stream, tc - half, tc + half) / window
    values = stream.values if columns is None else stream.values[:, [stream.columns.index(c) for c in columns]]
    if how == "magnitude":  # box average: difference of the running integral
        size = np.linalg.norm(values, axis=1)
        integral = np.concatenate([[0.0], np.cumsum(0.5 * (size[1:] + size[:-1]) * np.diff(t))])
        return tc, (np.interp(tc + half, t, integral) - np.interp(tc - half, t, integral)) / window
    if how == "speed":
        values = stream.values[:, [stream.columns.index(c) for c in POSE_COLUMNS[:3]]]
    change = np.column_stack([np.interp(tc + half, t, v) - np.interp(tc - half, t, v) for v in values.T])
    return tc, np.linalg.norm(change, axis=1) / window


def _nearest(t: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Index of the stamp in `t` (increasing) nearest to each of `at`."""
    upper = np.clip(np.searchsorted(t, at), 1, len(t) - 1)
    return np.where(at - t[upper - 1] <= t[upper] - at, upper - 1, upper)


def _turn_angles(stream: Stream, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Angle (rad) of the rotation between a pose stream's orientations at the times `start` and `end`
    (each the nearest sample's: the streams this aligns are sampled far faster than the window)."""
    quat = stream.values[:, [stream.columns.index(c) for c in POSE_COLUMNS[3:]]]
    quat = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    a, b = quat[_nearest(stream.t, start)], quat[_nearest(stream.t, end)]
    return 2 * np.arccos(np.clip(np.abs(np.sum(a * b, axis=1)), 0.0, 1.0))


def _standardized(x: np.ndarray) -> np.ndarray:
    sd = x.std()
    return (x - x.mean()) / sd if sd > 0 else np.zeros_like(x)


@dataclass
class OffsetGuess:
    """The shift delta (s) of a stream against a reference, the peak correlation, and whether it is usable."""

    delta: float
    correlation: float
    at_edge: bool

    @property
    def usable(self) -> bool:
        return self.correlation >= MIN_CORRELATION and not self.at_edge


def correlate(signal: tuple[np.ndarray, np.ndarray], reference: tuple[np.ndarray, np.ndarray],
              max_offset: float) -> OffsetGuess:
    """The delta in [-max_offset, max_offset] maximizing corr(m_s(t), m_r(t + delta)) over the stamps t
    of the signal whose shifted time lies inside the reference for every delta."""
    (ts, ms), (tr, mr) = signal, reference
    step = float(min(np.median(np.diff(ts)), np.median(np.diff(tr))))
    deltas = np.arange(-np.floor(max_offset / step), np.floor(max_offset / step) + 1) * step
    keep = (ts + deltas[0] >= tr[0]) & (ts + deltas[-1] <= tr[-1])
    if keep.sum() < 10 or len(deltas) < 3:
        return OffsetGuess(0.0, 0.0, False)
    ts, ms = ts[keep], _standardized(ms[keep])
    corr = np.array([np.mean(ms * _standardized(np.interp(ts + d, tr, mr))) for d in deltas])
    i = int(np.argmax(corr))
    if i in (0, len(deltas) - 1):
        return OffsetGuess(float(deltas[i]), float(corr[i]), True)
    a, b, c = corr[i - 1:i + 2]
    curvature = a - 2 * b + c
    shift = 0.5 * (a - c) / curvature if curvature < 0 else 0.0
    return OffsetGuess(float(deltas[i] + shift * step), float(corr[i]), False)


class TimeOffsetGuess(Initializer):
    name = "time.offset_guess"
    summary = ("first guess of a time offset: the shift that best aligns the motion two streams see "
               "(cross-correlation of speed / rate-of-change signals)")
    robot_fields = ("robot",)
    stream_fields = ("stream", "reference")
    schema = {"type": "object",
              "properties": {"robot": {"type": "string"}, "parameter": {"type": "string"},
                             "stream": {"type": "string"}, "reference": {"type": "string"},
                             "signal": {"enum": list(SIGNALS), "default": "auto"},
                             "reference_signal": {"enum": list(SIGNALS), "default": "auto"},
                             "columns": {"type": "array", "items": {"type": "string"}, "minItems": 1},
                             "reference_columns": {"type": "array", "items": {"type": "string"}, "minItems": 1},
                             "max_offset": {"type": "number", "exclusiveMinimum": 0, "default": 0.5},
                             "window": {"type": "number", "exclusiveMinimum": 0, "default": 1.0}},
              "required": ["robot", "parameter", "stream", "reference"], "additionalProperties": False}

    def check(self, spec: Spec, scope) -> None:
        scope.require_parameter(spec, "robot", "parameter", "scalar")
        for key, signal, columns in (("stream", "signal", "columns"),
                                     ("reference", "reference_signal", "reference_columns")):
            if spec[signal] in ("speed", "turn_rate"):
                scope.require_columns(spec, key, POSE_COLUMNS)
                if columns in spec.data:
                    raise spec.error(columns, f"a {spec[signal]} signal uses the pose columns; remove `{columns}:`")
            if columns in spec.data:
                scope.require_columns(spec, key, tuple(spec[columns]))

    def initialize(self, ctx, spec: Spec) -> None:
        stream, reference = ctx.stream(spec["stream"]), ctx.stream(spec["reference"])
        guess = correlate(motion_signal(stream, spec["signal"], spec["window"], spec.get("columns")),
                          motion_signal(reference, spec["reference_signal"], spec["window"],
                                        spec.get("reference_columns")), spec["max_offset"])
        robot, name = spec["robot"], spec["parameter"]
        param = ctx.robot(robot).parameters[name]
        head = (f"time offset {robot}/{name} of stream {stream.name!r} against {reference.name!r}: "
                f"best alignment {guess.delta * 1e3:.1f} ms (correlation {guess.correlation:.2f})")
        if guess.usable:
            verdict = f"{head}; the graph starts from it"
            ks = range(len(ctx.states[robot])) if param.time_varying else [None]
            for k in ks:
                key = ctx.parameter(robot, name, None, k)
                ctx.set_initial(key, guess.delta)
        elif guess.at_edge:
            verdict = (f"{head} at the edge of the search range +-{spec['max_offset']} s: not used; "
                       "widen max_offset")
        else:
            verdict = (f"{head}: the streams share too little motion to align (a robot at rest, or at constant "
                       "speed, cannot reveal a time offset); not used")
        ctx.add_diagnostic(spec.label, {"offset_s": guess.delta, "correlation": guess.correlation,
                                        "used": guess.usable, "verdict": [verdict]})


@hookimpl
def register_initializers():
    return [TimeOffsetGuess]
