"""`uwb.sim`: differential-drive robots among UWB anchors in a room (planar: anchors and tags at
one height), with the errors real UWB ranging has.

Per robot: a smooth closed path (a Lissajous curve inside the room, heading along the motion),
wheel speeds with noise (`wheel_sigma`, m/s), a tag on a lever arm, and at every epoch (`rate` Hz)
a two-way range to every anchor: z_i = (1 + scale_error) ||p_tag - a_i|| + beta_i(t) + N(0, range_sigma), where the
bias starts at N(0, bias_sigma) and drifts as a random walk (`bias_drift`, m/sqrt(s)); with
`outlier_fraction` > 0, non-line-of-sight bursts (each about `burst_s` long, one anchor) add
+0.3 to +2 m to that share of the ranges. Two robots (`robots: 2`) also range tag to tag. Anchors
listed in `unknown_anchors` are off by `anchor_error` (m) in the description (sigma 10 m); the
others are known to 1 mm and fix the frame. With every anchor listed (a site nobody surveyed) the
description has no anchor sigma, the estimate is in the anchor frame (anchor 0 at the origin, anchor
1 on +x: the room below is drawn in it) and the config evaluates after alignment (`align: se3`).

`round_robin: true`: one anchor answers per epoch, in turn (the other columns hold 0: no range), as
tags that range to one anchor at a time do (`uwb.multilateration`'s automatic window then spans a round).
`site: field`: four beacons round a 70 x 45 m field, 10-70 m from the path, one lap in 200 s (about 1 m/s)
instead of the 10 x 8 m room (one lap in 40 s); with `round_robin`, a few Hz and `wheel_scale_error` (the right
wheel reading long by that fraction: odometry that drifts by a few %), the regime of a vehicle ranging to far
beacons one at a time.

`time_offset: {ranges: s}`: the range sample stamped t measures the tag at t + offset on the wheels' (and the
states') clock (fusionkit's sign convention, docs/models/unified_graph.md#time-offsets: ranging that lags by
50 ms is `ranges: -0.05`); the config then estimates each robot's `uwb_time_offset`. A drifting ranging clock:
`{ranges: {offset: s, rate: s/s}}`, the tag at t + offset + rate (t - t0) (t0: the first sample); the config
then also estimates each robot's `uwb_clock_rate` (0 +- 0.01 s/s).

Streams: `ranges_<r>` (t, r0..r{n-1}), `wheels_<r>` (t, v_right, v_left), `bias_<r>` (the true
biases, t, b0..), `tag_ranges` (two robots); truth: each robot's trajectory and the anchors.
"""

from __future__ import annotations

import numpy as np

from fusionkit.api import (CLOCK_SCHEMA, NON_NEGATIVE_SCHEMA as NONNEG, POSITIVE_SCHEMA as POSITIVE, Simulator,
                           SourceOutput, Stream, clock_times, pose_stream, sample_times)

ROBOT_NAMES = ("a", "b")
ANCHORS = "anchors"
WHEEL_DISTANCE = 0.3      # m
LEVER_ARM = [0.10, 0.05]  # m, tag on the robot
ROOM = [[0.0, 0.0], [10.0, 0.0], [10.0, 8.0], [0.0, 8.0]]  # anchors at the corners (m)
FIELD = [[0.0, 0.0], [70.0, 4.0], [66.0, 45.0], [-4.0, 42.0]]  # beacons round a field, 10-70 m from the path (m)
SITES = {"room": (ROOM, 40.0, "UWB anchors at the corners of a 10 x 8 m room (m)"),  # anchors, lap (s), summary
         "field": (FIELD, 200.0, "UWB beacons round a 70 x 45 m field (m)")}
BIAS_RATE = 10.0  # Hz: a drifting bias needs no more variables than this (faster ranging shares them)


