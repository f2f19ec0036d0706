"""Truth on the states' clock: refuse, before solving, a truth trajectory no state can be compared with.

No offset is ever guessed: truth and data that start at different moments would give a plausible but
wrong ATE after a shift to a common start, so a mismatch is an error that says what to fix.
"""

from __future__ import annotations

import numpy as np

from ..data.association import nearest
from ..data.stream import Stream
from ..errors import DataError
from .trajectory import MATCH_TOLERANCE

# Unix time of any recording exceeds 1e8 s (1973); time since the start of a recording stays below
# it (3 years)
UNIX_TIME_FROM = 1e8


def _clock_hint(a: np.ndarray, b: np.ndarray) -> str:
    unix = [t[0] >= UNIX_TIME_FROM for t in (a, b)]
    if unix[0] == unix[1]:
        return ""
    return ("; one looks like Unix time and the other like time since the start of the recording: subtract the "
            "recording's start time from the Unix stamps, or add it to the others")


def check_truth_clock(truth: Stream, robot: str, states_t: np.ndarray, clock: str) -> None:
    """DataError unless some state of `robot` (at `states_t`, clocked by `clock`, e.g. "stream 'vo'")
    has a truth pose within MATCH_TOLERANCE; names the truth's origin and both time ranges."""
    if len(nearest(states_t, truth.t, MATCH_TOLERANCE).row):
        return
    overlap = truth.t[0] <= states_t[-1] and states_t[0] <= truth.t[-1]
    why = (f"no truth pose is within {MATCH_TOLERANCE} s of a state" if overlap else "the time ranges do not overlap")
    raise DataError(f"{truth.origin or truth.name}: truth of robot {robot!r} spans t = {truth.t[0]:.3f} .. "
                    f"{truth.t[-1]:.3f} s, its states ({clock}) t = {states_t[0]:.3f} .. "
                    f"{states_t[-1]:.3f} s: {why}; expected truth stamped on the same clock in seconds"
                    f"{_clock_hint(truth.t, states_t)}")
