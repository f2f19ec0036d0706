"""Several recordings of one robot in one config: a source given several files reads them as one stream, each
file a recording, and the graph does not link states across where two recordings meet.

The files follow each other in time (each one's first stamp after the previous one's last: recordings on one
clock, or shifted so): the stream keeps each file's span (`Stream.parts`). After the graph is built, a factor whose
per-state variables lie on both sides of a gap between two recordings (odometry or a motion model bridging them) is
left out: the recordings share the calibration and nothing else.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from .stream import Stream

def concatenated(streams: list[Stream], files: list[Path]) -> Stream:
    """One stream of the recordings `streams` (read from `files`, in order): the same columns, each starting after
    the previous one ends; its `parts` the files' spans."""
    first = streams[0]
    for s, f in zip(streams[1:], files[1:]):
        if s.columns != first.columns:
            raise DataError(f"{f}: columns {', '.join(s.columns)}; the first recording of stream {first.name!r} "
                            f"({files[0]}) has {', '.join(first.columns)} (expected the same)")
    for (a, fa), (b, fb) in zip(zip(streams, files), zip(streams[1:], files[1:])):
        if b.t[0] <= a.t[-1]:
            raise DataError(f"{fb}: starts at t = {b.t[0]:.6f} s, before {fa} ends (t = {a.t[-1]:.6f} s); the "
                            "recordings of one stream follow each other in time (shift a recording's stamps so)")
    if len(streams) == 1:
        return first
    out = Stream(first.name, np.concatenate([s.t for s in streams]), first.columns,
                 np.concatenate([s.values for s in streams]), ", ".join(str(f) for f in files))
    out.notes.extend(n for s in streams for n in s.notes)
    out.parts = tuple((str(f), float(s.t[0]), float(s.t[-1])) for s, f in zip(streams, files))
    return out


def gaps(streams: dict[str, Stream]) -> list[tuple[float, float]]:
    """(end of a recording, start of the next) of every stream given several files, sorted."""
    return sorted({(a[2], b[1]) for s in streams.values() for a, b in zip(s.parts, s.parts[1:])})