def lissajous(t: np.ndarray, phase: float, room: np.ndarray, lap: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) and headings (N,) of a smooth closed path inside the room's bounding box, one lap in
    `lap` s."""
    lo, hi = room.min(axis=0), room.max(axis=0)
    centre, half = (lo + hi) / 2, 0.35 * (hi - lo)
    w = 2 * np.pi / lap
    pos = centre + half * np.column_stack([np.sin(w * t + phase), np.sin(2 * w * t + 1.7 * phase)])
    vel = half * np.column_stack([w * np.cos(w * t + phase), 2 * w * np.cos(2 * w * t + 1.7 * phase)])
    return pos, np.unwrap(np.arctan2(vel[:, 1], vel[:, 0]))


def wheel_speeds(t: np.ndarray, pos: np.ndarray, heading: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    """(v_right, v_left) (m/s) that drive the path between consecutive samples (held per interval)."""
    dt = np.diff(t)
    v = np.linalg.norm(np.diff(pos, axis=0), axis=1) / dt
    w = np.diff(heading) / dt
    v, w = np.append(v, v[-1]), np.append(w, w[-1])
    return v + w * d / 2, v - w * d / 2


def nlos_errors(shape: tuple[int, int], fraction: float, burst: int, rng: np.random.Generator) -> np.ndarray:
    """(epochs, anchors) positive errors: bursts of `burst` epochs on one anchor covering `fraction`."""
    out = np.zeros(shape)
    if fraction <= 0:
        return out
    n_bursts = int(round(fraction * shape[0] * shape[1] / burst))
    for _ in range(n_bursts):
        k, i = rng.integers(0, max(shape[0] - burst, 1)), rng.integers(0, shape[1])
        out[k:k + burst, i] = rng.uniform(0.3, 2.0)
    return out


class UwbSimulator(Simulator):
    name = "uwb.sim"
    summary = ("differential-drive robots among UWB anchors: ranges with drifting bias and NLOS bursts, wheel "
               "odometry, tag-to-tag ranges (two robots), truth")
    schema = {"type": "object",
              "properties": {"robots": {"type": "integer", "minimum": 1, "maximum": 2}, "duration": POSITIVE,
                             "rate": POSITIVE, "range_sigma": NONNEG, "bias_sigma": NONNEG, "bias_drift": NONNEG,
                             "outlier_fraction": {"type": "number", "minimum": 0, "maximum": 0.5},
                             "burst_s": POSITIVE, "wheel_sigma": NONNEG,
                             "unknown_anchors": {"type": "array",
                                                 "items": {"type": "integer", "minimum": 0,
                                                           "maximum": len(ROOM) - 1}},  # every site has 4 anchors
                             "anchor_error": NONNEG, "scale_error": {"type": "number", "minimum": -0.1, "maximum": 0.1},
                             "bias_model": {"enum": ["none", "constant", "time_varying"]},
                             "round_robin": {"type": "boolean"},
                             "site": {"enum": list(SITES)}, "wheel_scale_error": {"type": "number", "minimum": -0.2,
                                                                                  "maximum": 0.2},
                             "time_offset": {"type": "object", "properties": {"ranges": CLOCK_SCHEMA},
                                             "additionalProperties": False}},
              "additionalProperties": False}
    defaults = {"robots": 1, "duration": 60.0, "rate": 10.0, "range_sigma": 0.05, "bias_sigma": 0.15,
                "bias_drift": 0.03, "outlier_fraction": 0.0, "burst_s": 1.0, "wheel_sigma": 0.02,
                "unknown_anchors": [], "anchor_error": 1.0, "scale_error": 0.0, "bias_model": "time_varying",
                "round_robin": False, "site": "room", "wheel_scale_error": 0.0, "time_offset": {}}

    def _params(self, params: dict) -> dict:
        return {**self.defaults, **params}

    def stream_columns(self, params: dict):
        p = self._params(params)
        n = len(ROOM)
        out = {}
        for r in ROBOT_NAMES[:p["robots"]]:
            out[f"ranges_{r}"] = tuple(f"r{i}" for i in range(n))
            out[f"wheels_{r}"] = ("v_right", "v_left")
            out[f"bias_{r}"] = tuple(f"b{i}" for i in range(n))
        if p["robots"] == 2:
            out["tag_ranges"] = ("range",)
        return out

    def simulate(self, params: dict, rng: np.random.Generator) -> SourceOutput:
        p = self._params(params)
        anchors, lap, _ = SITES[p["site"]]
        anchors = np.asarray(anchors, float)
        n = len(anchors)
        t = sample_times(p["duration"], p["rate"])
        streams, truth, tags = {}, {}, {}
        b = np.asarray(LEVER_ARM)
        for j, r in enumerate(ROBOT_NAMES[:p["robots"]]):
            pos, heading = lissajous(t, 1.3 * j, anchors, lap)
            c, s = np.cos(heading), np.sin(heading)
            tag = pos + np.column_stack([c * b[0] - s * b[1], s * b[0] + c * b[1]])
            tags[r] = tag
            dt = 1.0 / p["rate"]
            if "ranges" in p["time_offset"]:  # the ranges see the tag at their stamp + offset (+ drift)
                pos_m, heading_m = lissajous(clock_times(p["time_offset"]["ranges"], t), 1.3 * j, anchors, lap)
                tag_m = pos_m + np.column_stack([np.cos(heading_m) * b[0] - np.sin(heading_m) * b[1],
                                                 np.sin(heading_m) * b[0] + np.cos(heading_m) * b[1]])
            else:
                tag_m = tag
            bias = rng.normal(0.0, p["bias_sigma"], n) + np.cumsum(
                rng.normal(0.0, p["bias_drift"] * np.sqrt(dt), (len(t), n)), axis=0)
            true_range = np.linalg.norm(tag_m[:, None, :] - anchors[None], axis=2)
            burst = max(1, int(round(p["burst_s"] * p["rate"])))
            z = ((1 + p["scale_error"]) * true_range + bias + rng.normal(0.0, p["range_sigma"], true_range.shape)
                 + nlos_errors(true_range.shape, p["outlier_fraction"], burst, rng))
            if p["round_robin"]:  # one anchor per epoch, in turn; the others' columns hold 0: no range
                z[np.arange(len(t))[:, None] % n != np.arange(n)[None]] = 0.0
            vr, vl = wheel_speeds(t, pos, heading, WHEEL_DISTANCE)
            vr, vl = vr + rng.normal(0.0, p["wheel_sigma"], len(t)), vl + rng.normal(0.0, p["wheel_sigma"], len(t))
            vr = vr * (1.0 + p["wheel_scale_error"])  # a right wheel that reads long: odometry that drifts
            cols = tuple(f"r{i}" for i in range(n))
            streams[f"ranges_{r}"] = Stream(f"ranges_{r}", t, cols, z, "simulated:ranges")
            streams[f"wheels_{r}"] = Stream(f"wheels_{r}", t, ("v_right", "v_left"), np.column_stack([vr, vl]),
                                            "simulated:wheels")
            streams[f"bias_{r}"] = Stream(f"bias_{r}", t, tuple(f"b{i}" for i in range(n)), bias, "simulated:bias")
            quat = np.column_stack([np.zeros((len(t), 2)), np.sin(heading / 2), np.cos(heading / 2)])
            truth[r] = pose_stream(r, t, np.column_stack([pos, np.zeros(len(t)), quat]), "simulated:truth")
        if p["robots"] == 2:
            d = np.linalg.norm(tags["a"] - tags["b"], axis=1) + rng.normal(0.0, p["range_sigma"], len(t))
            streams["tag_ranges"] = Stream("tag_ranges", t, ("range",), d[:, None], "simulated:tag_ranges")
        calibration = {ANCHORS: {"anchor": {"type": "point2", "values": anchors.tolist()}}}
        clock = p["time_offset"].get("ranges")
        if clock is not None:
            offset = clock["offset"] if isinstance(clock, dict) else clock
            truth_clock = {"uwb_time_offset": {"type": "scalar", "value": float(offset)}}
            if self._ranging_rate(p):
                truth_clock["uwb_clock_rate"] = {"type": "scalar", "value": float(clock["rate"])}
            calibration.update({r: dict(truth_clock) for r in ROBOT_NAMES[:p["robots"]]})
        return SourceOutput(streams, truth, calibration)

    @staticmethod
    def _ranging_rate(params: dict) -> bool:
        """Whether the ranging clock has a rate error (descriptions and config then gain `uwb_clock_rate`)."""
        raw = params["time_offset"].get("ranges")
        return isinstance(raw, dict) and "rate" in raw

    def robots(self, params: dict) -> dict[str, dict]:
        p = self._params(params)
        site, _, summary = SITES[p["site"]]
        anchors = np.asarray(site, float)
        rng = np.random.default_rng(12345)  # the description's guess for the unknown anchors
        nominal, sigma = anchors.copy(), [[0.001, 0.001] for _ in anchors]
        for i in p["unknown_anchors"]:
            nominal[i] += rng.normal(0.0, p["anchor_error"] / np.sqrt(2), 2)
            sigma[i] = [10.0, 10.0]
        anchor = {"type": "point2", "values": nominal.round(4).tolist(), "sigma": sigma}
        if _unsurveyed(p):
            del anchor["sigma"]  # no survey: the values are placeholders the initializer replaces
        out = {ANCHORS: {"name": ANCHORS, "summary": summary,
                         "parameters": {"anchor": anchor}}}
        for r in ROBOT_NAMES[:p["robots"]]:
            desc = {"name": r, "summary": "differential-drive robot with a UWB tag",
                    "sensors": {"tag": {"type": "uwb_tag", "frame": "base",
                                        "mount": {"translation": LEVER_ARM + [0.0]}}},
                    "parameters": {}}
            if p["bias_model"] != "none":
                desc["parameters"]["uwb_bias"] = {"type": "scalar", "values": [0.0] * len(anchors), "sigma": 1.0,
                                                  "time_varying": p["bias_model"] == "time_varying", "unit": "m"}
            if p["scale_error"]:
                desc["parameters"]["uwb_scale"] = {"type": "scalar", "value": 0.0, "sigma": 0.1}
            if "ranges" in p["time_offset"]:
                desc["parameters"]["uwb_time_offset"] = {"type": "scalar", "value": 0.0, "sigma": 1.0, "unit": "s"}
            if self._ranging_rate(p):
                desc["parameters"]["uwb_clock_rate"] = {"type": "scalar", "value": 0.0, "sigma": 0.01, "unit": "s/s"}
            out[r] = desc
        return out

    def config(self, params: dict) -> dict:
        """Per robot: UWB ranges (bias per the bias model; time-varying biases are variables at about
        BIAS_RATE Hz), wheel odometry, multilateration start; two robots add their tag-to-tag
        ranges. Batch Levenberg-Marquardt."""
        p = self._params(params)
        every = max(1, int(round(p["rate"] / BIAS_RATE)))  # time-varying biases at about BIAS_RATE Hz
        robots = {ANCHORS: {"description": f"robots/{ANCHORS}.yaml"}}
        factors, inits = [], []
        for r in ROBOT_NAMES[:p["robots"]]:
            robots[r] = {"description": f"robots/{r}.yaml", "states": {"stream": f"ranges_{r}", "type": "pose2"}}
            rng_entry = {"type": "uwb.range", "robot": r, "stream": f"ranges_{r}", "anchors": ANCHORS, "tag": "tag",
                         "sigma": max(p["range_sigma"], 1e-3)}
            if p["bias_model"] != "none":
                rng_entry["bias"] = "uwb_bias"
            if p["bias_model"] == "time_varying" and every > 1:
                rng_entry["bias_every"] = every
            if p["scale_error"]:
                rng_entry["scale"] = "uwb_scale"
            if "ranges" in p["time_offset"]:
                rng_entry["time_offset"] = {"parameter": "uwb_time_offset",  # from 0: range rates and wheel
                                            **({"rate": "uwb_clock_rate"} if self._ranging_rate(p) else {})}
                # speeds see the motion differently (a range's rate depends on the direction), no guess from them
            factors.append(rng_entry)
            if p["bias_model"] == "time_varying":
                walk = {"type": "parameter.random_walk", "robot": r, "parameter": "uwb_bias",
                        "sigma": max(p["bias_drift"], 1e-4)}
                factors.append({**walk, "every": every} if every > 1 else walk)
            factors.append({"type": "odometry.diff_drive", "robot": r, "stream": f"wheels_{r}",
                            "wheel_distance": WHEEL_DISTANCE,
                            "sigma": {"translation": max(p["wheel_sigma"], 1e-3) * 0.5,
                                      "rotation": max(p["wheel_sigma"], 1e-3) / WHEEL_DISTANCE}})
            init = {"type": "uwb.multilateration", "robot": r, "anchors": ANCHORS, "stream": f"ranges_{r}",
                    "tag": "tag"}
            if p["unknown_anchors"] and r == "a":
                init["unknown"] = list(p["unknown_anchors"])
                if p["bias_model"] != "none":
                    init["bias"] = "uwb_bias"
            inits.append(init)
        if p["robots"] == 2:
            factors.append({"type": "uwb.tag_range", "robot": "a", "other": "b", "stream": "tag_ranges",
                            "tag": "tag", "other_tag": "tag", "sigma": max(p["range_sigma"], 1e-3)})
        config = {"robots": robots, "factors": factors, "initializers": inits,
                  "solver": {"type": "batch", "method": "lm"}}
        if _unsurveyed(p):
            config["truth"] = {"align": "se2"}  # the anchor frame is not the world's: compare after alignment (planar)
        return config


def _unsurveyed(p: dict) -> bool:
    """Every anchor unknown: no survey fixes the frame."""
    return set(p["unknown_anchors"]) >= set(range(len(ROOM)))


SIMULATORS = [UwbSimulator]
