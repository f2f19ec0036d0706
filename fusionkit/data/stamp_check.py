"""Streams that stamp several samples alike (round-robin ranging logs) against what the config does with them.

A robot's state clock (`states: {stream: ...}`, one state per sample) needs strictly increasing stamps, and
so does every component that integrates, interpolates or pairs up a stream's samples in time (odometry, IMU,
wheel encoders, pose interpolation, relative factors). A component names the stream fields whose samples it
takes one by one, by stamp, in `accepts_repeated_stamps` (a tuple of keys); every other field is refused.
"""

from __future__ import annotations

from ..plugins import registry
from .stream import Stream


def accepts_repeated_stamps(component: type, field: str) -> bool:
    return field in getattr(component, "accepts_repeated_stamps", ())


def _repeats(stream: Stream) -> str:
    count, first = stream.repeated_stamps()
    origin = f" ({stream.origin})" if stream.origin else ""
    return (f"stream {stream.name!r}{origin} stamps {count} sample(s) like the one before (first at t = "
            f"{first:.6f} s)")


def check_repeated_stamps(config, streams: dict[str, Stream]) -> None:
    """ConfigError, at the config key that names the stream, where a stream with repeated stamps is used by
    something that needs strictly increasing ones."""
    repeated = {name for name, s in streams.items() if len(s) > 1 and s.repeated_stamps()[0]}
    if not repeated:
        return
    for robot, setup in config.robots.items():
        name = (setup.states or {}).get("stream")
        if name in repeated and "rate" not in setup.states:
            raise config.doc.error(("robots", robot, "states", "stream"),
                                   f"{_repeats(streams[name])}; one state per sample needs strictly increasing "
                                   "stamps: clock the states by another stream or by `rate:`")
    reg = registry()
    for kind, specs in (("factor_types", config.factors), ("initializers", config.initializers)):
        for spec in specs:
            component = reg.get(kind, spec.type)
            for key in component.stream_fields:
                if key in spec.data and spec[key] in repeated and not accepts_repeated_stamps(component, key):
                    raise spec.error(key, f"{_repeats(streams[spec[key]])}; {spec.type} integrates, interpolates or "
                                     f"pairs up the samples of `{key}` in time and needs strictly increasing stamps "
                                     "(the entries that take samples one by one accept repeated ones, e.g. "
                                     "uwb.range)")
