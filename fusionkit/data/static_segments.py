"""`static_segments`: the static poses of a recording in which the robot dwells and swings.

A cable robot calibrated with a static model (sagging cables) is moved from pose to pose and held
there while its end-effector swings at constant cable lengths. The source reads the recording's files
and finds the stretches in which every column of one stream (`segments_from`, e.g. the cable lengths)
stays within `tolerance` (max - min) for at least `min_duration` s; each stretch becomes one sample at
its middle time: the mean of that stream and of every other file (`also`) over the stretch -- poses
(TUM files) averaged as poses (mean position, chordal mean rotation), so a swing about the equilibrium
averages out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..hookspecs import hookimpl
from ..components import Source, SourceOutput, Spec
from .builtin_sources import NAME, resolve
from .files import read_csv_header, read_csv_stream, read_tum
from .stream import POSE_COLUMNS, Stream

FILE = {"type": "object", "properties": {"name": NAME, "path": {"type": "string"}},
        "required": ["name", "path"], "additionalProperties": False}


def constant_stretches(t: np.ndarray, values: np.ndarray, tolerance: float, min_duration: float) -> list[tuple[float, float]]:
    """(start, end) times (s) of the maximal runs of consecutive samples over which every column stays within
    `tolerance` (max - min), scanned from the start, that last at least `min_duration`."""
    out, start = [], 0
    lo, hi = values[0].copy(), values[0].copy()
    for i in range(1, len(t) + 1):
        if i < len(t):
            lo_i, hi_i = np.minimum(lo, values[i]), np.maximum(hi, values[i])
            if np.all(hi_i - lo_i <= tolerance):
                lo, hi = lo_i, hi_i
                continue
        if t[i - 1] - t[start] >= min_duration:
            out.append((float(t[start]), float(t[i - 1])))
        if i < len(t):
            start, lo, hi = i, values[i].copy(), values[i].copy()
    return out


def averaged(stream: Stream, stretches: list[tuple[float, float]]) -> Stream:
    """One sample per stretch at its middle time: the mean of the stream's samples inside it (poses as poses)."""
    from scipy.spatial.transform import Rotation
    rows = [(stream.t >= a) & (stream.t <= b) for a, b in stretches]
    if any(not r.any() for r in rows):
        empty = next(i for i, r in enumerate(rows) if not r.any())
        a, b = stretches[empty]
        raise ValueError(f"stream {stream.name!r} has no sample in the static stretch {a:.3f} .. {b:.3f} s")
    values = np.array([stream.values[r].mean(axis=0) for r in rows])
    if stream.is_pose:  # the quaternion columns, wherever they are, by the rotations' mean
        quat = [stream.columns.index(c) for c in POSE_COLUMNS[3:]]
        unit = stream.pose_array()[:, 3:]
        values[:, quat] = np.array([Rotation.from_quat(unit[r]).mean().as_quat() for r in rows])
    t = np.array([(a + b) / 2 for a, b in stretches])
    return Stream(stream.name, t, stream.columns, values, f"{stream.origin} (static stretches)")


def _read(path: Path, name: str) -> Stream:
    return read_tum(path, name) if path.suffix == ".tum" else read_csv_stream(path, name)


class StaticSegments(Source):
    name = "static_segments"
    summary = ("the static poses of a dwell-and-swing recording: stretches in which one stream stays constant, "
               "each averaged into one sample, with the other files averaged over the same stretches")
    schema = {"type": "object",
              "properties": {"segments_from": FILE, "also": {"type": "array", "items": FILE, "default": []},
                             "tolerance": {"type": "number", "exclusiveMinimum": 0},
                             "min_duration": {"type": "number", "exclusiveMinimum": 0, "default": 1.0}},
              "required": ["segments_from", "tolerance"], "additionalProperties": False}

    def _files(self, spec: Spec, base_dir: Path) -> list[tuple[tuple, dict, Path]]:
        entries = [(("segments_from",), spec["segments_from"])] + [(("also", i), e) for i, e in enumerate(spec["also"])]
        out = []
        for where, entry in entries:
            path = resolve(base_dir, entry["path"])
            if not path.is_file():
                raise spec.error(where + ("path",), f"file not found: {path}")
            out.append((where, entry, path))
        return out

    def stream_names(self, spec: Spec, base_dir: Path):
        return {entry["name"]: POSE_COLUMNS if path.suffix == ".tum" else tuple(read_csv_header(path))
                for _, entry, path in self._files(spec, base_dir)}

    def read(self, spec: Spec, base_dir: Path) -> SourceOutput:
        files = self._files(spec, base_dir)
        streams = [_read(path, entry["name"]) for _, entry, path in files]
        stretches = constant_stretches(streams[0].t, streams[0].values, spec["tolerance"], spec["min_duration"])
        if not stretches:
            raise spec.error("segments_from", f"stream {streams[0].name!r} never stays within {spec['tolerance']} for "
                             f"{spec['min_duration']} s: no static stretch (expected dwells; widen tolerance or "
                             "shorten min_duration)")
        out = {}
        for (where, _, _), stream in zip(files, streams):
            try:
                out[stream.name] = averaged(stream, stretches)
            except ValueError as exc:
                raise spec.error(where, str(exc)) from None
        note = (f"static_segments: {len(stretches)} static stretch(es) of {streams[0].name!r} (within "
                f"{spec['tolerance']} for >= {spec['min_duration']} s; {sum(b - a for a, b in stretches):.1f} of "
                f"{streams[0].t[-1] - streams[0].t[0]:.1f} s), each averaged into one sample")
        for stream in out.values():
            stream.notes.append(note)
            break
        return SourceOutput(out)


@hookimpl
def register_sources():
    return [StaticSegments]
